//! A single layer of particles on a triangle surface, at least `spacing` apart.

use std::collections::HashMap;

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::error::{invalid, Result};
use crate::mesh::TriangleMesh;

use super::random::hash;
use super::{check_spacing, MAX_PARTICLES};

/// Candidates per spacing along each direction: candidates are at most `spacing / 3` apart.
const CANDIDATES_PER_SPACING: f64 = 3.0;

/// Most candidate points [`sample_surface`] generates (32 bytes each while sampling: 2 GB),
/// about nine per `spacing^2` of area, which allows some six million particles.
pub const MAX_SURFACE_CANDIDATES: usize = 1 << 26;

/// Particles on the surface `vertices` (m) / `triangles` (closed or open), a single layer with
/// no two closer than `spacing` (m), for shells: greedy Poisson-disk sampling from dense
/// candidates.
///
/// The candidates cover every triangle with rows parallel to its longest edge, at most
/// `h = spacing / 3` apart along and across the rows. A surface point lies between two rows,
/// and its foot on the lower (longer) one is on that row (the triangle's angles at the longest
/// edge are acute), so it is within `sqrt(h^2 + h^2 / 4) = (sqrt 5 / 2) h` of a candidate.
/// They are visited in a random order (a hash of `seed` and the
/// candidate's number) and each one at least `spacing` away from every particle accepted so far
/// becomes a particle. Guarantees: distinct particles are at least `spacing` apart (3-D
/// distance); every surface point is within `spacing + (sqrt 5 / 2) h ~ 1.38 spacing` of a
/// particle (every candidate was accepted or lies within `spacing` of a particle); the count is
/// about `0.7 A / spacing^2` (`A` the area; the jamming density of random disk packings), so
/// each particle stands for `A / N` (m^2) of surface. The output is ordered by triangle and
/// does not depend on the number of threads; the greedy pass itself is serial.
///
/// Errors (naming the culprit): `spacing` not finite and positive; a mesh with fewer than
/// three vertices or no triangle, or one that [`TriangleMesh::new`] rejects (non-finite or
/// unused vertices, bad indices, degenerate or duplicate triangles, non-manifold edges); more
/// than [`MAX_SURFACE_CANDIDATES`] candidates or [`MAX_PARTICLES`] expected particles.
pub fn sample_surface(
    vertices: Vec<[f64; 3]>,
    triangles: Vec<[i64; 3]>,
    spacing: f64,
    seed: u64,
) -> Result<Vec<Vector3<f64>>> {
    Ok(sample_surface_with_normals(vertices, triangles, spacing, seed)?.points)
}

/// [`sample_surface`]'s particles with the unit normal of the triangle each lies on (oriented
/// by the triangle's winding) and the surface's area (m^2), for the shells' builder.
pub struct SurfaceSample {
    pub points: Vec<Vector3<f64>>,
    pub normals: Vec<Vector3<f64>>,
    pub area: f64,
}

