//! Python wrappers of the colliders: a base class `Collider` holds the core collider (shape,
//! friction, motion) and what every shape shares; `Plane`, `Sphere`, `Box`, `Capsule` and
//! `MeshCollider` construct it and expose their own geometry.

use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::collider::{Collider, Shape};

use super::arrays::{rotation_rows, to_numpy, to_numpy_1d, triangles, vec3, vec3s};
use super::errors::{guard, IntoPyResult};
use super::scalars::{Int, Real};

/// Base of every collider: a solid shape, a Coulomb `friction` coefficient (>= 0) and a
/// constant `velocity` (m/s) from the pose given at time 0.
#[pyclass(module = "peridyn._core", name = "Collider", subclass, frozen)]
pub struct PyCollider {
    pub inner: Collider,
}

impl PyCollider {
    /// The base part of a collider of `shape` with the keyword arguments every collider takes.
    fn new(
        shape: crate::error::Result<Shape>,
        friction: Real,
        velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let velocity = velocity
            .map(|v| vec3(v, "velocity"))
            .transpose()?
            .unwrap_or([0.0; 3]);
        let friction = friction.get("friction")?;
        Ok(Self {
            inner: Collider::new(shape.py()?, friction, velocity).py()?,
        })
    }
}

#[pymethods]
impl PyCollider {
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
    /// Signed distances (m, positive outside) of (n, 3) points at `time` (s).
    #[pyo3(signature = (points, time = Real::of(0.0)))]
    fn signed_distance<'py>(
        &self,
        points: &Bound<'py, PyAny>,
        time: Real,
    ) -> PyResult<Bound<'py, PyAny>> {
        let time = time.get("time")?;
        if !time.is_finite() {
            return Err(PyValueError::new_err(format!(
                "time must be finite (s), got {time}"
            )));
        }
        let p = vec3s(points, "points", None)?;
        Ok(to_numpy_1d(
            points.py(),
            p.iter()
                .map(|x| self.inner.signed_distance(x, time))
                .collect(),
        ))
    }
}

/// The shape of a collider subclass.
fn shape<T: pyo3::PyClass<BaseType = PyCollider>>(slf: &PyRef<'_, T>) -> Shape {
    slf.as_super().inner.shape.clone()
}

/// Half-space collider: vertices stay on the side the normal points to.
#[pyclass(module = "peridyn._core", name = "Plane", extends = PyCollider, frozen)]
pub struct PyPlane;

#[pymethods]
impl PyPlane {
    #[new]
    #[pyo3(signature = (*, point = None, normal = None, friction = Real::of(0.0), velocity = None))]
    fn new(
        point: Option<&Bound<'_, PyAny>>,
        normal: Option<&Bound<'_, PyAny>>,
        friction: Real,
        velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let point = point
            .map(|p| vec3(p, "point"))
            .transpose()?
            .unwrap_or([0.0; 3]);
        let normal = normal
            .map(|n| vec3(n, "normal"))
            .transpose()?
            .unwrap_or([0.0, 0.0, 1.0]);
        Ok(PyClassInitializer::from(PyCollider::new(
            Shape::plane(point, normal),
            friction,
            velocity,
        )?)
        .add_subclass(Self))
    }
    #[getter]
    fn point(slf: PyRef<'_, Self>) -> Vec<f64> {
        match shape(&slf) {
            Shape::Plane { point, .. } => point.as_slice().to_vec(),
            _ => unreachable!("a Plane holds a plane"),
        }
    }
    /// Unit normal.
    #[getter]
    fn normal(slf: PyRef<'_, Self>) -> Vec<f64> {
        match shape(&slf) {
            Shape::Plane { normal, .. } => normal.as_slice().to_vec(),
            _ => unreachable!("a Plane holds a plane"),
        }
    }
    fn __repr__(slf: PyRef<'_, Self>) -> String {
        match shape(&slf) {
            Shape::Plane { point, normal } => {
                format!(
                    "Plane(point={:?}, normal={:?})",
                    point.as_slice(),
                    normal.as_slice()
                )
            }
            _ => unreachable!("a Plane holds a plane"),
        }
    }
}

