//! Python wrappers of the materials.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::material::Material;

use super::errors::IntoPyResult;
use super::scalars::Real;

/// Evaluates `f` on every row of a (..., 3) array of principal stretches.
fn per_row<'py>(
    stretches: &Bound<'py, PyAny>,
    width: usize,
    f: impl Fn([f64; 3]) -> Vec<f64>,
) -> PyResult<Bound<'py, PyAny>> {
    let np = stretches.py().import("numpy")?;
    let arr = super::arrays::real_array(stretches, "stretches")?;
    let shape: Vec<usize> = arr.getattr("shape")?.extract()?;
    if shape.last() != Some(&3) {
        return Err(PyValueError::new_err(format!(
            "stretches must have shape (..., 3), got {shape:?}"
        )));
    }
    let flat: Vec<f64> = arr.call_method1("reshape", (-1,))?.extract()?;
    if let Some(k) = flat.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
        return Err(PyValueError::new_err(format!(
            "stretches must be finite and > 0, entry {k} is {}",
            flat[k]
        )));
    }
    let out: Vec<f64> = flat.chunks(3).flat_map(|c| f([c[0], c[1], c[2]])).collect();
    let mut out_shape = shape[..shape.len() - 1].to_vec();
    if width > 1 {
        out_shape.push(width);
    }
    np.call_method1("array", (out,))?
        .call_method1("reshape", (out_shape,))
}

/// One `#[pymethods]` block per material class: its own items plus the shared ones.
macro_rules! material_class {
    ($ty:ty, { $($own:tt)* }) => {
        #[pymethods]
        impl $ty {
            $($own)*

            /// Small-strain shear modulus (Pa).
            #[getter]
            fn shear_modulus(&self) -> f64 {
                self.inner.shear_modulus()
            }
            /// Small-strain in-plane Young's modulus (Pa) of the sheet (normal unstretched).
            #[getter]
            fn youngs_modulus(&self) -> f64 {
                let (mu, lam) = (self.inner.shear_modulus(), self.inner.lame_lambda());
                4.0 * mu * (mu + lam) / (2.0 * mu + lam)
            }
            /// Small-strain in-plane Poisson ratio of the sheet.
            #[getter]
            fn poisson_ratio(&self) -> f64 {
                let (mu, lam) = (self.inner.shear_modulus(), self.inner.lame_lambda());
                if mu + lam == 0.0 {
                    0.0
                } else {
                    lam / (2.0 * mu + lam)
                }
            }
            /// Principal stresses dPsi/dlambda (Pa) for principal stretches of shape (..., 3).
            fn stress<'py>(&self, stretches: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
                let m = self.inner.to_real::<f64>();
                per_row(stretches, 3, |l| m.stress(l).to_vec())
            }
            /// Energy density Psi (J/m^3) for principal stretches of shape (..., 3).
            fn energy_density<'py>(&self, stretches: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
                let m = self.inner.to_real::<f64>();
                per_row(stretches, 1, |l| vec![m.energy(l)])
            }
            fn __eq__(&self, other: &Self) -> bool {
                self.inner == other.inner
            }
        }
    };
}

/// Stretching model of Lu et al. 2023 (eq. 39-41): Psi = s0 sum_m A3(lambda_m).
#[pyclass(module = "peridyn._core", name = "StretchA3", frozen)]
#[derive(Clone)]
pub struct PyStretchA3 {
    pub inner: Material,
}

material_class!(PyStretchA3, {
    #[new]
    #[pyo3(signature = (*, s0))]
    fn new(s0: Real) -> PyResult<Self> {
        Ok(Self {
            inner: Material::stretch_a3(s0.get("s0")?).py()?,
        })
    }
    /// From the sheet's Young's modulus E (Pa): s0 = E / 2. A3 has no Poisson coupling, so nu must be 0.
    #[staticmethod]
    #[pyo3(signature = (E, nu = Real::of(0.0)))]
    #[allow(non_snake_case)]
    fn from_young(E: Real, nu: Real) -> PyResult<Self> {
        Ok(Self {
            inner: Material::stretch_a3_from_young(E.get("E")?, nu.get("nu")?).py()?,
        })
    }
    /// Stiffness (Pa).
    #[getter]
    fn s0(&self) -> f64 {
        match self.inner {
            Material::StretchA3 { s0 } => s0,
            Material::NeoHookean { s0, .. } => s0,
        }
    }
    fn __repr__(&self) -> String {
        format!("StretchA3(s0={})", self.s0())
    }
});

/// Compressible neo-Hookean model of Lu et al. 2023 (eq. 36-38).
#[pyclass(module = "peridyn._core", name = "NeoHookean", frozen)]
#[derive(Clone)]
pub struct PyNeoHookean {
    pub inner: Material,
}

material_class!(PyNeoHookean, {
    #[new]
    #[pyo3(signature = (*, s0, s1))]
    fn new(s0: Real, s1: Real) -> PyResult<Self> {
        Ok(Self {
            inner: Material::neo_hookean(s0.get("s0")?, s1.get("s1")?).py()?,
        })
    }
    /// From the sheet's in-plane (plane-stress) Young's modulus E (Pa) and Poisson ratio nu:
    /// s0 = E / (4 (1 + nu)), s1 = E nu / (2 (1 - nu^2)).
    #[staticmethod]
    #[allow(non_snake_case)]
    fn from_young(E: Real, nu: Real) -> PyResult<Self> {
        Ok(Self {
            inner: Material::neo_hookean_from_young(E.get("E")?, nu.get("nu")?).py()?,
        })
    }
    #[getter]
    fn s0(&self) -> f64 {
        match self.inner {
            Material::NeoHookean { s0, .. } | Material::StretchA3 { s0 } => s0,
        }
    }
    #[getter]
    fn s1(&self) -> f64 {
        match self.inner {
            Material::NeoHookean { s1, .. } => s1,
            Material::StretchA3 { .. } => 0.0,
        }
    }
    fn __repr__(&self) -> String {
        format!("NeoHookean(s0={}, s1={})", self.s0(), self.s1())
    }
});

/// Extracts a material argument.
pub fn extract(obj: &Bound<'_, PyAny>) -> PyResult<Material> {
    if let Ok(m) = obj.cast::<PyStretchA3>() {
        return Ok(m.get().inner);
    }
    if let Ok(m) = obj.cast::<PyNeoHookean>() {
        return Ok(m.get().inner);
    }
    Err(PyValueError::new_err(format!(
        "material must be StretchA3 or NeoHookean, got {}",
        obj.get_type().name()?
    )))
}

/// A material as its Python object.
pub fn to_py(py: Python<'_>, m: Material) -> PyResult<Py<PyAny>> {
    Ok(match m {
        Material::StretchA3 { .. } => Py::new(py, PyStretchA3 { inner: m })?.into_any(),
        Material::NeoHookean { .. } => Py::new(py, PyNeoHookean { inner: m })?.into_any(),
    })
}
