//! A solid's volume as particles on a cubic lattice.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::collider::MeshDistance;
use crate::error::{check_param, invalid, Result};

use super::random::in_unit_ball;
use super::{check_spacing, MAX_PARTICLES};

/// Most lattice sites examined (inside the mesh or not): a thin shape in a large box costs
/// time in proportion to its box, so that is capped too.
const MAX_SITES: f64 = (1u64 << 33) as f64;

/// The cubic lattice of spacing `s` centred in a box: `n_k = max(ceil(extent_k / s), 1)` sites
/// along axis `k` at `centre_k + (i - (n_k - 1) / 2) s`. A box whose sides are whole multiples
/// of `s` is tiled exactly by the sites' cells (each site at the centre of its cube of side `s`).
#[derive(Debug, Clone, Copy)]
pub(super) struct Lattice {
    pub first: Vector3<f64>,
    pub spacing: f64,
    pub dims: [usize; 3],
}

impl Lattice {
    /// The lattice over the box `lo..hi` (m), or an error naming the site count above `cap`.
    pub fn over(lo: Vector3<f64>, hi: Vector3<f64>, spacing: f64, cap: f64) -> Result<Self> {
        let counts = [0, 1, 2].map(|k| ((hi[k] - lo[k]) / spacing).ceil().max(1.0));
        let sites = counts[0] * counts[1] * counts[2];
        if sites > cap {
            return Err(invalid!(
                "the sampling lattice would have {sites:.3e} sites ({:?} along x, y, z), more than {cap:.3e}: use a larger spacing ({spacing} m)",
                counts
            ));
        }
        let dims = counts.map(|c| c as usize);
        let first = Vector3::from(
            [0, 1, 2].map(|k| 0.5 * (lo[k] + hi[k]) - 0.5 * (dims[k] - 1) as f64 * spacing),
        );
        Ok(Self {
            first,
            spacing,
            dims,
        })
    }

    /// Site `(i, j, k)` (m).
    #[inline]
    pub fn site(&self, i: usize, j: usize, k: usize) -> Vector3<f64> {
        self.first + Vector3::new(i as f64, j as f64, k as f64) * self.spacing
    }
}

/// Particles filling the solid bounded by the closed mesh `vertices` (m) / `triangles`: the
/// sites of a cubic lattice of `spacing` (m, centred in the mesh's bounding box, see
/// [`Lattice`]), each moved by a random offset uniform in the ball of radius
/// `jitter * spacing` (`jitter` in `[0, 0.5)`, a fraction of the spacing; the offset of site
/// `(i, j, k)` is a hash of `seed` and the site), kept when the moved point is strictly inside
/// (exact signed distance [`MeshDistance`] below 0). Each particle stands for `spacing^3` (m^3)
/// of material.
///
/// Guarantees: every particle is strictly inside; particles are at least
/// `(1 - 2 jitter) spacing` apart (exactly `spacing` without jitter); the count times
/// `spacing^3` approximates the enclosed volume to within the material of a surface layer about
/// half a spacing thick (`|N spacing^3 - V| <~ A spacing / 2`, `A` the surface area); the
/// order is the lattice's (x fastest, then y, then z). The result is the same for any
/// number of threads.
///
/// The inside test is exact rather than [`crate::collider::SdfGrid`]'s interpolated field:
/// that field's error near sharp edges is `O(h)` in its own cell size, so sites near a cube's
/// edges would be misclassified unless its grid were much finer than the lattice. Cost: one
/// nearest-triangle query (`O(log m)` for `m` triangles) per site near the surface; a query's
/// distance certifies every site of its row within that distance, so deep interior and far
/// exterior sites are nearly free.
///
/// Errors (naming the culprit): `spacing` not finite and positive; `jitter` outside `[0, 0.5)`;
/// a mesh that is not closed and consistently oriented, has degenerate triangles or encloses no
/// volume; more than [`MAX_PARTICLES`] particles expected (`V / spacing^3`) or more than `2^33`
/// lattice sites.
pub fn sample_volume(
    vertices: Vec<[f64; 3]>,
    triangles: Vec<[i64; 3]>,
    spacing: f64,
    jitter: f64,
    seed: u64,
) -> Result<Vec<Vector3<f64>>> {
    let spacing = check_spacing(spacing)?;
    let jitter = check_param(
        "jitter",
        jitter,
        |j| (0.0..0.5).contains(&j),
        "a fraction of the spacing in [0, 0.5)",
    )?;
    let mesh = MeshDistance::new(vertices, triangles)?;
    let expected = mesh.volume() / spacing.powi(3);
    if expected > MAX_PARTICLES as f64 {
        return Err(invalid!(
            "sampling would give about {expected:.3e} particles (volume {} m^3 / spacing^3), more than {MAX_PARTICLES}: use a larger spacing ({spacing} m)",
            mesh.volume()
        ));
    }
    let (lo, hi) = mesh.bounds();
    let lattice = Lattice::over(lo, hi, spacing, MAX_SITES)?;
    let [nx, ny, nz] = lattice.dims;
    let radius = jitter * spacing;
    let rows: Vec<Vec<Vector3<f64>>> = (0..ny * nz)
        .into_par_iter()
        .map(|row| {
            let (j, k) = (row % ny, row / ny);
            let mut out = Vec::new();
            let mut hint = 0;
            // Sites before `certain` are on the side `inside` of the surface.
            let (mut certain, mut inside) = (0usize, false);
            for i in 0..nx {
                let mut x = lattice.site(i, j, k);
                if radius > 0.0 {
                    x += in_unit_ball(seed, [i as u64, j as u64, k as u64]) * radius;
                }
                if i >= certain {
                    let (d, nearest) = mesh.signed_distance_from(&x, hint);
                    hint = nearest;
                    inside = d < 0.0;
                    // Site i + m (moved) is within m spacing + 2 radius of this point: on its
                    // side while that stays below |d| (with a margin for round-off).
                    let reach = d.abs() * (1.0 - 1e-9) - 2.0 * radius;
                    let steps = (reach / spacing).ceil().max(1.0).min((nx - i) as f64);
                    certain = i + steps as usize;
                }
                if inside {
                    out.push(x);
                }
            }
            out
        })
        .collect();
    Ok(rows.concat())
}
