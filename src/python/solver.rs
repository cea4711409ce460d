//! Python wrapper of [`Solver`], in f32 or f64.

use std::sync::Arc;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::collider::{Collider, MovingCollider, Pose};
use crate::error::Result;
use crate::gpu::GpuSolver;
use crate::solve::{
    Acceleration, BodyMut, Clock, GlobalSolver, Solver, SolverParams, SolverState, StepStats,
};

use super::arrays::{rotation_rows, to_numpy, to_numpy_1d, vec3};
use super::body::{check_held, LockedBody, PyBody, SharedBody};
use super::collider;
use super::contact::PyContact;
use super::errors::{guard, IntoPyResult};
use super::options::{
    AccelerationKind, Backend, Float, ACCELERATION, BACKEND, GLOBAL_SOLVER, METHOD, PRECISION,
    PRECONDITIONER,
};
use super::owner::SolverMark;
use super::resolution;
use super::scalars::{Flag, Int, Real, Text};
use super::solver_state;
use super::step_stats::PyStepStats;

/// Most worker threads a CPU solver may start (each is an OS thread with its own stack).
const MAX_THREADS: i64 = 1024;

/// The core solver, on the CPU or the GPU, in the precision the user chose.
enum Precision {
    F64(Solver<f64>),
    F32(Solver<f32>),
    Gpu32(Box<GpuSolver<f32>>),
    Gpu64(Box<GpuSolver<f64>>),
}

