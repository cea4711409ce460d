//! Particle sampling from meshes: `sample_volume` and `sample_surface`, taking a
//! trimesh.Trimesh (anything with `vertices` and `faces`) or a `(vertices, triangles)` pair.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use super::arrays::{to_numpy, triangles, vec3s};
use super::errors::guard;
use crate::particles;

/// Checks that an array-like holds real numbers (float or integer dtype) before numpy
/// converts it, so that booleans, complex numbers or strings are refused by name.
fn real_dtype(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<()> {
    let arr = obj.py().import("numpy")?.call_method1("asarray", (obj,))?;
    let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
    if matches!(kind.as_str(), "f" | "i" | "u") {
        Ok(())
    } else {
        Err(PyValueError::new_err(format!(
            "{name} must hold real numbers, got dtype {}",
            arr.getattr("dtype")?.str()?
        )))
    }
}

/// Vertices (m) and triangles of a mesh.
type Mesh = (Vec<[f64; 3]>, Vec<[i64; 3]>);

/// The mesh argument as vertices (m) and triangles, validated by shape and dtype.
pub(super) fn mesh_of(mesh: &Bound<'_, PyAny>, what: &str) -> PyResult<Mesh> {
    let (v, f) = if mesh.hasattr("vertices")? && mesh.hasattr("faces")? {
        (mesh.getattr("vertices")?, mesh.getattr("faces")?)
    } else {
        match mesh.extract::<(Bound<'_, PyAny>, Bound<'_, PyAny>)>() {
            Ok(pair) => pair,
            Err(_) => {
                return Err(PyValueError::new_err(format!(
                    "{what} takes a trimesh.Trimesh or a (vertices, triangles) pair, got {}",
                    mesh.get_type().name()?
                )))
            }
        }
    };
    real_dtype(&v, "vertices")?;
    let vertices = vec3s(&v, "vertices", None)?;
    if let Some(i) = vertices
        .iter()
        .position(|x| !x.iter().all(|c| c.is_finite()))
    {
        return Err(PyValueError::new_err(format!(
            "vertices: vertex {i} is not finite: {:?}",
            vertices[i].as_slice()
        )));
    }
    let t = triangles(&f, "triangles")?;
    Ok((vertices.iter().map(|x| (*x).into()).collect(), t))
}

pub(super) fn seed_of(seed: i128) -> PyResult<u64> {
    u64::try_from(seed).map_err(|_| {
        PyValueError::new_err(format!("seed must be an integer in [0, 2^64), got {seed}"))
    })
}

/// Particles filling a closed mesh on a cubic lattice of `spacing` (m), each standing for
/// `spacing^3` (m^3); `jitter` moves each by at most that fraction of the spacing (seeded).
#[pyfunction]
#[pyo3(signature = (mesh, spacing, *, jitter = 0.0, seed = 0))]
pub fn sample_volume<'py>(
    py: Python<'py>,
    mesh: &Bound<'py, PyAny>,
    spacing: f64,
    jitter: f64,
    seed: i128,
) -> PyResult<Bound<'py, PyAny>> {
    let (v, t) = mesh_of(mesh, "sample_volume")?;
    let seed = seed_of(seed)?;
    let x = py.detach(|| {
        guard("sample_volume", || {
            particles::sample_volume(v, t, spacing, jitter, seed)
        })
    })?;
    to_numpy(py, x.into_iter())
}

/// A single layer of particles on a surface (closed or open), at least `spacing` (m) apart.
#[pyfunction]
#[pyo3(signature = (mesh, spacing, *, seed = 0))]
pub fn sample_surface<'py>(
    py: Python<'py>,
    mesh: &Bound<'py, PyAny>,
    spacing: f64,
    seed: i128,
) -> PyResult<Bound<'py, PyAny>> {
    let (v, t) = mesh_of(mesh, "sample_surface")?;
    let seed = seed_of(seed)?;
    let x = py.detach(|| {
        guard("sample_surface", || {
            particles::sample_surface(v, t, spacing, seed)
        })
    })?;
    to_numpy(py, x.into_iter())
}
