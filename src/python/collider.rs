//! Python wrappers of the colliders.

use pyo3::prelude::*;

use crate::contact::Collider;

use super::arrays::{to_numpy_1d, vec3, vec3s};
use super::errors::IntoPyResult;

fn distances<'py>(c: &Collider, points: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    let p = vec3s(points, "points", None)?;
    Ok(to_numpy_1d(
        points.py(),
        p.iter().map(|x| c.signed_distance(x)).collect(),
    ))
}

/// Half-space collider: vertices stay on the side the normal points to.
#[pyclass(module = "peridyn._core", name = "Plane", frozen)]
#[derive(Clone)]
pub struct PyPlane {
    pub inner: Collider,
}

#[pymethods]
impl PyPlane {
    #[new]
    #[pyo3(signature = (*, point = None, normal = None))]
    fn new(point: Option<&Bound<'_, PyAny>>, normal: Option<&Bound<'_, PyAny>>) -> PyResult<Self> {
        let point = point
            .map(|p| vec3(p, "point"))
            .transpose()?
            .unwrap_or([0.0; 3]);
        let normal = normal
            .map(|n| vec3(n, "normal"))
            .transpose()?
            .unwrap_or([0.0, 0.0, 1.0]);
        Ok(Self {
            inner: Collider::plane(point, normal).py()?,
        })
    }
    #[getter]
    fn point(&self) -> Vec<f64> {
        match self.inner {
            Collider::Plane { point, .. } => point.as_slice().to_vec(),
            _ => unreachable!("PyPlane holds a plane"),
        }
    }
    /// Unit normal.
    #[getter]
    fn normal(&self) -> Vec<f64> {
        match self.inner {
            Collider::Plane { normal, .. } => normal.as_slice().to_vec(),
            _ => unreachable!("PyPlane holds a plane"),
        }
    }
    /// Signed distances (m, positive on the free side) of (n, 3) points.
    fn signed_distance<'py>(&self, points: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        distances(&self.inner, points)
    }
    fn __repr__(&self) -> String {
        format!(
            "Plane(point={:?}, normal={:?})",
            self.point(),
            self.normal()
        )
    }
}

/// Solid sphere collider.
#[pyclass(module = "peridyn._core", name = "Sphere", frozen)]
#[derive(Clone)]
pub struct PySphere {
    pub inner: Collider,
}

#[pymethods]
impl PySphere {
    #[new]
    #[pyo3(signature = (*, center, radius))]
    fn new(center: &Bound<'_, PyAny>, radius: f64) -> PyResult<Self> {
        Ok(Self {
            inner: Collider::sphere(vec3(center, "center")?, radius).py()?,
        })
    }
    #[getter]
    fn center(&self) -> Vec<f64> {
        match self.inner {
            Collider::Sphere { center, .. } => center.as_slice().to_vec(),
            _ => unreachable!("PySphere holds a sphere"),
        }
    }
    #[getter]
    fn radius(&self) -> f64 {
        match self.inner {
            Collider::Sphere { radius, .. } => radius,
            _ => unreachable!("PySphere holds a sphere"),
        }
    }
    /// Signed distances (m, positive outside) of (n, 3) points.
    fn signed_distance<'py>(&self, points: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        distances(&self.inner, points)
    }
    fn __repr__(&self) -> String {
        format!(
            "Sphere(center={:?}, radius={})",
            self.center(),
            self.radius()
        )
    }
}

/// Extracts a collider argument.
pub fn extract(obj: &Bound<'_, PyAny>) -> PyResult<Collider> {
    if let Ok(p) = obj.cast::<PyPlane>() {
        return Ok(p.get().inner);
    }
    if let Ok(s) = obj.cast::<PySphere>() {
        return Ok(s.get().inner);
    }
    Err(pyo3::exceptions::PyValueError::new_err(format!(
        "collider must be Plane or Sphere, got {}",
        obj.get_type().name()?
    )))
}
