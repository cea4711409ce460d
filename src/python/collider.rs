//! Python wrappers of the colliders.

use pyo3::prelude::*;

use crate::contact::{Collider, Shape};

use super::arrays::{to_numpy_1d, vec3, vec3s};
use super::errors::IntoPyResult;

fn distances<'py>(
    c: &Collider,
    points: &Bound<'py, PyAny>,
    time: f64,
) -> PyResult<Bound<'py, PyAny>> {
    let p = vec3s(points, "points", None)?;
    Ok(to_numpy_1d(
        points.py(),
        p.iter().map(|x| c.signed_distance(x, time)).collect(),
    ))
}

/// A collider of `shape` with the keyword arguments every collider takes.
fn collider(
    shape: crate::error::Result<Shape>,
    friction: f64,
    velocity: Option<&Bound<'_, PyAny>>,
) -> PyResult<Collider> {
    let velocity = velocity
        .map(|v| vec3(v, "velocity"))
        .transpose()?
        .unwrap_or([0.0; 3]);
    Collider::new(shape.py()?, friction, velocity).py()
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
    #[pyo3(signature = (*, point = None, normal = None, friction = 0.0, velocity = None))]
    fn new(
        point: Option<&Bound<'_, PyAny>>,
        normal: Option<&Bound<'_, PyAny>>,
        friction: f64,
        velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let point = point
            .map(|p| vec3(p, "point"))
            .transpose()?
            .unwrap_or([0.0; 3]);
        let normal = normal
            .map(|n| vec3(n, "normal"))
            .transpose()?
            .unwrap_or([0.0, 0.0, 1.0]);
        Ok(Self {
            inner: collider(Shape::plane(point, normal), friction, velocity)?,
        })
    }
    #[getter]
    fn point(&self) -> Vec<f64> {
        match self.inner.shape {
            Shape::Plane { point, .. } => point.as_slice().to_vec(),
            _ => unreachable!("PyPlane holds a plane"),
        }
    }
    /// Unit normal.
    #[getter]
    fn normal(&self) -> Vec<f64> {
        match self.inner.shape {
            Shape::Plane { normal, .. } => normal.as_slice().to_vec(),
            _ => unreachable!("PyPlane holds a plane"),
        }
    }
    /// Signed distances (m, positive on the free side) of (n, 3) points at `time` (s).
    #[pyo3(signature = (points, time = 0.0))]
    fn signed_distance<'py>(
        &self,
        points: &Bound<'py, PyAny>,
        time: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        distances(&self.inner, points, time)
    }
    /// Coulomb friction coefficient.
    #[getter]
    fn friction(&self) -> f64 {
        self.inner.friction
    }
    /// Constant velocity (m/s) from the pose given at time 0.
    #[getter]
    fn velocity(&self) -> Vec<f64> {
        self.inner.velocity.as_slice().to_vec()
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
    #[pyo3(signature = (*, center, radius, friction = 0.0, velocity = None))]
    fn new(
        center: &Bound<'_, PyAny>,
        radius: f64,
        friction: f64,
        velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        Ok(Self {
            inner: collider(
                Shape::sphere(vec3(center, "center")?, radius),
                friction,
                velocity,
            )?,
        })
    }
    #[getter]
    fn center(&self) -> Vec<f64> {
        match self.inner.shape {
            Shape::Sphere { center, .. } => center.as_slice().to_vec(),
            _ => unreachable!("PySphere holds a sphere"),
        }
    }
    #[getter]
    fn radius(&self) -> f64 {
        match self.inner.shape {
            Shape::Sphere { radius, .. } => radius,
            _ => unreachable!("PySphere holds a sphere"),
        }
    }
    /// Signed distances (m, positive outside) of (n, 3) points at `time` (s).
    #[pyo3(signature = (points, time = 0.0))]
    fn signed_distance<'py>(
        &self,
        points: &Bound<'py, PyAny>,
        time: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        distances(&self.inner, points, time)
    }
    /// Coulomb friction coefficient.
    #[getter]
    fn friction(&self) -> f64 {
        self.inner.friction
    }
    /// Constant velocity (m/s) from the pose given at time 0.
    #[getter]
    fn velocity(&self) -> Vec<f64> {
        self.inner.velocity.as_slice().to_vec()
    }
    fn __repr__(&self) -> String {
        format!(
            "Sphere(center={:?}, radius={})",
            self.center(),
            self.radius()
        )
    }
}

/// Solid oriented box collider.
#[pyclass(module = "peridyn._core", name = "Box", frozen)]
#[derive(Clone)]
pub struct PyBox {
    pub inner: Collider,
}

