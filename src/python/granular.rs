//! Python wrapper of the granular particle material, [`Granular`].

use pyo3::prelude::*;

use crate::error::check_param;
use crate::particles::{Granular, DEFAULT_WICKING};

use super::errors::IntoPyResult;
use super::scalars::Real;

/// Dry and wet sand (He et al. 2017, section 7, eq. 25-28): a particle material whose
/// stiffness follows its SPH density, with a friction angle and static friction.
#[pyclass(module = "peridyn._core", name = "Granular", frozen)]
#[derive(Clone, Copy)]
pub struct PyGranular {
    pub inner: Granular,
}

#[pymethods]
impl PyGranular {
    /// `friction_angle` (degrees, in (0, 90)), `saturation` (water, in [0, 1]); the
    /// reference friction stiffness `K_f` (Pa) and its hardening `H_f`, the reference
    /// cohesion stiffness `K_c` (Pa) and falloff `H_0`, the debonding scale `b`, and the
    /// static friction `eta` (in (0, 1], None for none), the grains' contact friction
    /// coefficient `mu_c` (>= 0), their rolling resistance `mu_r` (>= 0, None for grains that
    /// do not turn), the capillary diffusivity `wicking` (m^2/s, in [0, 0.01])
    /// of the water the grains hold: docs/particles/granular.md.
    #[new]
    #[pyo3(signature = (
        *, friction_angle, saturation = Real::of(0.0),
        friction_stiffness = Real::of(1e5), friction_hardening = Real::of(10.0),
        cohesion_stiffness = Real::of(2e4), cohesion_falloff = Real::of(10.0),
        debonding = Real::of(1.0), static_friction = Some(Real::of(0.8)),
        contact_friction = Real::of(0.0), rolling_resistance = None,
        wicking = Real::of(DEFAULT_WICKING),
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        friction_angle: Real,
        saturation: Real,
        friction_stiffness: Real,
        friction_hardening: Real,
        cohesion_stiffness: Real,
        cohesion_falloff: Real,
        debonding: Real,
        static_friction: Option<Real>,
        contact_friction: Real,
        rolling_resistance: Option<Real>,
        wicking: Real,
    ) -> PyResult<Self> {
        let inner = Granular {
            friction_angle: friction_angle.get("friction_angle")?,
            saturation: saturation.get("saturation")?,
            friction_stiffness: friction_stiffness.get("friction_stiffness")?,
            friction_hardening: friction_hardening.get("friction_hardening")?,
            cohesion_stiffness: cohesion_stiffness.get("cohesion_stiffness")?,
            cohesion_falloff: cohesion_falloff.get("cohesion_falloff")?,
            debonding: debonding.get("debonding")?,
            static_friction: static_friction
                .map(|s| s.get("static_friction"))
                .transpose()?,
            contact_friction: contact_friction.get("contact_friction")?,
            rolling_resistance: rolling_resistance
                .map(|r| r.get("rolling_resistance"))
                .transpose()?,
            wicking: wicking.get("wicking")?,
        };
        inner.validate().py()?;
        Ok(Self { inner })
    }
    /// Internal friction angle (degrees).
    #[getter]
    fn friction_angle(&self) -> f64 {
        self.inner.friction_angle
    }
    /// Water saturation (0 to 1).
    #[getter]
    fn saturation(&self) -> f64 {
        self.inner.saturation
    }
    /// Reference friction stiffness `K_f` (Pa, eq. 25).
    #[getter]
    fn friction_stiffness(&self) -> f64 {
        self.inner.friction_stiffness
    }
    /// Friction hardening `H_f` (eq. 25).
    #[getter]
    fn friction_hardening(&self) -> f64 {
        self.inner.friction_hardening
    }
    /// Reference cohesion stiffness `K_c` (Pa, eq. 26).
    #[getter]
    fn cohesion_stiffness(&self) -> f64 {
        self.inner.cohesion_stiffness
    }
    /// Cohesion falloff `H_0` (eq. 27).
    #[getter]
    fn cohesion_falloff(&self) -> f64 {
        self.inner.cohesion_falloff
    }
    /// Debonding scale `b` (eq. 27).
    #[getter]
    fn debonding(&self) -> f64 {
        self.inner.debonding
    }
    /// Static friction `eta` (eq. 28), or None.
    #[getter]
    fn static_friction(&self) -> Option<f64> {
        self.inner.static_friction
    }
    /// Contact friction coefficient `mu_c` between touching grains (dimensionless).
    #[getter]
    fn contact_friction(&self) -> f64 {
        self.inner.contact_friction
    }
    /// Rolling resistance `mu_r` of the grains (dimensionless), or None: they do not turn.
    #[getter]
    fn rolling_resistance(&self) -> Option<f64> {
        self.inner.rolling_resistance
    }
    /// Capillary diffusivity `D` (m^2/s) of the water the grains hold.
    #[getter]
    fn wicking(&self) -> f64 {
        self.inner.wicking
    }
    /// `k_f + k_c` (Pa) at the density ratio `rho / rho_0` (eq. 25-27; finite, >= 0).
    fn stiffness(&self, density_ratio: Real) -> PyResult<f64> {
        let ratio = check_param(
            "density_ratio",
            density_ratio.get("density_ratio")?,
            |r| r >= 0.0,
            "a finite ratio >= 0",
        )
        .py()?;
        Ok(self.inner.stiffness(ratio))
    }
    pub(crate) fn __repr__(&self) -> String {
        let g = &self.inner;
        format!(
            "Granular(friction_angle={}, saturation={}, friction_stiffness={}, \
             friction_hardening={}, cohesion_stiffness={}, cohesion_falloff={}, debonding={}, \
             static_friction={}, contact_friction={}, rolling_resistance={}, wicking={})",
            g.friction_angle,
            g.saturation,
            g.friction_stiffness,
            g.friction_hardening,
            g.cohesion_stiffness,
            g.cohesion_falloff,
            g.debonding,
            g.static_friction
                .map_or("None".to_string(), |e| e.to_string()),
            g.contact_friction,
            g.rolling_resistance
                .map_or("None".to_string(), |r| r.to_string()),
            g.wicking
        )
    }
}