impl Precision {
    fn step(&mut self, bodies: &mut [BodyMut<'_>]) -> Result<StepStats> {
        match self {
            Self::F64(s) => s.step(bodies),
            Self::F32(s) => s.step(bodies),
            Self::Gpu32(s) => s.step(bodies),
            Self::Gpu64(s) => s.step(bodies),
        }
    }
    fn float(&self) -> Float {
        match self {
            Self::F64(_) | Self::Gpu64(_) => Float::F64,
            Self::F32(_) | Self::Gpu32(_) => Float::F32,
        }
    }
    fn backend(&self) -> Backend {
        match self {
            Self::F64(_) | Self::F32(_) => Backend::Cpu,
            Self::Gpu32(_) | Self::Gpu64(_) => Backend::Gpu,
        }
    }
    /// Worker threads of the CPU backend; the GPU backend drives the device from one thread.
    fn threads(&self) -> usize {
        match self {
            Self::F64(s) => s.threads(),
            Self::F32(s) => s.threads(),
            Self::Gpu32(_) | Self::Gpu64(_) => 1,
        }
    }
}

macro_rules! with_solver {
    ($p:expr, $s:ident => $body:expr) => {
        match $p {
            Precision::F64($s) => $body,
            Precision::F32($s) => $body,
            Precision::Gpu32($s) => $body,
            Precision::Gpu64($s) => $body,
        }
    };
}

/// Implicit Euler time stepping by the semi-implicit successive substitution method (SISSM).
#[pyclass(module = "peridyn._core", name = "Solver", subclass)]
pub struct PySolver {
    core: Precision,
    bodies: Vec<PyBody>,
    colliders: Vec<Py<PyAny>>,
    /// This solver's identity, which its bodies hold ([`super::owner::Owner`]).
    mark: Arc<SolverMark>,
}

#[pymethods]
impl PySolver {
    #[new]
    #[pyo3(signature = (*, dt, gravity = None, tol = Real::of(1e-4), max_iters = Int::of(100),
                        threads = None, step_length = Flag::of(true), precision = None,
                        preconditioner = Text::of("tangent"), acceleration = None,
                        chebyshev_rho = None,
                        chebyshev_delay = None,
                        record_energy = Flag::of(false), method = Text::of("sissm"),
                        inner_iters = Int::of(1), backend = Text::of("cpu"), contact = None,
                        global_solver = Text::of("chebyshev"),
                        particle_tol = Real::of(SolverParams::DEFAULT_PARTICLE_TOL),
                        two_level = Flag::of(true),
                        max_speed = Real::of(SolverParams::DEFAULT_MAX_SPEED)))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        dt: Real,
        gravity: Option<&Bound<'_, PyAny>>,
        tol: Real,
        max_iters: Int,
        threads: Option<Int>,
        step_length: Flag,
        precision: Option<Text>,
        preconditioner: Text,
        acceleration: Option<Text>,
        chebyshev_rho: Option<Real>,
        chebyshev_delay: Option<Int>,
        record_energy: Flag,
        method: Text,
        inner_iters: Int,
        backend: Text,
        contact: Option<PyRef<'_, PyContact>>,
        global_solver: Text,
        particle_tol: Real,
        two_level: Flag,
        max_speed: Real,
    ) -> PyResult<Self> {
        let dt = dt.get("dt")?;
        let tol = tol.get("tol")?;
        let particle_tol = particle_tol.get("particle_tol")?;
        let max_speed = max_speed.get("max_speed")?;
        let max_iters = max_iters.get("max_iters")?;
        let threads = threads.map(|t| t.get("threads")).transpose()?;
        let chebyshev_rho = chebyshev_rho
            .map(|rho| rho.get("chebyshev_rho"))
            .transpose()?;
        let chebyshev_delay = chebyshev_delay
            .map(|delay| {
                let delay = delay.get("chebyshev_delay")?;
                usize::try_from(delay).map_err(|_| {
                    PyValueError::new_err(format!("chebyshev_delay must be >= 1, got {delay}"))
                })
            })
            .transpose()?;
        let inner_iters = inner_iters.get("inner_iters")?;
        let method = METHOD.parse(method.get("method")?)?;
        if inner_iters < 1 {
            return Err(PyValueError::new_err(format!(
                "inner_iters must be >= 1, got {inner_iters}"
            )));
        }
        let acceleration = Text::get_optional(&acceleration, "acceleration")?;
        let acceleration = match ACCELERATION.parse_optional(acceleration)? {
            AccelerationKind::Plain => Acceleration::None,
            AccelerationKind::Chebyshev => Acceleration::Chebyshev {
                rho: chebyshev_rho.unwrap_or(Acceleration::DEFAULT_RHO),
                delay: chebyshev_delay.unwrap_or(Acceleration::DEFAULT_DELAY),
            },
        };
        let global_solver = GLOBAL_SOLVER.parse(global_solver.get("global_solver")?)?;
        let chebyshev_runs =
            acceleration != Acceleration::None || global_solver == GlobalSolver::Chebyshev;
        for (name, given) in [
            ("chebyshev_rho", chebyshev_rho.is_some()),
            ("chebyshev_delay", chebyshev_delay.is_some()),
        ] {
            if given && !chebyshev_runs {
                return Err(PyValueError::new_err(format!(
                    "{name} applies to acceleration='chebyshev' or global_solver='chebyshev'; \
                     got neither (global_solver={global_solver:?}): pass \
                     acceleration='chebyshev' or leave {name} out"
                )));
            }
        }
        let gravity = gravity
            .map(|g| vec3(g, "gravity"))
            .transpose()?
            .unwrap_or([0.0, 0.0, -9.81]);
        let max_iters = iteration_cap(max_iters)?;
        let threads = match threads {
            None => None,
            Some(n) if (1..=MAX_THREADS).contains(&n) => Some(n as usize),
            Some(n) => {
                return Err(PyValueError::new_err(format!(
                    "threads must be in [1, {MAX_THREADS}] or None, got {n}"
                )))
            }
        };
        let params = SolverParams {
            dt,
            gravity,
            tol,
            particle_tol,
            max_iters,
            max_speed,
            step_length: step_length.get("step_length")?,
            preconditioner: PRECONDITIONER.parse(preconditioner.get("preconditioner")?)?,
            acceleration,
            method,
            inner_iters: inner_iters as usize,
            record_energy: record_energy.get("record_energy")?,
            contact: contact.map(|c| c.inner),
            global_solver,
            particle_chebyshev_rho: chebyshev_rho,
            particle_chebyshev_delay: chebyshev_delay,
            particle_two_level: two_level.get("two_level")?,
        };
        let backend = BACKEND.parse(backend.get("backend")?)?;
        let precision = Text::get_optional(&precision, "precision")?
            .map(|p| PRECISION.parse(p))
            .transpose()?;
        check_dt(
            dt,
            precision.unwrap_or(match backend {
                Backend::Cpu => Float::F64,
                Backend::Gpu => Float::F32,
            }),
        )?;
        let core = match (backend, precision) {
            (Backend::Cpu, None | Some(Float::F64)) => {
                Precision::F64(Solver::new(params, threads).py()?)
            }
            (Backend::Cpu, Some(Float::F32)) => Precision::F32(Solver::new(params, threads).py()?),
            (Backend::Gpu, precision) => {
                if threads.is_some() {
                    return Err(PyValueError::new_err(
                        "threads applies to backend='cpu' only; the GPU backend takes threads=None",
                    ));
                }
                if precision == Some(Float::F64) {
                    Precision::Gpu64(Box::new(GpuSolver::new(params).py()?))
                } else {
                    Precision::Gpu32(Box::new(GpuSolver::new(params).py()?))
                }
            }
        };
        Ok(Self {
            core,
            bodies: Vec::new(),
            colliders: Vec::new(),
            mark: Arc::new(SolverMark),
        })
    }

    /// Adds a body (a Membrane or Particles); the solver steps it from now on. A body belongs
    /// to the solver it was last added to ([`super::owner::Owner`]): adding it twice to one
    /// solver is a `ValueError`; adding it to another hands it over, and this solver's `step`
    /// then refuses it until it is added here again (which takes it back, in its place).
    fn add(&mut self, body: &Bound<'_, PyAny>) -> PyResult<()> {
        let py = body.py();
        let new = PyBody::extract(body)?;
        let core = new.shared(py);
        let listed = self.bodies.iter().position(|b| b.shared(py).same(&core));
        if let Some(index) = listed {
            if new.with_owner(py, |owner| owner.held_by(&self.mark)) {
                return Err(PyValueError::new_err(format!(
                    "this {} is already body {index} of this solver: a body is added once",
                    new.describe(py)
                )));
            }
        }
        self.warn_resolution(py, listed.is_none().then_some(&new), &[&new])?;
        new.with_owner(py, |owner| owner.claim(&self.mark));
        match listed {
            None => self.bodies.push(new),
            // Taken back: another solver stepped it since this one's record of it, which is now
            // of other positions, as after `set_positions`.
            Some(_) => {
                if let LockedBody::Particles(mut p) = core.lock() {
                    p.mark_positions_replaced();
                }
            }
        }
        Ok(())
    }

    /// Adds a collider (Plane, Sphere, Box, Capsule or MeshCollider, with its friction and
    /// velocity).
    fn add_collider(&mut self, collider: &Bound<'_, PyAny>) -> PyResult<()> {
        let c: Collider = collider::extract(collider)?;
        with_solver!(&mut self.core, s => s.add_collider(c)).py()?;
        self.colliders.push(collider.clone().unbind());
        Ok(())
    }

    /// Sets the pose collider `index` reaches at the end of the next step: its geometry as
    /// given, turned by `rotation` (3x3, orthonormal, det +1) and moved by `translation` (m).
    #[pyo3(signature = (index, *, rotation = None, translation = None))]
    fn set_collider_pose(
        &mut self,
        index: Int,
        rotation: Option<&Bound<'_, PyAny>>,
        translation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let index = self.collider_index(index)?;
        let pose = pose_arg(rotation, translation)?;
        match &mut self.core {
            Precision::F64(s) => s.set_collider_pose(index, pose).py(),
            Precision::F32(s) => s.set_collider_pose(index, pose).py(),
            Precision::Gpu32(_) | Precision::Gpu64(_) => Err(no_gpu_poses()),
        }
    }

    /// The current pose of collider `index`: (rotation (3, 3), translation (3,) in m), such that
    /// a point `b` of the geometry as given is now at `rotation @ b + translation`.
    fn collider_pose<'py>(&self, py: Python<'py>, index: Int) -> PyResult<PoseArrays<'py>> {
        let index = self.collider_index(index)?;
        let pose = match &self.core {
            Precision::F64(s) => s.collider_pose(index).py()?,
            Precision::F32(s) => s.collider_pose(index).py()?,
            Precision::Gpu32(s) => {
                MovingCollider::new(s.colliders()[index].clone()).pose(s.clock().time)
            }
            Precision::Gpu64(s) => {
                MovingCollider::new(s.colliders()[index].clone()).pose(s.clock().time)
            }
        };
        pose_arrays(py, &pose)
    }

    /// What the motion of collider `index` depends on besides its velocity and the clock, for
    /// saving a simulation: `(base, target)`, the pose at time 0 its velocity carries on from and
    /// the pose set for the end of the next step (None when none is pending), each as
    /// `(rotation, translation)`.
    fn collider_motion<'py>(
        &self,
        py: Python<'py>,
        index: Int,
    ) -> PyResult<(PoseArrays<'py>, Option<PoseArrays<'py>>)> {
        let index = self.collider_index(index)?;
        let (base, target) = match &self.core {
            Precision::F64(s) => s.collider_motion(index).py()?,
            Precision::F32(s) => s.collider_motion(index).py()?,
            Precision::Gpu32(_) | Precision::Gpu64(_) => (Pose::IDENTITY, None),
        };
        let target = target.map(|t| pose_arrays(py, &t)).transpose()?;
        Ok((pose_arrays(py, &base)?, target))
    }

    /// Restores a motion read with `collider_motion` (both parts of the target, or neither).
    #[pyo3(signature = (index, *, base_rotation, base_translation, target_rotation = None,
                        target_translation = None))]
    fn set_collider_motion(
        &mut self,
        index: Int,
        base_rotation: &Bound<'_, PyAny>,
        base_translation: &Bound<'_, PyAny>,
        target_rotation: Option<&Bound<'_, PyAny>>,
        target_translation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let index = self.collider_index(index)?;
        let base = pose_arg(Some(base_rotation), Some(base_translation))?;
        let target = match (target_rotation, target_translation) {
            (None, None) => None,
            (Some(r), Some(t)) => Some(pose_arg(Some(r), Some(t))?),
            _ => return Err(PyValueError::new_err(
                "set_collider_motion: give both target_rotation and target_translation, or neither",
            )),
        };
        match &mut self.core {
            Precision::F64(s) => s.set_collider_motion(index, base, target).py(),
            Precision::F32(s) => s.set_collider_motion(index, base, target).py(),
            Precision::Gpu32(_) | Precision::Gpu64(_) => {
                if base == Pose::IDENTITY && target.is_none() {
                    Ok(())
                } else {
                    Err(no_gpu_poses())
                }
            }
        }
    }

    /// What the next steps depend on besides the bodies, the clock, ``dt`` and the colliders'
    /// motion, as a dict of named arrays (:func:`peridyn.save_state` saves it as entries
    /// ``internal_<name>``): the contact local step's warm start per membrane vertex
    /// (``contact_warm_start``, (N, 3) m; (0, 3) before the first contact step) and the rest
    /// gaps of the contact pairs that started within the barrier's reach (whether they were
    /// seeded, the reach in m, and per gap its pair's four vertices, whether it is edge-edge,
    /// and its distance in m), and the friction at the grains' contacts the next step starts
    /// from (``grain_contact_pairs``, (P, 2) particle indices over the particle bodies in
    /// order, each touching pair in both orders, and ``grain_contact_multipliers``, (P, 3) m;
    /// none at a body whose positions were set since the last step, which starts them at 0).
    /// The GPU backend has no contact: its arrays are empty.
    fn internal_state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let revisions: Vec<u64> = self
            .bodies
            .iter()
            .filter_map(|body| match body.shared(py).lock() {
                LockedBody::Particles(p) => Some(p.positions_revision()),
                LockedBody::Membrane(_) => None,
            })
            .collect();
        let state = match &self.core {
            Precision::F64(s) => s.saved_state(&revisions),
            Precision::F32(s) => s.saved_state(&revisions),
            Precision::Gpu32(_) | Precision::Gpu64(_) => SolverState::default(),
        };
        solver_state::to_dict(py, state)
    }

    /// Restores a dict read with ``internal_state`` into a solver set up the same way (same
    /// bodies in the same order, parameters and colliders); the next step takes it. Checked
    /// whole before anything changes (every entry, of the right dtype and shape, finite,
    /// vertex indices within the membranes); an empty dict resets the state (the next contact
    /// step starts afresh).
    fn set_internal_state(&mut self, py: Python<'_>, state: &Bound<'_, PyDict>) -> PyResult<()> {
        let (mut vertices, mut particles, mut frictional) = (0, 0, false);
        for body in &self.bodies {
            match body.shared(py).lock() {
                LockedBody::Membrane(m) => vertices += m.num_vertices(),
                LockedBody::Particles(p) => {
                    particles += p.num_particles();
                    frictional |= p.granular().is_some_and(|g| g.contact_friction > 0.0);
                }
            }
        }
        let state = solver_state::from_dict(state, vertices, particles)?;
        if !frictional && !state.grain_contacts.is_empty() {
            return Err(PyValueError::new_err(format!(
                "the internal state holds {} grain contacts with friction, but no particle body \
                 has contact friction",
                state.grain_contacts.len()
            )));
        }
        match &mut self.core {
            Precision::F64(s) => s.restore_state(state).py(),
            Precision::F32(s) => s.restore_state(state).py(),
            Precision::Gpu32(_) | Precision::Gpu64(_) if state == SolverState::default() => Ok(()),
            Precision::Gpu32(_) | Precision::Gpu64(_) => Err(PyValueError::new_err(
                "the GPU backend has no contact: its internal state holds no contact warm start \
                 or rest gaps",
            )),
        }
    }

    /// Advances every body by one time step and returns its statistics. Raises
    /// `DivergenceError` (bodies unchanged) when the step produces non-finite positions.
    fn step(&mut self, py: Python<'_>) -> PyResult<PyStepStats> {
        if self.bodies.is_empty() {
            return Err(PyValueError::new_err(
                "the solver has no bodies: call solver.add(membrane) first",
            ));
        }
        if self.core.backend() == Backend::Cpu {
            let bodies: Vec<&PyBody> = self.bodies.iter().collect();
            self.warn_resolution(py, None, &bodies)?;
        }
        // After the warning (which may run Python) and with no Python after it: the owners are
        // those the step sees.
        check_held(py, &self.bodies, &self.mark)?;
        let shared: Vec<SharedBody> = self.bodies.iter().map(|b| b.shared(py)).collect();
        let core = &mut self.core;
        let stats = py.detach(move || {
            guard("Solver.step", || {
                let mut locks: Vec<LockedBody> = shared.iter().map(SharedBody::lock).collect();
                let mut refs: Vec<BodyMut> = locks.iter_mut().map(LockedBody::body_mut).collect();
                core.step(&mut refs)
            })
        });
        Ok(PyStepStats::from(stats?))
    }

    /// Time step h (s); settable.
    #[getter]
    fn dt(&self) -> f64 {
        with_solver!(&self.core, s => s.params().dt)
    }
    #[setter]
    fn set_dt(&mut self, dt: Real) -> PyResult<()> {
        let dt = dt.get("dt")?;
        check_dt(dt, self.core.float())?;
        with_solver!(&mut self.core, s => {
            let p = SolverParams { dt, ..*s.params() };
            s.set_params(p).py()
        })
    }
    #[getter]
    fn gravity(&self) -> Vec<f64> {
        with_solver!(&self.core, s => s.params().gravity.to_vec())
    }
    /// The membranes' convergence tolerance (m); settable, as the speed/accuracy trade of a
    /// run can change between steps.
    #[getter]
    fn tol(&self) -> f64 {
        with_solver!(&self.core, s => s.params().tol)
    }
    #[setter]
    fn set_tol(&mut self, tol: Real) -> PyResult<()> {
        let tol = tol.get("tol")?;
        with_solver!(&mut self.core, s => {
            let p = SolverParams { tol, ..*s.params() };
            s.set_params(p).py()
        })
    }
    /// The particles' force-imbalance tolerance (m/s^2); settable.
    #[getter]
    fn particle_tol(&self) -> f64 {
        with_solver!(&self.core, s => s.params().particle_tol)
    }
    #[setter]
    fn set_particle_tol(&mut self, particle_tol: Real) -> PyResult<()> {
        let particle_tol = particle_tol.get("particle_tol")?;
        with_solver!(&mut self.core, s => {
            let p = SolverParams { particle_tol, ..*s.params() };
            s.set_params(p).py()
        })
    }
    /// The fastest a free point may end a step (m/s; inf: unchecked), else `DivergenceError`
    /// with the last good state kept; settable.
    #[getter]
    fn max_speed(&self) -> f64 {
        with_solver!(&self.core, s => s.params().max_speed)
    }
    #[setter]
    fn set_max_speed(&mut self, max_speed: Real) -> PyResult<()> {
        let max_speed = max_speed.get("max_speed")?;
        with_solver!(&mut self.core, s => {
            let p = SolverParams { max_speed, ..*s.params() };
            s.set_params(p).py()
        })
    }
    /// Most global iterations of one step; settable.
    #[getter]
    fn max_iters(&self) -> usize {
        with_solver!(&self.core, s => s.params().max_iters)
    }
    #[setter]
    fn set_max_iters(&mut self, max_iters: Int) -> PyResult<()> {
        let max_iters = iteration_cap(max_iters.get("max_iters")?)?;
        with_solver!(&mut self.core, s => {
            let p = SolverParams { max_iters, ..*s.params() };
            s.set_params(p).py()
        })
    }
    #[getter]
    fn step_length(&self) -> bool {
        with_solver!(&self.core, s => s.params().step_length)
    }
    #[getter]
    fn preconditioner(&self) -> &'static str {
        PRECONDITIONER.name(with_solver!(&self.core, s => s.params().preconditioner))
    }
    /// None or "chebyshev".
    #[getter]
    fn acceleration(&self) -> Option<&'static str> {
        ACCELERATION.name_optional(
            match with_solver!(&self.core, s => s.params().acceleration) {
                Acceleration::None => AccelerationKind::Plain,
                Acceleration::Chebyshev { .. } => AccelerationKind::Chebyshev,
            },
        )
    }
    /// The contact parameters, or None when contact is off. Settable to another `Contact`
    /// between steps (a `Contact` is frozen: build a new one), but contact cannot be switched
    /// on or off on a solver: one built without it kept nothing apart.
    #[getter]
    fn contact(&self) -> Option<PyContact> {
        with_solver!(&self.core, s => s.params().contact.map(|inner| PyContact { inner }))
    }
    #[setter]
    fn set_contact(&mut self, contact: Option<PyRef<'_, PyContact>>) -> PyResult<()> {
        with_solver!(&mut self.core, s => {
            let params = *s.params();
            match (params.contact, contact) {
                (Some(_), Some(new)) => s
                    .set_params(SolverParams { contact: Some(new.inner), ..params })
                    .py(),
                (Some(_), None) => Err(PyValueError::new_err(
                    "contact cannot be switched off on a solver that has it: build a Solver \
                     without contact= instead",
                )),
                (None, _) => Err(PyValueError::new_err(
                    "contact cannot be switched on on a solver built without it (nothing kept \
                     its bodies apart so far): build the Solver with contact=peridyn.Contact(...)",
                )),
            }
        })
    }
    /// "sissm", "descent", "newton" or "auto".
    #[getter]
    fn method(&self) -> &'static str {
        METHOD.name(with_solver!(&self.core, s => s.params().method))
    }
    /// How particle bodies solve their global step: "direct", "jacobi", "chebyshev" or
    /// "position".
    #[getter]
    fn global_solver(&self) -> &'static str {
        GLOBAL_SOLVER.name(with_solver!(&self.core, s => s.params().global_solver))
    }
    /// Jacobi sweeps per global iteration.
    #[getter]
    fn inner_iters(&self) -> usize {
        with_solver!(&self.core, s => s.params().inner_iters)
    }
    #[getter]
    fn record_energy(&self) -> bool {
        with_solver!(&self.core, s => s.params().record_energy)
    }
    #[getter]
    fn precision(&self) -> &'static str {
        PRECISION.name(self.core.float())
    }
    /// "cpu" or "gpu".
    #[getter]
    fn backend(&self) -> &'static str {
        BACKEND.name(self.core.backend())
    }
    #[getter]
    fn threads(&self) -> usize {
        self.core.threads()
    }
    /// Bytes the GPU kernels load and store per global iteration for the bodies of the last
    /// step (None on the CPU backend or before the first step).
    #[getter]
    fn bytes_per_iteration(&self) -> Option<u64> {
        match &self.core {
            Precision::Gpu32(s) => s.bytes_per_iteration(),
            Precision::Gpu64(s) => s.bytes_per_iteration(),
            _ => None,
        }
    }
    /// Simulation time (s).
    #[getter]
    fn time(&self) -> f64 {
        with_solver!(&self.core, s => s.clock().time)
    }
    #[getter]
    fn steps_taken(&self) -> u64 {
        with_solver!(&self.core, s => s.clock().steps)
    }
    /// Sets the simulation time (s) and step count, e.g. when restoring a saved state.
    fn set_clock(&mut self, time: Real, steps_taken: Int) -> PyResult<()> {
        let time = time.get("time")?;
        let steps_taken = steps_taken.get("steps_taken")?;
        let steps_taken = u64::try_from(steps_taken).map_err(|_| {
            PyValueError::new_err(format!("steps_taken must be >= 0, got {steps_taken}"))
        })?;
        let clock = Clock::at(time, steps_taken).py()?;
        with_solver!(&mut self.core, s => s.set_clock(clock));
        Ok(())
    }
    #[getter]
    fn bodies(&self, py: Python<'_>) -> Vec<Py<PyAny>> {
        self.bodies.iter().map(|b| b.object(py)).collect()
    }
    #[getter]
    fn colliders(&self, py: Python<'_>) -> Vec<Py<PyAny>> {
        self.colliders.iter().map(|c| c.clone_ref(py)).collect()
    }
    fn __repr__(&self) -> String {
        with_solver!(&self.core, s => {
            let p = s.params();
            format!(
                "Solver(dt={}, gravity={:?}, tol={}, particle_tol={}, max_iters={}, max_speed={}, two_level={}, backend='{}', precision='{}', threads={}, bodies={}, colliders={}, time={})",
                p.dt, p.gravity, p.tol, p.particle_tol, p.max_iters, p.max_speed, if p.particle_two_level { "True" } else { "False" }, self.backend(), self.precision(), self.core.threads(), self.bodies.len(), self.colliders.len(), s.clock().time
            )
        })
    }
}

