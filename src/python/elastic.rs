//! Python wrapper of the particles' elastic material, [`Elastic`].

use pyo3::prelude::*;

use crate::particles::Elastic;

use super::errors::IntoPyResult;
use super::scalars::Real;

/// The elastic material of particle bodies (He et al. 2017, eq. 8).
#[pyclass(module = "peridyn._core", name = "Elastic", frozen)]
#[derive(Clone, Copy)]
pub struct PyElastic {
    pub inner: Elastic,
}

#[pymethods]
impl PyElastic {
    /// The paper's parameters (Pa): `mu` weighs the deviatoric term, `lam` the isotropic one.
    /// Not Lame parameters: the model's Poisson ratio is 1/4 whatever they are.
    #[new]
    #[pyo3(signature = (*, mu, lam))]
    fn new(mu: Real, lam: Real) -> PyResult<Self> {
        let inner = Elastic::Paper {
            mu: mu.get("mu")?,
            lam: lam.get("lam")?,
        };
        inner.validate().py()?;
        Ok(Self { inner })
    }

    /// A material whose bodies have the Young's modulus `E` (Pa) and Poisson ratio `nu` (in
    /// [0, 0.45]) along the axes of their sampling lattice, calibrated by lattice sums, with a
    /// dilatation term and the free surfaces corrected.
    #[staticmethod]
    #[allow(non_snake_case)]
    fn from_young(E: Real, nu: Real) -> PyResult<Self> {
        let inner = Elastic::Young {
            e: E.get("E")?,
            nu: nu.get("nu")?,
        };
        inner.validate().py()?;
        Ok(Self { inner })
    }

    /// The paper's `mu` (Pa), or None for a material given by `from_young` (its `mu` depends
    /// on the body's spacing and horizon: see `Particles.moduli`).
    #[getter]
    fn mu(&self) -> Option<f64> {
        match self.inner {
            Elastic::Paper { mu, .. } => Some(mu),
            Elastic::Young { .. } => None,
        }
    }
    /// The paper's `lam` (Pa), or None (see `mu`).
    #[getter]
    fn lam(&self) -> Option<f64> {
        match self.inner {
            Elastic::Paper { lam, .. } => Some(lam),
            Elastic::Young { .. } => None,
        }
    }
    /// The Young's modulus asked for (Pa), or None for the paper's parameters.
    #[getter]
    fn youngs_modulus(&self) -> Option<f64> {
        match self.inner {
            Elastic::Young { e, .. } => Some(e),
            Elastic::Paper { .. } => None,
        }
    }
    /// The Poisson ratio asked for, or None for the paper's parameters (whose ratio is 1/4).
    #[getter]
    fn poisson_ratio(&self) -> Option<f64> {
        match self.inner {
            Elastic::Young { nu, .. } => Some(nu),
            Elastic::Paper { .. } => None,
        }
    }
    pub(crate) fn __repr__(&self) -> String {
        match self.inner {
            Elastic::Paper { mu, lam } => format!("Elastic(mu={mu}, lam={lam})"),
            Elastic::Young { e, nu } => format!("Elastic.from_young({e}, {nu})"),
        }
    }
}
