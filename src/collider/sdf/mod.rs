//! A closed triangle mesh as a signed distance field on a regular grid (the `MeshCollider`).
//!
//! Build: at every grid node `x_ijk = origin + h (i, j, k)` the exact distance to the nearest
//! triangle ([`nearest::TriangleTree`], nodes in parallel), signed by the angle-weighted
//! pseudonormal of the closest feature ([`closed_surface::ClosedSurface`]); negative inside.
//! The grid covers the mesh's bounding box padded by `margin` on every side.
//!
//! Query: inside the grid, the trilinear interpolant `phi(x)` of the node values, and as the
//! normal the normalised gradient of that same interpolant (exact for the field queried, so a
//! move along it changes `phi` to first order by its length; it jumps across cell faces, as
//! the trilinear field's gradient does). Outside the grid the field continues as
//! `phi(x) = |x - p| + phi(p)` with `p` the closest point of the grid box, which keeps
//! `phi` continuous and an upper bound on the exact distance (triangle inequality).
//!
//! Accuracy: where the exact distance is smooth the error is `O(h^2)` (about `h^2 / (8 r)`
//! near a surface of curvature radius `r`); at the medial axis and around sharp edges it is
//! `O(h)`, below `sqrt(3) h` in any case since the field is 1-Lipschitz. The tests report the
//! measured error against the exact distance.

mod closed_surface;
mod exact;
mod nearest;

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::error::{invalid, Result};

use closed_surface::ClosedSurface;
pub use exact::MeshDistance;
use nearest::TriangleTree;

/// Most grid nodes a field may have (8 bytes each).
const MAX_NODES: usize = 1 << 27;

/// Signed distance field of a closed mesh, sampled on a regular grid (SI units).
pub struct SdfGrid {
    surface: ClosedSurface,
    /// Position of node (0, 0, 0) (m).
    origin: Vector3<f64>,
    /// Node spacing h (m).
    cell: f64,
    /// Nodes along x, y, z.
    dims: [usize; 3],
    /// Signed distance (m, negative inside) of node (i, j, k) at `i + nx (j + ny k)`.
    values: Vec<f64>,
}

impl std::fmt::Debug for SdfGrid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "SdfGrid {{ triangles: {}, dims: {:?}, cell: {} m }}",
            self.surface.triangles.len(),
            self.dims,
            self.cell
        )
    }
}

impl PartialEq for SdfGrid {
    fn eq(&self, other: &Self) -> bool {
        self.origin == other.origin
            && self.cell == other.cell
            && self.dims == other.dims
            && self.values == other.values
    }
}

impl SdfGrid {
    /// The field of the closed mesh `vertices` (m) / `triangles` (vertex indices), with
    /// `resolution` cells along the longest side of the mesh's bounding box (cell size
    /// `h = longest side / resolution`, m) and the box padded by `margin` (m; default
    /// `max(0.1 longest side, 2 h)`). The mesh is checked by [`ClosedSurface::new`];
    /// `resolution` must be at least 2 and the grid at most [`MAX_NODES`] nodes.
    pub fn build(
        vertices: Vec<[f64; 3]>,
        triangles: Vec<[i64; 3]>,
        resolution: usize,
        margin: Option<f64>,
    ) -> Result<Self> {
        if resolution < 2 {
            return Err(invalid!(
                "resolution (cells along the mesh's longest side) must be >= 2, got {resolution}"
            ));
        }
        if let Some(m) = margin {
            if !(m.is_finite() && m >= 0.0) {
                return Err(invalid!("margin must be a finite length >= 0 m, got {m}"));
            }
        }
        let surface = ClosedSurface::new(vertices, triangles)?;
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for v in &surface.vertices {
            lo = lo.inf(v);
            hi = hi.sup(v);
        }
        let longest = (hi - lo).max();
        let cell = longest / resolution as f64;
        let margin = margin.unwrap_or((0.1 * longest).max(2.0 * cell));
        let origin = lo - Vector3::repeat(margin);
        let span = hi - lo + Vector3::repeat(2.0 * margin);
        let dims = [0, 1, 2].map(|k| (span[k] / cell).ceil() as usize + 1);
        let nodes = dims[0].saturating_mul(dims[1]).saturating_mul(dims[2]);
        if nodes > MAX_NODES {
            return Err(invalid!(
                "the grid would have {nodes} nodes ({dims:?}), more than {MAX_NODES}: lower the resolution ({resolution}) or the margin ({margin} m)"
            ));
        }
        let tree = TriangleTree::new(surface.corners());
        let [nx, ny, _] = dims;
        let mut values = vec![0.0; nodes];
        // Rows along x in parallel; each node's search starts from the previous node's nearest
        // triangle, whose distance bounds it tightly.
        values
            .par_chunks_mut(nx)
            .enumerate()
            .for_each(|(row, out)| {
                let (j, k) = (row % ny, row / ny);
                let mut hint = 0;
                for (i, value) in out.iter_mut().enumerate() {
                    let x = origin + Vector3::new(i as f64, j as f64, k as f64) * cell;
                    let nearest = tree.nearest_from(&x, hint);
                    let d = nearest.separation.norm();
                    *value = if surface.is_inside(&nearest) { -d } else { d };
                    hint = nearest.triangle;
                }
            });
        Ok(Self {
            surface,
            origin,
            cell,
            dims,
            values,
        })
    }

    /// Node spacing h (m).
    pub fn cell_size(&self) -> f64 {
        self.cell
    }