/// [`sample_surface`] with each particle's normal and the area ([`SurfaceSample`]).
pub fn sample_surface_with_normals(
    vertices: Vec<[f64; 3]>,
    triangles: Vec<[i64; 3]>,
    spacing: f64,
    seed: u64,
) -> Result<SurfaceSample> {
    let spacing = check_spacing(spacing)?;
    if vertices.len() < 3 || triangles.is_empty() {
        return Err(invalid!(
            "a surface needs at least 3 vertices and 1 triangle, got {} and {}",
            vertices.len(),
            triangles.len()
        ));
    }
    let mesh = TriangleMesh::new(vertices, triangles)?;
    let x = mesh.vertices();
    let h = spacing / CANDIDATES_PER_SPACING;
    let layouts: Vec<RowLayout> = mesh
        .triangles()
        .iter()
        .map(|t| RowLayout::new(t.map(|i| x[i as usize]), h))
        .collect();
    let total: f64 = layouts.iter().map(|l| l.count as f64).sum();
    let area: f64 = layouts.iter().map(|l| l.area).sum();
    if total > MAX_SURFACE_CANDIDATES as f64 {
        return Err(invalid!(
            "sampling the surface needs {total:.3e} candidate points (area {area} m^2), more than {MAX_SURFACE_CANDIDATES}: use a larger spacing ({spacing} m)"
        ));
    }
    let expected = area / (spacing * spacing);
    if expected > MAX_PARTICLES as f64 {
        return Err(invalid!(
            "sampling would give about {expected:.3e} particles (area / spacing^2), more than {MAX_PARTICLES}: use a larger spacing ({spacing} m)"
        ));
    }
    let (candidates, on): (Vec<Vector3<f64>>, Vec<u32>) = layouts
        .par_iter()
        .enumerate()
        .flat_map_iter(|(t, l)| l.points().map(move |p| (p, t as u32)))
        .unzip();
    let mut visit: Vec<(u64, u32)> = (0..candidates.len() as u32)
        .into_par_iter()
        .map(|c| (hash(seed, &[u64::from(c)]), c))
        .collect();
    visit.par_sort_unstable();

    // Accepted particles in cells of side `spacing`: a particle closer than `spacing` to a point
    // lies in the 27 cells around the point's.
    let cell_of = |p: &Vector3<f64>| p.map(|c| (c / spacing).floor() as i64);
    let mut cells: HashMap<Vector3<i64>, Vec<u32>> = HashMap::new();
    let mut accepted: Vec<u32> = Vec::new();
    let s2 = spacing * spacing;
    for &(_, c) in &visit {
        let p = &candidates[c as usize];
        let home = cell_of(p);
        let mut free = true;
        'search: for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let key = home + Vector3::new(dx, dy, dz);
                    for &a in cells.get(&key).map_or(&[][..], |v| &v[..]) {
                        if (candidates[a as usize] - p).norm_squared() < s2 {
                            free = false;
                            break 'search;
                        }
                    }
                }
            }
        }
        if free {
            cells.entry(home).or_default().push(c);
            accepted.push(c);
        }
    }
    accepted.sort_unstable();
    Ok(SurfaceSample {
        points: accepted.iter().map(|&c| candidates[c as usize]).collect(),
        normals: accepted
            .iter()
            .map(|&c| layouts[on[c as usize] as usize].normal())
            .collect(),
        area,
    })
}

/// Candidate rows over one triangle: rows parallel to its longest edge `a b`, from that edge
/// (`t = 0`) to the apex `c` (`t = 1`) in `rows` equal steps of at most `h` (m); row `r`, of
/// length `(1 - t) |b - a|`, holds points at most `h` apart, both ends included.
struct RowLayout {
    corners: [Vector3<f64>; 3],
    rows: usize,
    /// Length of the longest edge over `h`.
    along: f64,
    count: usize,
    /// Area (m^2).
    area: f64,
}

impl RowLayout {
    fn new(t: [Vector3<f64>; 3], h: f64) -> Self {
        let longest = (0..3)
            .max_by(|&i, &j| {
                let len = |k: usize| (t[(k + 1) % 3] - t[k]).norm_squared();
                len(i).total_cmp(&len(j)).then(j.cmp(&i))
            })
            .expect("three edges");
        let corners = [t[longest], t[(longest + 1) % 3], t[(longest + 2) % 3]];
        let [a, b, c] = corners;
        let base = (b - a).norm();
        let twice_area = (b - a).cross(&(c - a)).norm();
        let height = twice_area / base;
        let rows = (height / h).ceil().max(1.0) as usize;
        let along = base / h;
        let count = (0..=rows).map(|r| Self::per_row(along, r, rows)).sum();
        Self {
            corners,
            rows,
            along,
            count,
            area: 0.5 * twice_area,
        }
    }

    /// The unit normal, oriented by the winding (the corners are a cyclic turn of it).
    fn normal(&self) -> Vector3<f64> {
        let [a, b, c] = self.corners;
        (b - a).cross(&(c - a)).normalize()
    }

    /// Points of row `r` of `rows`: at most `h` apart over `(1 - r / rows) along h`.
    fn per_row(along: f64, r: usize, rows: usize) -> usize {
        let length = along * (1.0 - r as f64 / rows as f64);
        length.ceil() as usize + 1
    }

    fn points(&self) -> impl Iterator<Item = Vector3<f64>> + '_ {
        let [a, b, c] = self.corners;
        (0..=self.rows).flat_map(move |r| {
            let t = r as f64 / self.rows as f64;
            let (start, end) = (a + (c - a) * t, b + (c - b) * t);
            let m = Self::per_row(self.along, r, self.rows);
            (0..m).map(move |q| {
                if m == 1 {
                    start
                } else {
                    start + (end - start) * (q as f64 / (m - 1) as f64)
                }
            })
        })
    }
}
