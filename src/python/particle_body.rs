//! Python wrapper of [`Particles`]. The body lives behind an `Arc<Mutex>` shared with the
//! solvers it was added to, as a membrane does.

use std::sync::{Arc, Mutex, MutexGuard};

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::particles::{
    DruckerPrager, Elastic, Granular, ParticleParams, Particles, RegionMaterial, FLUID_PLACEHOLDER,
};

use super::arrays::{indices as index_list, to_numpy, to_numpy_1d, vec3s};
use super::elastic::PyElastic;
use super::errors::{guard, IntoPyResult};
use super::fluid::PyViscoelasticFluid;
use super::granular::PyGranular;
use super::material_state;
use super::owner::Owner;
use super::pins;
use super::plasticity::PyDruckerPrager;
use super::rest_bonds;
use super::scalars::Real;

/// An elastic body of particles (He, Wang and Wu 2017) simulated by projective peridynamics.
#[pyclass(module = "peridyn._core", name = "Particles")]
pub struct PyParticles {
    pub inner: Arc<Mutex<Particles>>,
    /// The solver stepping it ([`Owner`]).
    pub owner: Owner,
}

impl PyParticles {
    pub fn lock(&self) -> MutexGuard<'_, Particles> {
        self.inner.lock().unwrap_or_else(|p| p.into_inner())
    }
}

impl PyParticles {
    fn wrap(body: Particles) -> Self {
        Self {
            inner: Arc::new(Mutex::new(body)),
            owner: Owner::default(),
        }
    }
}

/// The parameters of a particle body from the constructors' arguments, checked by name.
fn params_of(
    spacing: Real,
    density: Real,
    material: &Bound<'_, PyAny>,
    horizon: Option<Real>,
) -> PyResult<ParticleParams> {
    let material = match material.cast::<PyGranular>() {
        Ok(g) => granular_moduli(&g.get().inner),
        Err(_) => {
            material
                .cast::<PyElastic>()
                .map_err(|_| {
                    PyValueError::new_err(format!(
                        "material must be a peridyn.Elastic, peridyn.Granular or peridyn.ViscoelasticFluid, got {}",
                        material
                            .get_type()
                            .name()
                            .map_or("?".into(), |n| n.to_string())
                    ))
                })?
                .get()
                .inner
        }
    };
    Ok(ParticleParams {
        spacing: spacing.get("spacing")?,
        density: density.get("density")?,
        horizon: horizon.map(|h| h.get("horizon")).transpose()?,
        material,
    })
}

/// Refuses a granular or fluid material for a shell or a rod (sand and fluids come as
/// bodies of `peridyn.Particles(...)`).
fn elastic_only(material: &Bound<'_, PyAny>) -> PyResult<()> {
    let kind = if material.cast::<PyGranular>().is_ok() {
        "peridyn.Granular"
    } else if material.cast::<PyViscoelasticFluid>().is_ok() {
        "peridyn.ViscoelasticFluid"
    } else {
        return Ok(());
    };
    Err(PyValueError::new_err(format!(
        "material must be a peridyn.Elastic for a shell or a rod: a {kind} body is made with \
         peridyn.Particles(...)"
    )))
}

/// The nominal moduli of a granular body (its stiffness per particle follows its density):
/// `mu = 0`, `lam = K_f`.
fn granular_moduli(g: &Granular) -> Elastic {
    Elastic::Paper {
        mu: 0.0,
        lam: g.friction_stiffness,
    }
}

/// The plastic law of the constructor's `plasticity` argument (a `peridyn.DruckerPrager`).
fn plasticity_of(p: &Bound<'_, PyAny>) -> PyResult<DruckerPrager> {
    p.cast::<PyDruckerPrager>()
        .map(|d| d.get().inner)
        .map_err(|_| {
            PyValueError::new_err(format!(
                "plasticity must be None or a peridyn.DruckerPrager, got {}",
                p.get_type().name().map_or("?".into(), |n| n.to_string())
            ))
        })
}

