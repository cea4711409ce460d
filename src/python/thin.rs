//! Python builders of shells and rods ([`Particles::shell`], [`Particles::rod`]), behind
//! `peridyn.Particles.shell` and `peridyn.Particles.rod`.

use pyo3::prelude::*;

use crate::particles::{ParticleParams, Particles};

use super::arrays::vec3s;
use super::errors::guard;
use super::particles::{mesh_of, seed_of};

/// A shell of `thickness` (m) on `mesh` (a trimesh.Trimesh or a (vertices, triangles) pair).
pub fn shell(
    py: Python<'_>,
    mesh: &Bound<'_, PyAny>,
    thickness: f64,
    seed: i128,
    params: ParticleParams,
) -> PyResult<Particles> {
    let (v, t) = mesh_of(mesh, "Particles.shell")?;
    let seed = seed_of(seed)?;
    py.detach(|| {
        guard("Particles.shell", || {
            Particles::shell(v, t, thickness, seed, params)
        })
    })
}

/// A rod of `radius` (m) along the polyline `points` ((P, 3) m).
pub fn rod(
    py: Python<'_>,
    points: &Bound<'_, PyAny>,
    radius: f64,
    params: ParticleParams,
) -> PyResult<Particles> {
    let x = vec3s(points, "points", None)?;
    py.detach(|| guard("Particles.rod", || Particles::rod(&x, radius, params)))
}
