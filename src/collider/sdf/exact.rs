//! The exact signed distance to a closed mesh, without a grid: the nearest triangle from the
//! tree ([`TriangleTree`]), signed by the pseudonormal of its closest feature
//! ([`ClosedSurface::is_inside`]). Slower per query than [`super::SdfGrid`]'s interpolation but
//! exact (to round-off) everywhere, including at sharp edges and thin features: the particle
//! sampler uses it to decide what is inside.

use nalgebra::Vector3;

use crate::error::Result;

use super::closed_surface::ClosedSurface;
use super::nearest::TriangleTree;

/// A closed mesh ready for exact signed distance queries (SI units).
#[derive(Debug, Clone)]
pub struct MeshDistance {
    surface: ClosedSurface,
    tree: TriangleTree,
    /// Enclosed volume (m^3, positive).
    volume: f64,
}

impl MeshDistance {
    /// The closed mesh `vertices` (m) / `triangles`, checked by [`ClosedSurface::new`] (closed,
    /// consistently oriented, no degenerate triangles, encloses a volume); errors name the
    /// offending vertex, edge or triangle.
    pub fn new(vertices: Vec<[f64; 3]>, triangles: Vec<[i64; 3]>) -> Result<Self> {
        let surface = ClosedSurface::new(vertices, triangles)?;
        let x = &surface.vertices;
        let volume = surface
            .triangles
            .iter()
            .map(|t| x[t[0] as usize].dot(&x[t[1] as usize].cross(&x[t[2] as usize])) / 6.0)
            .sum();
        let tree = TriangleTree::new(surface.corners());
        Ok(Self {
            surface,
            tree,
            volume,
        })
    }

    /// Enclosed volume (m^3).
    pub fn volume(&self) -> f64 {
        self.volume
    }

    /// Lowest and highest corner of the mesh's bounding box (m).
    pub fn bounds(&self) -> (Vector3<f64>, Vector3<f64>) {
        self.surface.vertices.iter().fold(
            (
                Vector3::repeat(f64::INFINITY),
                Vector3::repeat(f64::NEG_INFINITY),
            ),
            |(lo, hi), v| (lo.inf(v), hi.sup(v)),
        )
    }

    /// The signed distance from `x` to the surface (m, negative inside, zero on it) and the
    /// nearest triangle, searched from triangle `hint` (a nearby query's triangle makes the
    /// search faster; any triangle index is valid).
    pub fn signed_distance_from(&self, x: &Vector3<f64>, hint: usize) -> (f64, usize) {
        let nearest = self.tree.nearest_from(x, hint);
        let d = nearest.separation.norm();
        let signed = if self.surface.is_inside(&nearest) {
            -d
        } else {
            d
        };
        (signed, nearest.triangle)
    }
}