/// A fluid body (`material=ViscoelasticFluid(...)`): no horizon or plasticity of its own.
fn fluid_body(
    py: Python<'_>,
    positions: &Bound<'_, PyAny>,
    spacing: Real,
    density: Real,
    fluid: crate::particles::ViscoelasticFluid,
    horizon: Option<Real>,
    plasticity: Option<&Bound<'_, PyAny>>,
) -> PyResult<PyParticles> {
    if horizon.is_some() || plasticity.is_some() {
        return Err(PyValueError::new_err(
            "a ViscoelasticFluid body takes no horizon or plasticity: its neighbourhoods are the SPH support (2.2 spacings)",
        ));
    }
    let (spacing, density) = (spacing.get("spacing")?, density.get("density")?);
    let x = vec3s(positions, "positions", None)?;
    let body = py.detach(|| {
        guard("Particles()", || {
            Particles::fluid(x, spacing, density, fluid)
        })
    })?;
    Ok(PyParticles::wrap(body))
}

#[pymethods]
impl PyParticles {
    #[new]
    #[pyo3(signature = (positions, *, spacing, density, material, horizon = None, plasticity = None))]
    fn new(
        py: Python<'_>,
        positions: &Bound<'_, PyAny>,
        spacing: Real,
        density: Real,
        material: &Bound<'_, PyAny>,
        horizon: Option<Real>,
        plasticity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        if let Ok(fluid) = material.cast::<PyViscoelasticFluid>() {
            return fluid_body(
                py,
                positions,
                spacing,
                density,
                fluid.get().inner,
                horizon,
                plasticity,
            );
        }
        let plasticity = plasticity.map(plasticity_of).transpose()?;
        let granular = material.cast::<PyGranular>().ok().map(|g| g.get().inner);
        if granular.is_some() && plasticity.is_some() {
            return Err(PyValueError::new_err(
                "plasticity must be None for a peridyn.Granular material, which yields by its \
                 own friction angle",
            ));
        }
        let params = params_of(spacing, density, material, horizon)?;
        let x = vec3s(positions, "positions", None)?;
        let body = py.detach(|| {
            guard("Particles()", || {
                let mut body = Particles::new(x, params)?;
                match granular {
                    Some(g) => body.set_granular(g)?,
                    None => body.set_plasticity(plasticity)?,
                }
                Ok(body)
            })
        })?;
        Ok(Self::wrap(body))
    }

    /// A shell: one layer of particles on a surface with two ghost layers (see thin.rs).
    #[staticmethod]
    #[pyo3(signature = (mesh, *, spacing, thickness, density, material, horizon = None, seed = 0))]
    #[allow(clippy::too_many_arguments)]
    fn shell(
        py: Python<'_>,
        mesh: &Bound<'_, PyAny>,
        spacing: Real,
        thickness: Real,
        density: Real,
        material: &Bound<'_, PyAny>,
        horizon: Option<Real>,
        seed: i128,
    ) -> PyResult<Self> {
        elastic_only(material)?;
        let params = params_of(spacing, density, material, horizon)?;
        super::thin::shell(py, mesh, thickness.get("thickness")?, seed, params).map(Self::wrap)
    }

    /// A rod: a line of particles with four ghosts around each (see thin.rs).
    #[staticmethod]
    #[pyo3(signature = (points, *, spacing, radius, density, material, horizon = None))]
    fn rod(
        py: Python<'_>,
        points: &Bound<'_, PyAny>,
        spacing: Real,
        radius: Real,
        density: Real,
        material: &Bound<'_, PyAny>,
        horizon: Option<Real>,
    ) -> PyResult<Self> {
        elastic_only(material)?;
        let params = params_of(spacing, density, material, horizon)?;
        super::thin::rod(py, points, radius.get("radius")?, params).map(Self::wrap)
    }