/// Solid sphere collider.
#[pyclass(module = "peridyn._core", name = "Sphere", extends = PyCollider, frozen)]
pub struct PySphere;

#[pymethods]
impl PySphere {
    #[new]
    #[pyo3(signature = (*, center, radius, friction = Real::of(0.0), velocity = None))]
    fn new(
        center: &Bound<'_, PyAny>,
        radius: Real,
        friction: Real,
        velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyClassInitializer<Self>> {
        Ok(PyClassInitializer::from(PyCollider::new(
            Shape::sphere(vec3(center, "center")?, radius.get("radius")?),
            friction,
            velocity,
        )?)
        .add_subclass(Self))
    }
    #[getter]
    fn center(slf: PyRef<'_, Self>) -> Vec<f64> {
        match shape(&slf) {
            Shape::Sphere { center, .. } => center.as_slice().to_vec(),
            _ => unreachable!("a Sphere holds a sphere"),
        }
    }
    #[getter]
    fn radius(slf: PyRef<'_, Self>) -> f64 {
        match shape(&slf) {
            Shape::Sphere { radius, .. } => radius,
            _ => unreachable!("a Sphere holds a sphere"),
        }
    }
    fn __repr__(slf: PyRef<'_, Self>) -> String {
        match shape(&slf) {
            Shape::Sphere { center, radius } => {
                format!("Sphere(center={:?}, radius={radius})", center.as_slice())
            }
            _ => unreachable!("a Sphere holds a sphere"),
        }
    }
}

/// Solid oriented box collider.
#[pyclass(module = "peridyn._core", name = "Box", extends = PyCollider, frozen)]
pub struct PyBox;

#[pymethods]
impl PyBox {
    #[new]
    #[pyo3(signature = (*, center, half_extents, rotation = None, friction = Real::of(0.0), velocity = None))]
    fn new(
        center: &Bound<'_, PyAny>,
        half_extents: &Bound<'_, PyAny>,
        rotation: Option<&Bound<'_, PyAny>>,
        friction: Real,
        velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let rows = match rotation {
            None => [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            Some(r) => rotation_rows(r, "rotation")?,
        };
        let cuboid = Shape::cuboid(
            vec3(center, "center")?,
            vec3(half_extents, "half_extents")?,
            rows,
        );
        Ok(
            PyClassInitializer::from(PyCollider::new(cuboid, friction, velocity)?)
                .add_subclass(Self),
        )
    }
    #[getter]
    fn center(slf: PyRef<'_, Self>) -> Vec<f64> {
        match shape(&slf) {
            Shape::Box { center, .. } => center.as_slice().to_vec(),
            _ => unreachable!("a Box holds a box"),
        }
    }
    #[getter]
    fn half_extents(slf: PyRef<'_, Self>) -> Vec<f64> {
        match shape(&slf) {
            Shape::Box { half_extents, .. } => half_extents.as_slice().to_vec(),
            _ => unreachable!("a Box holds a box"),
        }
    }
    /// Rotation matrix (rows), whose columns are the box's axes.
    #[getter]
    fn rotation(slf: PyRef<'_, Self>) -> Vec<Vec<f64>> {
        match shape(&slf) {
            Shape::Box { axes, .. } => (0..3)
                .map(|r| (0..3).map(|c| axes[(r, c)]).collect())
                .collect(),
            _ => unreachable!("a Box holds a box"),
        }
    }
    fn __repr__(slf: PyRef<'_, Self>) -> String {
        match shape(&slf) {
            Shape::Box {
                center,
                half_extents,
                ..
            } => {
                format!(
                    "Box(center={:?}, half_extents={:?})",
                    center.as_slice(),
                    half_extents.as_slice()
                )
            }
            _ => unreachable!("a Box holds a box"),
        }
    }
}

/// Solid capsule collider: the points within `radius` of the segment from `a` to `b`.
#[pyclass(module = "peridyn._core", name = "Capsule", extends = PyCollider, frozen)]
pub struct PyCapsule;

#[pymethods]
impl PyCapsule {
    #[new]
    #[pyo3(signature = (*, a, b, radius, friction = Real::of(0.0), velocity = None))]
    fn new(
        a: &Bound<'_, PyAny>,
        b: &Bound<'_, PyAny>,
        radius: Real,
        friction: Real,
        velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let capsule = Shape::capsule(vec3(a, "a")?, vec3(b, "b")?, radius.get("radius")?);
        Ok(
            PyClassInitializer::from(PyCollider::new(capsule, friction, velocity)?)
                .add_subclass(Self),
        )
    }
    #[getter]
    fn a(slf: PyRef<'_, Self>) -> Vec<f64> {
        match shape(&slf) {
            Shape::Capsule { a, .. } => a.as_slice().to_vec(),
            _ => unreachable!("a Capsule holds a capsule"),
        }
    }
    #[getter]
    fn b(slf: PyRef<'_, Self>) -> Vec<f64> {
        match shape(&slf) {
            Shape::Capsule { b, .. } => b.as_slice().to_vec(),
            _ => unreachable!("a Capsule holds a capsule"),
        }
    }
    #[getter]
    fn radius(slf: PyRef<'_, Self>) -> f64 {
        match shape(&slf) {
            Shape::Capsule { radius, .. } => radius,
            _ => unreachable!("a Capsule holds a capsule"),
        }
    }
    fn __repr__(slf: PyRef<'_, Self>) -> String {
        match shape(&slf) {
            Shape::Capsule { a, b, radius } => {
                format!(
                    "Capsule(a={:?}, b={:?}, radius={radius})",
                    a.as_slice(),
                    b.as_slice()
                )
            }
            _ => unreachable!("a Capsule holds a capsule"),
        }
    }
}

/// Solid bounded by a closed triangle mesh, sampled as a signed distance field on a grid.
#[pyclass(module = "peridyn._core", name = "MeshCollider", extends = PyCollider, frozen)]
pub struct PyMeshCollider;

#[pymethods]
impl PyMeshCollider {
    /// `vertices` (n, 3) in m and `triangles` (m, 3), or a trimesh.Trimesh (anything with
    /// `vertices` and `faces`) alone; `resolution` cells along the mesh's longest side;
    /// `margin` (m) padding of the grid around the mesh.
    #[new]
    #[pyo3(signature = (vertices, triangles = None, *, resolution = Int::of(64), margin = None,
                        friction = Real::of(0.0), velocity = None))]
    fn new(
        py: Python<'_>,
        vertices: &Bound<'_, PyAny>,
        triangles: Option<&Bound<'_, PyAny>>,
        resolution: Int,
        margin: Option<Real>,
        friction: Real,
        velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let (vertices, faces) = match triangles {
            Some(t) => (vertices.clone(), t.clone()),
            None if vertices.hasattr("faces")? => {
                (vertices.getattr("vertices")?, vertices.getattr("faces")?)
            }
            None => {
                return Err(PyValueError::new_err(
                    "MeshCollider takes vertices and triangles, or a trimesh.Trimesh alone",
                ))
            }
        };
        let v: Vec<[f64; 3]> = vec3s(&vertices, "vertices", None)?
            .iter()
            .map(|x| (*x).into())
            .collect();
        let t = self::triangles(&faces, "triangles")?;
        let margin = margin.map(|m| m.get("margin")).transpose()?;
        let resolution = resolution.get("resolution")?;
        let resolution = usize::try_from(resolution).map_err(|_| {
            PyValueError::new_err(format!(
                "resolution (cells along the mesh's longest side) must be >= 2, got {resolution}"
            ))
        })?;
        check_grid_size(&v, resolution, margin)?;
        let mesh =
            py.detach(|| guard("MeshCollider", || Ok(Shape::mesh(v, t, resolution, margin))))?;
        Ok(PyClassInitializer::from(PyCollider::new(mesh, friction, velocity)?).add_subclass(Self))
    }
    /// Grid node spacing (m).
    #[getter]
    fn cell_size(slf: PyRef<'_, Self>) -> f64 {
        grid_of(&slf, |g| g.cell_size())
    }
    /// Grid nodes along x, y and z.
    #[getter]
    fn grid_shape(slf: PyRef<'_, Self>) -> (usize, usize, usize) {
        grid_of(&slf, |g| {
            let [x, y, z] = g.dims();
            (x, y, z)
        })
    }
    /// Lowest and highest corner of the grid box (m).
    #[getter]
    fn bounds(slf: PyRef<'_, Self>) -> (Vec<f64>, Vec<f64>) {
        grid_of(&slf, |g| {
            let (lo, hi) = g.bounds();
            (lo.as_slice().to_vec(), hi.as_slice().to_vec())
        })
    }
    /// (n, 3) vertices (m).
    #[getter]
    fn vertices<'py>(slf: PyRef<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        let py = slf.py();
        grid_of(&slf, |g| to_numpy(py, g.mesh().0.iter().copied()))
    }
    /// (m, 3) triangles, oriented outward (counter-clockwise seen from outside).
    #[getter]
    fn triangles<'py>(slf: PyRef<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        let py = slf.py();
        grid_of(&slf, |g| {
            let flat: Vec<i64> = g.mesh().1.iter().flatten().map(|&i| i as i64).collect();
            let n = flat.len() / 3;
            Ok(PyArray1::from_vec(py, flat).reshape([n, 3])?.into_any())
        })
    }
    fn __repr__(slf: PyRef<'_, Self>) -> String {
        grid_of(&slf, |g| {
            format!(
                "MeshCollider(triangles={}, grid_shape={:?}, cell_size={})",
                g.mesh().1.len(),
                g.dims(),
                g.cell_size()
            )
        })
    }
}