impl PySolver {
    /// Warns (`peridyn.PrecisionWarning`, [`resolution::warn_resolution`]) for each of
    /// `warned` whose coordinates round away the motion of a step from rest, with `added`
    /// stepped too. Checked when a body is added, and before each step on the CPU backend (the
    /// GPU backend keeps positions on the device: only when added).
    fn warn_resolution(
        &self,
        py: Python<'_>,
        added: Option<&PyBody>,
        warned: &[&PyBody],
    ) -> PyResult<()> {
        let bodies: Vec<&PyBody> = self.bodies.iter().chain(added).collect();
        let (dt, gravity) = with_solver!(&self.core, s => (s.params().dt, s.params().gravity));
        let precision = match self.core.float() {
            Float::F32 => ("f32", f64::from(f32::EPSILON)),
            Float::F64 => ("f64", f64::EPSILON),
        };
        resolution::warn_resolution(py, &bodies, warned, precision, dt, &gravity.into())
    }

    /// `index` checked against the colliders added.
    fn collider_index(&self, index: Int) -> PyResult<usize> {
        let index = index.get("collider index")?;
        usize::try_from(index)
            .ok()
            .filter(|i| *i < self.colliders.len())
            .ok_or_else(|| {
                PyValueError::new_err(format!(
                    "collider index {index} is out of range: the solver has {} colliders",
                    self.colliders.len()
                ))
            })
    }
}