    /// Number of real (non-ghost) particles: particles `0..num_real` (the rest are ghosts).
    #[getter]
    fn num_real(&self) -> usize {
        self.lock().num_real()
    }
    /// (num_real, 3) positions of the real particles (m): `positions[:num_real]`.
    #[getter]
    fn real_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let p = self.lock();
        to_numpy(py, p.positions()[..p.num_real()].iter().copied())
    }
    /// (N - num_real,) the real particle each ghost belongs to (int64).
    #[getter]
    fn ghost_owner<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        to_numpy_1d(
            py,
            self.lock()
                .ghost_owners()
                .iter()
                .map(|&o| o as i64)
                .collect(),
        )
    }

    #[getter]
    fn num_particles(&self) -> usize {
        self.lock().num_particles()
    }
    /// (N, 3) current positions (m); settable.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_numpy(py, self.lock().positions().iter().copied())
    }
    #[setter]
    fn set_positions(&self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let mut p = self.lock();
        let n = p.num_particles();
        p.set_positions(vec3s(value, "positions", Some(n))?).py()
    }
    /// (N, 3) velocities (m/s); settable.
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_numpy(py, self.lock().velocities().iter().copied())
    }
    #[setter]
    fn set_velocities(&self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let mut p = self.lock();
        let n = p.num_particles();
        p.set_velocities(vec3s(value, "velocities", Some(n))?).py()
    }
    /// (N, 3) reference positions (m).
    #[getter]
    fn rest_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_numpy(py, self.lock().reference().iter().copied())
    }
    /// Lattice spacing (m).
    #[getter]
    fn spacing(&self) -> f64 {
        self.lock().params().spacing
    }
    /// Density (kg/m^3).
    #[getter]
    fn density(&self) -> f64 {
        self.lock().params().density
    }
    /// Horizon radius (m).
    #[getter]
    fn horizon(&self) -> f64 {
        self.lock().horizon()
    }
    /// The material: a ``peridyn.Elastic``, the ``peridyn.Granular`` of sand or the
    /// ``peridyn.ViscoelasticFluid`` of a fluid.
    #[getter]
    fn material(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let p = self.lock();
        if let Some(&inner) = p.fluid_material() {
            return Ok(Py::new(py, PyViscoelasticFluid { inner })?.into_any());
        }
        Ok(match p.granular() {
            Some(&inner) => Py::new(py, PyGranular { inner })?.into_any(),
            None => Py::new(
                py,
                PyElastic {
                    inner: p.params().material,
                },
            )?
            .into_any(),
        })
    }
    /// Changes the material during a run (He et al. 2017, Fig. 19): ``material`` an
    /// ``Elastic`` (the body becomes a solid whose bonds are born at the current positions)
    /// or a ``ViscoelasticFluid`` (it melts). Positions, velocities and pins are kept; solvers
    /// rebuild the body's working set at their next step. ValueError, changing nothing, for
    /// another material, a shell, rod or sand, a plastic body made fluid, or a particle whose
    /// neighbourhood at the current positions is not three-dimensional (named).
    ///
    /// With ``indices``, only those particles change (a region, Fig. 19: between a Newtonian
    /// fluid and an elastic solid; bonds between solid particles of which one changed are born
    /// at the current positions, bonds across the fluid-solid boundary carry nothing, the
    /// fluid's density constraints see the solid particles: docs/particles/couplings.md).
    /// ValueError naming a bad index, or a material other than the body's elastic or fluid one.
    #[pyo3(signature = (material, indices = None))]
    fn set_material(
        &self,
        py: Python<'_>,
        material: &Bound<'_, PyAny>,
        indices: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let (elastic, fluid) = if let Ok(f) = material.cast::<PyViscoelasticFluid>() {
            (FLUID_PLACEHOLDER, Some(f.get().inner))
        } else if let Ok(e) = material.cast::<PyElastic>() {
            (e.get().inner, None)
        } else {
            return Err(PyValueError::new_err(format!(
                "material must be a peridyn.Elastic or peridyn.ViscoelasticFluid, got {}",
                material
                    .get_type()
                    .name()
                    .map_or("?".into(), |n| n.to_string())
            )));
        };
        let region = indices
            .filter(|i| !i.is_none())
            .map(|i| index_list(i, "indices"))
            .transpose()?;
        let inner = &self.inner;
        py.detach(|| {
            guard("Particles.set_material()", || {
                let mut body = inner.lock().unwrap_or_else(|p| p.into_inner());
                match &region {
                    None => body.set_material(elastic, fluid),
                    Some(list) => body.set_material_of(
                        list,
                        fluid.map_or(RegionMaterial::Solid(elastic), RegionMaterial::Fluid),
                    ),
                }
            })
        })
    }
    /// A sand body's water saturation per particle (float64, in [0, 1]): the material's,
    /// risen where a liquid in the same solver has reached the grains and wicked on from
    /// grain to grain (docs/particles/couplings.md, "Liquid with wet sand"); None for a body that
    /// is not sand.
    #[getter]
    fn saturation<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyAny>> {
        self.lock().saturation().map(|t| to_numpy_1d(py, t))
    }
    /// (N,) pressure of each fluid particle's density constraint over the last step (Pa,
    /// float64, read-only): `p_i = -kappa rho0 lambda_i / h^2` of the projection's
    /// multipliers summed over the step's passes, `kappa` = 0.817 the kernel's gradient
    /// factor on the lattice (docs/particles/fluids.md, round y2). Zeros before the first step,
    /// after ``positions`` were set (the last step's pressure was of other positions; so after
    /// ``load_state`` too) and at particles without a constraint (solids); not part of a saved
    /// state (the next step does not start from it).
    #[getter]
    fn pressure<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        to_numpy_1d(py, self.lock().pressure())
    }
    /// Per particle, whether it is a fluid particle (bool array): all True for a fluid body,
    /// all False for a solid, mixed once ``set_material(material, indices)`` changed a region.
    #[getter]
    fn fluid_particles<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        let p = self.lock();
        let mask = (0..p.num_particles())
            .map(|i| p.is_fluid_particle(i))
            .collect();
        to_numpy_1d(py, mask)
    }
    /// The resolved moduli (Pa): {'mu', 'lam', 'kappa'} (the paper's mu and lam, and the
    /// dilatation modulus beyond the paper; 0 for `Elastic(mu=, lam=)`).
    #[getter]
    fn moduli(&self) -> (f64, f64, f64) {
        let m = self.lock().moduli();
        (m.mu, m.lam, m.kappa)
    }
    /// Mass of each particle (kg): density times spacing^3.
    #[getter]
    fn particle_mass(&self) -> f64 {
        self.lock().particle_mass()
    }
    /// The plastic law, or None for an elastic body.
    #[getter]
    fn plasticity(&self) -> Option<PyDruckerPrager> {
        self.lock()
            .plasticity()
            .map(|&inner| PyDruckerPrager { inner })
    }
    /// For a plastic body, (sqrt_J2, strength) per particle (Pa, float64 arrays): the
    /// Drucker-Prager measure `sqrt(J2)` and `A + B I1` at the current positions and
    /// reference bonds (NaN for a particle without a three-dimensional neighbourhood); it
    /// yields where `sqrt_J2 > strength`. None for an elastic body.
    fn yield_state<'py>(&self, py: Python<'py>) -> Option<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let states = self.lock().yield_states()?;
        let pick = |f: fn(&crate::particles::YieldState) -> f64| {
            states
                .iter()
                .map(|s| s.as_ref().map_or(f64::NAN, f))
                .collect::<Vec<f64>>()
        };
        Some((
            to_numpy_1d(py, pick(|s| s.sqrt_j2)),
            to_numpy_1d(py, pick(|s| s.strength)),
        ))
    }
    /// CSR (offsets, indices) of every particle's neighbours (int64): within the horizon at
    /// rest, or for a plastic body the bonds it has now (searched on deformed positions).
    fn neighborhood<'py>(&self, py: Python<'py>) -> (Bound<'py, PyAny>, Bound<'py, PyAny>) {
        let p = self.lock();
        let h = p.current_rest_bonds();
        (
            to_numpy_1d(py, h.offsets.iter().map(|&o| o as i64).collect()),
            to_numpy_1d(py, h.indices.iter().map(|&o| o as i64).collect()),
        )
    }
    /// A plastic body's current reference bonds as a dict of arrays (``offsets`` (N + 1,) and
    /// ``neighbours`` (B,) int64 in CSR, ``vectors`` (B, 3) m, ``born`` (B,) m the length
    /// each bond's weight was set at, ``plastic_strain`` (N,), ``volume`` (N,) the volume each
    /// particle's reference bonds span over its rest volume), which the returns and the
    /// neighbour rebuilds of the steps so far have made; None for an elastic body. Settable
    /// (checked whole; None goes back to the reference positions' bonds): what
    /// ``peridyn.save_state`` saves and ``load_state`` restores.
    #[getter]
    fn rest_bonds<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let p = self.lock();
        if p.plasticity().is_none() {
            return Ok(None);
        }
        rest_bonds::to_dict(py, p.current_rest_bonds()).map(Some)
    }
    #[setter]
    fn set_rest_bonds(&self, value: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        let bonds = match value {
            None => None,
            Some(v) if v.is_none() => None,
            Some(v) => {
                let dict = v.cast::<PyDict>().map_err(|_| {
                    PyValueError::new_err(format!(
                        "rest_bonds must be None or a dict, got {}",
                        v.get_type().name().map_or("?".into(), |n| n.to_string())
                    ))
                })?;
                Some(rest_bonds::from_dict(dict)?)
            }
        };
        self.lock().restore_rest_bonds(bonds).py()
    }
    /// What the body's material has become during the run, as a dict of numpy arrays (an
    /// optional part empty when absent): ``elastic`` ``[0, mu, lam]`` (Pa) or ``[1, E, nu]``;
    /// ``fluid`` the fluid's parameters or empty; ``horizon`` (m) or empty for the default;
    /// ``reference`` (N, 3) m, the positions the bonds are measured from (the positions at a
    /// ``set_material``); ``fluid_mask`` (N,) bool of a mixed body; ``wetted`` (N,) a sand
    /// body's saturations once a liquid wetted it; ``region_<name>`` a mixed body's bonds (the
    /// entries of ``rest_bonds``). Settable into a body set up as the one it came from (checked
    /// whole; parts equal to the body's own change nothing): what ``peridyn.save_state`` saves
    /// and ``load_state`` restores.
    #[getter]
    fn material_state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let state = self.lock().material_state();
        material_state::to_dict(py, state)
    }
    #[setter]
    fn set_material_state(&self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let dict = value.cast::<PyDict>().map_err(|_| {
            PyValueError::new_err(format!(
                "material_state must be a dict, got {}",
                value
                    .get_type()
                    .name()
                    .map_or("?".into(), |n| n.to_string())
            ))
        })?;
        let state = material_state::from_dict(dict)?;
        guard("Particles.material_state", || {
            self.lock().restore_material_state(state)
        })
    }
    /// Fixes particles at `targets` ((len(indices), 3) m; default: where they are now); a
    /// shell's or rod's ghost particles follow their real particle.
    #[pyo3(signature = (indices, targets = None))]
    fn pin(&self, indices: &Bound<'_, PyAny>, targets: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        pins::pin(|| Ok(self.lock()), indices, targets)
    }
    /// Releases the given pinned particles (all when None).
    #[pyo3(signature = (indices = None))]
    fn unpin(&self, indices: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        pins::unpin(&mut *self.lock(), indices)
    }
    /// Sorted indices of the pinned particles (int64).
    #[getter]
    fn pinned<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        pins::pinned(py, &*self.lock())
    }
    /// (P, 3) targets of the pinned particles (m), in the order of `pinned`; settable.
    #[getter]
    fn pin_targets<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        pins::pin_targets(py, &*self.lock())
    }
    #[setter]
    fn set_pin_targets(&self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        pins::set_pin_targets(&mut *self.lock(), value)
    }
    /// Elastic energy (J, eq. 8 with the dilatation term) at the current positions.
    fn elastic_energy(&self, py: Python<'_>) -> PyResult<f64> {
        let inner = self.inner.clone();
        py.detach(move || {
            guard("Particles.elastic_energy", || {
                inner
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .elastic_energy()
            })
        })
    }
    /// (N, 3) internal forces (N) at the current positions (eq. 12).
    fn internal_forces<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let inner = self.inner.clone();
        let f = py.detach(move || {
            guard("Particles.internal_forces", || {
                inner
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .internal_forces()
            })
        })?;
        to_numpy(py, f.into_iter())
    }
    /// Kinetic energy (J).
    fn kinetic_energy(&self) -> f64 {
        self.lock().kinetic_energy()
    }
    fn __repr__(&self) -> String {
        let p = self.lock();
        let params = p.params();
        format!(
            "Particles(particles={}, spacing={}, density={}, horizon={}, material={}, pinned={})",
            p.num_particles(),
            params.spacing,
            params.density,
            p.horizon(),
            match (p.fluid_material(), p.granular()) {
                (Some(&inner), _) => PyViscoelasticFluid { inner }.__repr__(),
                (None, Some(&inner)) => PyGranular { inner }.__repr__(),
                (None, None) => PyElastic {
                    inner: params.material,
                }
                .__repr__(),
            },
            p.pins().len()
        )
    }
}
