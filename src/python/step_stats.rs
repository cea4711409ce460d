//! Python wrapper of [`StepStats`]: what one time step did, with its phase timings and the
//! contact and particle figures as dicts.

use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::solve::StepStats;

use super::arrays::to_numpy_1d;

/// What one time step did.
#[pyclass(module = "peridyn._core", name = "StepStats", frozen)]
pub struct PyStepStats {
    inner: StepStats,
}

impl From<StepStats> for PyStepStats {
    fn from(inner: StepStats) -> Self {
        Self { inner }
    }
}

#[pymethods]
impl PyStepStats {
    #[getter]
    fn iterations(&self) -> usize {
        self.inner.iterations
    }
    /// The last iteration's max_i |y_i^k - y_i^(k-1)| (m): the last of ``moves``.
    #[getter]
    fn last_move(&self) -> f64 {
        self.inner.last_move()
    }
    /// Estimated distance (m) from the result to the exact implicit Euler solution: the last of
    /// ``residuals``.
    #[getter]
    fn residual(&self) -> f64 {
        self.inner.residual()
    }
    #[getter]
    fn converged(&self) -> bool {
        self.inner.converged
    }
    /// Largest vertex move of each iteration (m).
    #[getter]
    fn moves<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        to_numpy_1d(py, self.inner.moves.clone())
    }
    /// The convergence measure ``residual`` after each iteration (m).
    #[getter]
    fn residuals<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        to_numpy_1d(py, self.inner.residuals.clone())
    }
    /// Total variational energy E(y^k) (J) of every iterate k = 0..iterations (empty unless the
    /// solver was built with record_energy=True).
    #[getter]
    fn energies<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        to_numpy_1d(py, self.inner.energies.clone())
    }
    /// ``method="newton"``: Hessian products of its conjugate-gradient solves in the step (0
    /// for the other methods).
    #[getter]
    fn linear_products(&self) -> usize {
        self.inner.linear_products
    }
    /// ``method="newton"``: milliseconds per phase of its iterations, summed over the step
    /// (``jacobi``: SISSM's systems and residual; ``models``: the Hessian models;
    /// ``coarse_assembly``, ``coarse_factor``: the coarse level; ``cg``: the conjugate
    /// gradients; ``line_search``: its trials), and the counts ``factorizations`` (of the
    /// coarse matrix) and ``trials`` (line-search kernel passes). Zeros for the other methods.
    #[getter]
    fn newton<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let t = &self.inner.newton;
        let d = PyDict::new(py);
        for (k, v) in [
            ("jacobi", t.jacobi),
            ("models", t.models),
            ("coarse_assembly", t.coarse_assembly),
            ("coarse_factor", t.coarse_factor),
            ("cg", t.cg),
            ("line_search", t.line_search),
        ] {
            d.set_item(k, v)?;
        }
        d.set_item("factorizations", t.factorizations)?;
        d.set_item("trials", t.trials)?;
        Ok(d)
    }
    /// Milliseconds per phase.
    #[getter]
    fn timings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let t = &self.inner.timings;
        let d = PyDict::new(py);
        for (k, v) in [
            ("predict", t.predict),
            ("global", t.global),
            ("kernel", t.kernel),
            ("colliders", t.colliders),
            ("finish", t.finish),
            ("plasticity", t.plasticity),
            ("neighbours", t.neighbours),
            ("density", t.density),
            ("viscosity", t.viscosity),
            ("redistribution", t.redistribution),
            ("coupling", t.coupling),
            ("contact", t.contact),
            ("total", t.total),
        ] {
            d.set_item(k, v)?;
        }
        Ok(d)
    }
    /// Contact figures of the step (zeros when contact is off): `candidate_pairs` (triangle
    /// pairs of the broad phase's last build, largest over the iterations), `box_pairs` (the
    /// triangle pairs of that build whose inflated boxes overlap, before the distance test that
    /// leaves the candidates; largest), `cached_pairs` (primitive pairs of that build and of
    /// the repairs since, which each filter chooses from; largest), `primitive_pairs`
    /// (primitive pairs that may come within the barrier's reach, largest), `active_pairs`
    /// (primitive pairs within the barrier's reach at the end), `local_iterations` (descent
    /// iterations, summed), `clamped` (vertices the final CCD clamp moved, summed),
    /// `ccd_queries` (primitive pair CCD queries, summed), `broad_phase_builds` (summed; the
    /// other local steps reused the last build), `cache_repairs` (summed; repairs of the last
    /// build for a few vertices that strayed beyond their skins, each instead of a build),
    /// `live_refreshes` (filterings of the cached pairs into the live list, summed), `sweeps`
    /// (those filterings that looked at every cached pair near enough afresh, summed; the
    /// others looked again only at the pairs that may have come nearer since the last
    /// sweep), milliseconds `broad_phase_ms`, `ccd_ms`, `descent_ms`, and `barrier_energy`
    /// (J, the barrier's energy `d mu B / h^2` at the step's end, see docs/model.md).
    #[getter]
    fn contact<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = &self.inner.contact;
        let d = PyDict::new(py);
        d.set_item("candidate_pairs", c.candidate_pairs)?;
        d.set_item("box_pairs", c.box_pairs)?;
        d.set_item("cached_pairs", c.cached_pairs)?;
        d.set_item("primitive_pairs", c.primitive_pairs)?;
        d.set_item("active_pairs", c.active_pairs)?;
        d.set_item("local_iterations", c.iterations)?;
        d.set_item("clamped", c.clamped)?;
        d.set_item("ccd_queries", c.ccd_queries)?;
        d.set_item("broad_phase_builds", c.broad_phase_builds)?;
        d.set_item("cache_repairs", c.cache_repairs)?;
        d.set_item("live_refreshes", c.live_refreshes)?;
        d.set_item("sweeps", c.sweeps)?;
        d.set_item("broad_phase_ms", c.broad_phase_ms)?;
        d.set_item("ccd_ms", c.ccd_ms)?;
        d.set_item("descent_ms", c.descent_ms)?;
        d.set_item("barrier_energy", c.barrier_energy)?;
        Ok(d)
    }
    /// The particle bodies' share of the step (zeros without them), from its start (the
    /// initial guess included): milliseconds `kernel_ms` (the local step and forces at the
    /// iterates), `residual_ms` (the residual of eq. 12 and its merit), `solve_ms` (the global
    /// solver's move, refactorisations included; of it `coarse_ms`, the bodies' coarse
    /// translation, and `two_level_ms`, the two-level correction), `line_search_ms` (the
    /// trials of eq. 13; of it `trial_kernel_ms`, their kernel passes), `project_ms` (collider projection, extrapolation, measures); `evaluations` (kernel
    /// passes, trials included), `factorizations` (numeric, of the direct solver's matrix or
    /// the two-level correction's coarse matrix), `analyses` (symbolic: a new pattern, on the
    /// first step and after a plastic body's neighbourhoods changed) and `held_static` (granular particles that static friction held, eq. 28); for fluids
    /// `density_passes` (density projections) and `density_error` (the largest relative
    /// excess density `rho / rho0 - 1` they left); `roundoff_floor` (m), the largest round-off
    /// floor `eps |y_i| D_i / m_i` the last convergence measure subtracted (it grows with the
    /// distance from the family's frame origin, near its bodies, or from the world origin
    /// when membranes share the step: a floor above the tolerance means the step converged to what
    /// the precision resolves there), and `worst_particle`, `(body, index)` of the particle
    /// holding that measure's largest term, `None` when every particle is within its floor.
    #[getter]
    fn particles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let p = &self.inner.particles;
        let d = PyDict::new(py);
        for (k, v) in [
            ("kernel_ms", p.kernel),
            ("residual_ms", p.residual),
            ("solve_ms", p.solve),
            ("coarse_ms", p.coarse),
            ("two_level_ms", p.two_level),
            ("line_search_ms", p.line_search),
            ("trial_kernel_ms", p.trial_kernel),
            ("project_ms", p.project),
        ] {
            d.set_item(k, v)?;
        }
        d.set_item("evaluations", p.evaluations)?;
        d.set_item("factorizations", p.factorizations)?;
        d.set_item("analyses", p.analyses)?;
        d.set_item("held_static", p.held_static)?;
        d.set_item("density_passes", p.density_passes)?;
        d.set_item("density_error", p.density_error)?;
        d.set_item("roundoff_floor", p.roundoff_floor)?;
        d.set_item("worst_particle", p.worst_particle)?;
        Ok(d)
    }
    /// Simulation time after the step (s).
    #[getter]
    fn time(&self) -> f64 {
        self.inner.time
    }
    /// 0-based index of the step.
    #[getter]
    fn step(&self) -> u64 {
        self.inner.step
    }
    fn __repr__(&self) -> String {
        format!(
            "StepStats(step={}, iterations={}, last_move={:.3e}, converged={}, total_ms={:.3})",
            self.inner.step,
            self.inner.iterations,
            self.inner.last_move(),
            self.inner.converged,
            self.inner.timings.total
        )
    }
}