/// A pose as numpy arrays: rotation (3, 3) and translation (3,) in m.
type PoseArrays<'py> = (Bound<'py, PyAny>, Bound<'py, PyAny>);

fn pose_arrays<'py>(py: Python<'py>, pose: &Pose) -> PyResult<PoseArrays<'py>> {
    let rows = (0..3).map(|r| pose.rotation.row(r).transpose());
    Ok((
        to_numpy(py, rows)?,
        to_numpy_1d(py, pose.translation.as_slice().to_vec()),
    ))
}

/// A pose from optional Python arguments (default: identity, no translation), checked.
fn pose_arg(
    rotation: Option<&Bound<'_, PyAny>>,
    translation: Option<&Bound<'_, PyAny>>,
) -> PyResult<Pose> {
    let rows = match rotation {
        None => [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        Some(r) => rotation_rows(r, "rotation")?,
    };
    let translation = translation
        .map(|t| vec3(t, "translation"))
        .transpose()?
        .unwrap_or([0.0; 3]);
    Pose::new(rows, translation).py()
}

/// Refuses a time step `dt` (s) the precision `float` cannot step with: `h^2` (the gravity
/// kick and the inertia weights) must stay a normal number and `1/h` (the velocities) finite,
/// or every step would produce non-finite or zero velocities. `dt` not finite or not > 0 is
/// left to the core, which names it.
/// `max_iters` as a count: a negative value is refused here by name (the core's
/// [`SolverParams::validate`] refuses 0).
fn iteration_cap(max_iters: i64) -> PyResult<usize> {
    usize::try_from(max_iters)
        .map_err(|_| PyValueError::new_err(format!("max_iters must be >= 1, got {max_iters}")))
}

fn check_dt(dt: f64, float: Float) -> PyResult<()> {
    if !(dt.is_finite() && dt > 0.0) {
        return Ok(());
    }
    let (name, ok, smallest, largest) = match float {
        Float::F32 => {
            let h = dt as f32;
            let ok = (h * h).is_normal() && (1.0 / h).is_finite();
            ("f32", ok, f64::from(f32::MIN_POSITIVE), f64::from(f32::MAX))
        }
        Float::F64 => {
            let ok = (dt * dt).is_normal() && (1.0 / dt).is_finite();
            ("f64", ok, f64::MIN_POSITIVE, f64::MAX)
        }
    };
    if ok {
        return Ok(());
    }
    let (lo, hi) = (
        smallest.sqrt() * (1.0 + 1e-6),
        largest.sqrt() * (1.0 - 1e-6),
    );
    let what = if dt < 1.0 {
        format!(
            "dt^2 = {:e} underflows (the smallest normal {name} is {smallest:e})",
            dt * dt
        )
    } else {
        format!(
            "dt^2 = {:e} overflows (the largest {name} is {largest:e})",
            dt * dt
        )
    };
    let other = if name == "f32" {
        " or precision='f64'"
    } else {
        ""
    };
    Err(PyValueError::new_err(format!(
        "dt = {dt:e} s cannot be stepped in precision '{name}': {what}, so the velocities \
         (y - x) / dt would not be finite; use {lo:.3e} s <= dt <= {hi:.3e} s{other}"
    )))
}

fn no_gpu_poses() -> PyErr {
    PyValueError::new_err("the GPU backend does not move colliders by pose; use backend='cpu'")
}