    /// Nodes along x, y and z.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Lowest and highest corner of the grid box (m).
    pub fn bounds(&self) -> (Vector3<f64>, Vector3<f64>) {
        let far = Vector3::from(self.dims.map(|n| (n - 1) as f64)) * self.cell;
        (self.origin, self.origin + far)
    }

    /// The mesh (outward-oriented): vertices (m) and triangles.
    pub fn mesh(&self) -> (&[Vector3<f64>], &[[u32; 3]]) {
        (&self.surface.vertices, &self.surface.triangles)
    }

    /// The field `phi(x)` (m, negative inside) and its gradient (see the module docs).
    pub fn value_and_gradient(&self, x: &Vector3<f64>) -> (f64, Vector3<f64>) {
        let (lo, hi) = self.bounds();
        let p = x.sup(&lo).inf(&hi);
        let (value, mut gradient) = self.trilinear(&p);
        let off = x - p;
        let reach = off.norm();
        if reach == 0.0 {
            return (value, gradient);
        }
        for k in 0..3 {
            if off[k] != 0.0 {
                gradient[k] = 0.0;
            }
        }
        (reach + value, gradient + off / reach)
    }

    /// `phi(x)` (m, negative inside).
    pub fn signed_distance(&self, x: &Vector3<f64>) -> f64 {
        self.value_and_gradient(x).0
    }

    /// The unit normal `grad phi / |grad phi|` (+z where the gradient vanishes).
    pub fn normal(&self, x: &Vector3<f64>) -> Vector3<f64> {
        let g = self.value_and_gradient(x).1;
        let n = g.norm();
        if n > 0.0 {
            g / n
        } else {
            Vector3::z()
        }
    }

    /// `x` itself where `phi(x) >= margin`, else `x` moved along the gradient by Newton steps
    /// `x <- x - (phi(x) - margin') grad phi / |grad phi|^2` until `phi` is within
    /// `PROJECTION_TOLERANCE h` above `margin` (the trilinear field is nearly linear over a
    /// cell, so two or three steps suffice; after [`PROJECTION_STEPS`] the closest point found
    /// outside the margin is kept).
    pub fn project(&self, x: Vector3<f64>, margin: f64) -> Vector3<f64> {
        let (mut value, mut gradient) = self.value_and_gradient(&x);
        if value >= margin {
            return x;
        }
        let tolerance = PROJECTION_TOLERANCE * self.cell;
        // Aim at the middle of the band so that round-off does not leave the point inside.
        let target = margin + 0.5 * tolerance;
        let (mut y, mut best) = (x, None::<(f64, Vector3<f64>)>);
        for _ in 0..PROJECTION_STEPS {
            let g2 = gradient.norm_squared();
            if g2 == 0.0 {
                break;
            }
            y -= gradient * ((value - target) / g2);
            (value, gradient) = self.value_and_gradient(&y);
            let gap = value - margin;
            if gap >= 0.0 {
                if best.is_none_or(|(b, _)| gap < b) {
                    best = Some((gap, y));
                }
                if gap <= tolerance {
                    break;
                }
            }
        }
        best.map_or(y, |(_, p)| p)
    }

    /// Trilinear value and gradient at a point `p` of the grid box.
    fn trilinear(&self, p: &Vector3<f64>) -> (f64, Vector3<f64>) {
        let u = (p - self.origin) / self.cell;
        let mut base = [0usize; 3];
        let mut t = Vector3::zeros();
        for k in 0..3 {
            let i = (u[k].floor().max(0.0) as usize).min(self.dims[k] - 2);
            base[k] = i;
            t[k] = (u[k] - i as f64).clamp(0.0, 1.0);
        }
        let [nx, ny, _] = self.dims;
        let at = |i: usize, j: usize, k: usize| {
            self.values[(base[0] + i) + nx * ((base[1] + j) + ny * (base[2] + k))]
        };
        let c = [
            [[at(0, 0, 0), at(0, 0, 1)], [at(0, 1, 0), at(0, 1, 1)]],
            [[at(1, 0, 0), at(1, 0, 1)], [at(1, 1, 0), at(1, 1, 1)]],
        ];
        let (tx, ty, tz) = (t.x, t.y, t.z);
        // Interpolate along z, then y, then x; the gradient follows by the product rule.
        let lerp = |a: f64, b: f64, s: f64| a + (b - a) * s;
        let cz = |i: usize, j: usize| lerp(c[i][j][0], c[i][j][1], tz);
        let dz = |i: usize, j: usize| c[i][j][1] - c[i][j][0];
        let (z00, z01, z10, z11) = (cz(0, 0), cz(0, 1), cz(1, 0), cz(1, 1));
        let (y0, y1) = (lerp(z00, z01, ty), lerp(z10, z11, ty));
        let value = lerp(y0, y1, tx);
        let gx = y1 - y0;
        let gy = lerp(z01 - z00, z11 - z10, tx);
        let gz = lerp(
            lerp(dz(0, 0), dz(0, 1), ty),
            lerp(dz(1, 0), dz(1, 1), ty),
            tx,
        );
        (value, Vector3::new(gx, gy, gz) / self.cell)
    }
}

/// Newton steps of [`SdfGrid::project`].
const PROJECTION_STEPS: usize = 8;

/// How far above the margin (in cells) [`SdfGrid::project`] may land.
const PROJECTION_TOLERANCE: f64 = 1e-9;

#[cfg(test)]
pub(crate) mod tests;