/// The most nodes a MeshCollider's grid may have (the core's limit, 8 bytes each).
const MAX_GRID_NODES: f64 = (1u64 << 27) as f64;

/// Refuses a grid whose node count (counted in f64, so that no size overflows) is beyond
/// [`MAX_GRID_NODES`], naming the resolution and the margin, before the core sizes it. Inputs
/// the core refuses with its own message (non-finite vertices, a resolution below 2, a bad
/// margin, a mesh of no extent) pass through to it.
fn check_grid_size(v: &[[f64; 3]], resolution: usize, margin: Option<f64>) -> PyResult<()> {
    if resolution < 2
        || v.is_empty()
        || !v.iter().flatten().all(|c| c.is_finite())
        || margin.is_some_and(|m| !(m.is_finite() && m >= 0.0))
    {
        return Ok(());
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in v {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let longest = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
    if !(longest > 0.0 && longest.is_finite()) {
        return Ok(());
    }
    let cell = longest / resolution as f64;
    let margin = margin.unwrap_or((0.1 * longest).max(2.0 * cell));
    let dims = [0, 1, 2].map(|k| ((hi[k] - lo[k] + 2.0 * margin) / cell).ceil() + 1.0);
    let nodes = dims[0] * dims[1] * dims[2];
    if nodes.is_finite() && nodes <= MAX_GRID_NODES {
        return Ok(());
    }
    Err(PyValueError::new_err(format!(
        "MeshCollider: the grid would have {nodes:.3e} nodes ({:.3e} x {:.3e} x {:.3e} of \
         {cell:e} m), more than {MAX_GRID_NODES}: lower the resolution ({resolution}) or the \
         margin ({margin:e} m)",
        dims[0], dims[1], dims[2]
    )))
}

/// `f` of a MeshCollider's grid.
fn grid_of<R>(
    slf: &PyRef<'_, PyMeshCollider>,
    f: impl FnOnce(&crate::collider::SdfGrid) -> R,
) -> R {
    match &slf.as_super().inner.shape {
        Shape::Mesh(grid) => f(grid),
        _ => unreachable!("a MeshCollider holds a mesh"),
    }
}

/// Extracts a collider argument (any subclass of `Collider`).
pub fn extract(obj: &Bound<'_, PyAny>) -> PyResult<Collider> {
    match obj.cast::<PyCollider>() {
        Ok(c) => Ok(c.get().inner.clone()),
        Err(_) => Err(PyValueError::new_err(format!(
            "collider must be Plane, Sphere, Box, Capsule or MeshCollider, got {}",
            obj.get_type().name()?
        ))),
    }
}
