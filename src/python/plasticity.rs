//! Python wrapper of the particles' plastic law, [`DruckerPrager`].

use pyo3::prelude::*;

use crate::particles::DruckerPrager;

use super::errors::IntoPyResult;
use super::scalars::{Flag, Real};

/// Drucker-Prager plasticity of particle bodies (He et al. 2017, section 5; the inner cone).
#[pyclass(module = "peridyn._core", name = "DruckerPrager", frozen)]
#[derive(Clone, Copy)]
pub struct PyDruckerPrager {
    pub inner: DruckerPrager,
}

#[pymethods]
impl PyDruckerPrager {
    /// `friction_angle` (degrees, in [0, 90)), `cohesion` (Pa, >= 0; > 0 when the angle is
    /// 0), `hardening` (Pa per unit of accumulated plastic strain, >= 0) and whether the
    /// neighbours are searched anew on the deformed positions after every step.
    #[new]
    #[pyo3(signature = (*, friction_angle, cohesion, hardening = Real::of(0.0), rebuild_neighbours = Flag::of(true)))]
    fn new(
        friction_angle: Real,
        cohesion: Real,
        hardening: Real,
        rebuild_neighbours: Flag,
    ) -> PyResult<Self> {
        let inner = DruckerPrager {
            friction_angle: friction_angle.get("friction_angle")?,
            cohesion: cohesion.get("cohesion")?,
            hardening: hardening.get("hardening")?,
            rebuild_neighbours: rebuild_neighbours.get("rebuild_neighbours")?,
        };
        inner.validate().py()?;
        Ok(Self { inner })
    }
    /// Internal friction angle (degrees).
    #[getter]
    fn friction_angle(&self) -> f64 {
        self.inner.friction_angle
    }
    /// Cohesion (Pa).
    #[getter]
    fn cohesion(&self) -> f64 {
        self.inner.cohesion
    }
    /// Hardening modulus (Pa).
    #[getter]
    fn hardening(&self) -> f64 {
        self.inner.hardening
    }
    #[getter]
    fn rebuild_neighbours(&self) -> bool {
        self.inner.rebuild_neighbours
    }
    pub(crate) fn __repr__(&self) -> String {
        let d = &self.inner;
        format!(
            "DruckerPrager(friction_angle={}, cohesion={}, hardening={}, rebuild_neighbours={})",
            d.friction_angle,
            d.cohesion,
            d.hardening,
            if d.rebuild_neighbours {
                "True"
            } else {
                "False"
            }
        )
    }
}