#[pymethods]
impl PyBox {
    #[new]
    #[pyo3(signature = (*, center, half_extents, rotation = None, friction = 0.0, velocity = None))]
    fn new(
        center: &Bound<'_, PyAny>,
        half_extents: &Bound<'_, PyAny>,
        rotation: Option<&Bound<'_, PyAny>>,
        friction: f64,
        velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let rows = match rotation {
            None => [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            Some(r) => {
                let m = vec3s(r, "rotation", Some(3))?;
                [
                    [m[0].x, m[0].y, m[0].z],
                    [m[1].x, m[1].y, m[1].z],
                    [m[2].x, m[2].y, m[2].z],
                ]
            }
        };
        Ok(Self {
            inner: collider(
                Shape::cuboid(
                    vec3(center, "center")?,
                    vec3(half_extents, "half_extents")?,
                    rows,
                ),
                friction,
                velocity,
            )?,
        })
    }
    #[getter]
    fn center(&self) -> Vec<f64> {
        match self.inner.shape {
            Shape::Box { center, .. } => center.as_slice().to_vec(),
            _ => unreachable!("PyBox holds a box"),
        }
    }
    #[getter]
    fn half_extents(&self) -> Vec<f64> {
        match self.inner.shape {
            Shape::Box { half_extents, .. } => half_extents.as_slice().to_vec(),
            _ => unreachable!("PyBox holds a box"),
        }
    }
    /// Rotation matrix (rows), whose columns are the box's axes.
    #[getter]
    fn rotation(&self) -> Vec<Vec<f64>> {
        match self.inner.shape {
            Shape::Box { axes, .. } => (0..3)
                .map(|r| (0..3).map(|c| axes[(r, c)]).collect())
                .collect(),
            _ => unreachable!("PyBox holds a box"),
        }
    }
    /// Signed distances (m, positive outside) of (n, 3) points at `time` (s).
    #[pyo3(signature = (points, time = 0.0))]
    fn signed_distance<'py>(
        &self,
        points: &Bound<'py, PyAny>,
        time: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        distances(&self.inner, points, time)
    }
    /// Coulomb friction coefficient.
    #[getter]
    fn friction(&self) -> f64 {
        self.inner.friction
    }
    /// Constant velocity (m/s) from the pose given at time 0.
    #[getter]
    fn velocity(&self) -> Vec<f64> {
        self.inner.velocity.as_slice().to_vec()
    }
    fn __repr__(&self) -> String {
        format!(
            "Box(center={:?}, half_extents={:?})",
            self.center(),
            self.half_extents()
        )
    }
}

/// Solid capsule collider: the points within `radius` of the segment from `a` to `b`.
#[pyclass(module = "peridyn._core", name = "Capsule", frozen)]
#[derive(Clone)]
pub struct PyCapsule {
    pub inner: Collider,
}

#[pymethods]
impl PyCapsule {
    #[new]
    #[pyo3(signature = (*, a, b, radius, friction = 0.0, velocity = None))]
    fn new(
        a: &Bound<'_, PyAny>,
        b: &Bound<'_, PyAny>,
        radius: f64,
        friction: f64,
        velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        Ok(Self {
            inner: collider(
                Shape::capsule(vec3(a, "a")?, vec3(b, "b")?, radius),
                friction,
                velocity,
            )?,
        })
    }
    #[getter]
    fn a(&self) -> Vec<f64> {
        match self.inner.shape {
            Shape::Capsule { a, .. } => a.as_slice().to_vec(),
            _ => unreachable!("PyCapsule holds a capsule"),
        }
    }
    #[getter]
    fn b(&self) -> Vec<f64> {
        match self.inner.shape {
            Shape::Capsule { b, .. } => b.as_slice().to_vec(),
            _ => unreachable!("PyCapsule holds a capsule"),
        }
    }
    #[getter]
    fn radius(&self) -> f64 {
        match self.inner.shape {
            Shape::Capsule { radius, .. } => radius,
            _ => unreachable!("PyCapsule holds a capsule"),
        }
    }
    /// Signed distances (m, positive outside) of (n, 3) points at `time` (s).
    #[pyo3(signature = (points, time = 0.0))]
    fn signed_distance<'py>(
        &self,
        points: &Bound<'py, PyAny>,
        time: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        distances(&self.inner, points, time)
    }
    /// Coulomb friction coefficient.
    #[getter]
    fn friction(&self) -> f64 {
        self.inner.friction
    }
    /// Constant velocity (m/s) from the pose given at time 0.
    #[getter]
    fn velocity(&self) -> Vec<f64> {
        self.inner.velocity.as_slice().to_vec()
    }
    fn __repr__(&self) -> String {
        format!(
            "Capsule(a={:?}, b={:?}, radius={})",
            self.a(),
            self.b(),
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
    if let Ok(b) = obj.cast::<PyBox>() {
        return Ok(b.get().inner);
    }
    if let Ok(c) = obj.cast::<PyCapsule>() {
        return Ok(c.get().inner);
    }
    Err(pyo3::exceptions::PyValueError::new_err(format!(
        "collider must be Plane, Sphere, Box or Capsule, got {}",
        obj.get_type().name()?
    )))
}
