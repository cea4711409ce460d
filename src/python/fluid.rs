//! Python wrapper of the fluid material, [`ViscoelasticFluid`].

use pyo3::prelude::*;

use crate::particles::{DensitySolver, ViscoelasticFluid};

use super::errors::IntoPyResult;
use super::scalars::{Flag, Int, Real, Text};

/// A fluid material of particle bodies (He et al. 2017, section 6): position-based density
/// constraints and an implicit viscosity; the defaults make a Newtonian liquid.
#[pyclass(module = "peridyn._core", name = "ViscoelasticFluid", frozen)]
#[derive(Clone, Copy)]
pub struct PyViscoelasticFluid {
    pub inner: ViscoelasticFluid,
}

#[pymethods]
impl PyViscoelasticFluid {
    /// `viscosity` (dynamic, Pa s, >= 0), `density_iterations` (most projections per step,
    /// >= 1; a conjugate-gradient iteration counts as one), `density_solver` (`"cg"`,
    /// the default: each linearisation's coupled system by preconditioned conjugate
    /// gradients; `"jacobi"`: Macklin and Mueller's Jacobi projections), `density_tolerance` (relative, in (0, 0.1]) and `relaxation` (the constraints'
    /// eps as a fraction of their rest-lattice denominator, > 0), `redistribution` (strength
    /// in [0, 1] of eq. 21-24, 0: none) and `redistribution_iterations` (passes per step, in
    /// [1, 100]), `shear_modulus` (Pa, >= 0: a viscoelastic fluid's elasticity; 0: Newtonian)
    /// and `yield_stress` (Pa, > 0; None: the shear modulus), `bulk_modulus` (Pa, the
    /// elasticity's, 2/3 to 29/3 of the shear modulus; None: 5/3 of it), `adhesion` (the liquid sticks to
    /// the body's pinned ghost particles by two-sided density constraints), `surface_tension`
    /// (N/m, >= 0; 0: none), `plastic_viscosity` (Pa s, >= 0: the Bingham viscosity of a
    /// viscoelastic fluid's flow beyond yield, which relaxes its overstress over
    /// `plastic_viscosity / shear_modulus`; 0: rate-independent).
    #[new]
    #[pyo3(signature = (*, viscosity = Real::of(1e-3), density_iterations = Int::of(50), density_solver = Text::of("cg"), density_tolerance = Real::of(1e-3), relaxation = Real::of(0.1), redistribution = Real::of(0.0), redistribution_iterations = Int::of(5), shear_modulus = Real::of(0.0), yield_stress = None, bulk_modulus = None, adhesion = Flag::of(false), surface_tension = Real::of(0.0), plastic_viscosity = Real::of(0.0)))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        viscosity: Real,
        density_iterations: Int,
        density_solver: Text,
        density_tolerance: Real,
        relaxation: Real,
        redistribution: Real,
        redistribution_iterations: Int,
        shear_modulus: Real,
        yield_stress: Option<Real>,
        bulk_modulus: Option<Real>,
        adhesion: Flag,
        surface_tension: Real,
        plastic_viscosity: Real,
    ) -> PyResult<Self> {
        let density_iterations = density_iterations.get("density_iterations")?;
        let redistribution_iterations =
            redistribution_iterations.get("redistribution_iterations")?;
        let iterations = usize::try_from(density_iterations).map_err(|_| {
            pyo3::exceptions::PyValueError::new_err(format!(
                "density_iterations must be at least 1, got {density_iterations}"
            ))
        })?;
        let passes = usize::try_from(redistribution_iterations).map_err(|_| {
            pyo3::exceptions::PyValueError::new_err(format!(
                "redistribution_iterations must be in [1, 100], got {redistribution_iterations}"
            ))
        })?;
        let inner = ViscoelasticFluid {
            viscosity: viscosity.get("viscosity")?,
            density_iterations: iterations,
            density_solver: DensitySolver::of_name(density_solver.get("density_solver")?).py()?,
            density_tolerance: density_tolerance.get("density_tolerance")?,
            relaxation: relaxation.get("relaxation")?,
            redistribution: redistribution.get("redistribution")?,
            redistribution_iterations: passes,
            shear_modulus: shear_modulus.get("shear_modulus")?,
            yield_stress: yield_stress.map(|y| y.get("yield_stress")).transpose()?,
            bulk_modulus: bulk_modulus.map(|k| k.get("bulk_modulus")).transpose()?,
            adhesion: adhesion.get("adhesion")?,
            surface_tension: surface_tension.get("surface_tension")?,
            plastic_viscosity: plastic_viscosity.get("plastic_viscosity")?,
        };
        inner.validate().py()?;
        Ok(Self { inner })
    }
    /// Dynamic viscosity (Pa s).
    #[getter]
    fn viscosity(&self) -> f64 {
        self.inner.viscosity
    }
    #[getter]
    fn density_iterations(&self) -> usize {
        self.inner.density_iterations
    }
    /// `"jacobi"` or `"cg"`.
    #[getter]
    fn density_solver(&self) -> &'static str {
        self.inner.density_solver.name()
    }
    #[getter]
    fn density_tolerance(&self) -> f64 {
        self.inner.density_tolerance
    }
    #[getter]
    fn relaxation(&self) -> f64 {
        self.inner.relaxation
    }
    #[getter]
    fn redistribution(&self) -> f64 {
        self.inner.redistribution
    }
    #[getter]
    fn redistribution_iterations(&self) -> usize {
        self.inner.redistribution_iterations
    }
    /// Shear modulus (Pa; 0: a Newtonian liquid).
    #[getter]
    fn shear_modulus(&self) -> f64 {
        self.inner.shear_modulus
    }
    /// Yield stress (Pa; None: the shear modulus).
    #[getter]
    fn yield_stress(&self) -> Option<f64> {
        self.inner.yield_stress
    }
    /// Bulk modulus of the elasticity (Pa; None: 5/3 of the shear modulus).
    #[getter]
    fn bulk_modulus(&self) -> Option<f64> {
        self.inner.bulk_modulus
    }
    /// Whether the liquid adheres to the body's ghost (pinned) particles.
    #[getter]
    fn adhesion(&self) -> bool {
        self.inner.adhesion
    }
    /// Surface tension (N/m; 0: none).
    #[getter]
    fn surface_tension(&self) -> f64 {
        self.inner.surface_tension
    }
    /// Plastic (Bingham) viscosity of the flow beyond yield (Pa s; 0: rate-independent).
    #[getter]
    fn plastic_viscosity(&self) -> f64 {
        self.inner.plastic_viscosity
    }
    pub(crate) fn __repr__(&self) -> String {
        let f = &self.inner;
        let optional = |v: Option<f64>| v.map_or("None".to_string(), |v| v.to_string());
        let (yield_stress, bulk_modulus) = (optional(f.yield_stress), optional(f.bulk_modulus));
        format!(
            "ViscoelasticFluid(viscosity={}, density_iterations={}, density_solver=\"{}\", density_tolerance={}, relaxation={}, redistribution={}, redistribution_iterations={}, shear_modulus={}, yield_stress={}, bulk_modulus={}, adhesion={}, surface_tension={}, plastic_viscosity={})",
            f.viscosity, f.density_iterations, f.density_solver.name(), f.density_tolerance, f.relaxation, f.redistribution, f.redistribution_iterations, f.shear_modulus, yield_stress, bulk_modulus, if f.adhesion { "True" } else { "False" }, f.surface_tension, f.plastic_viscosity
        )
    }
}
