//! Broad phase: candidate triangle pairs for the local step, by a uniform spatial hash grid.
//!
//! Why a grid and not a BVH: cloth triangles are nearly uniform in size, so one cell size
//! (twice the mean box extent) puts each box in a few cells; the grid is rebuilt from scratch
//! in `O(n)` whenever the local step needs new candidates (see `pair_cache`), so it never
//! degrades under the large deformations and
//! layer-crossing motions where a refitted BVH's boxes grow loose, and it has no tree to
//! maintain. Each pair is reported once: by the cell holding the lower corner of the two
//! boxes' intersection.
//!
//! A triangle's box covers its vertices at the start and at the end of the motion (so
//! continuous collision detection sees every pair that can meet) inflated on each side by its
//! own padding (so two boxes overlap whenever the triangles come within the sum of their
//! paddings; half the contact reach each when all are padded alike).

use nalgebra::Vector3;
use rayon::prelude::*;

/// Which triangles may touch which: the triangles, the body of each, and per body whether
/// self-contact is on.
#[derive(Debug, Clone, Copy)]
pub struct ContactMesh<'a> {
    /// Vertex indices (global) of every triangle.
    pub triangles: &'a [[u32; 3]],
    /// Body index of every triangle.
    pub body: &'a [u32],
    /// Per body: whether its triangles collide with each other.
    pub self_contact: &'a [bool],
}

impl ContactMesh<'_> {
    /// Whether triangles `a` and `b` may be a contact pair: different, sharing no vertex, and
    /// not both of one body without self-contact.
    pub fn may_touch(&self, a: usize, b: usize) -> bool {
        let (ta, tb) = (&self.triangles[a], &self.triangles[b]);
        let (ba, bb) = (self.body[a], self.body[b]);
        if ba == bb && !self.self_contact[ba as usize] {
            return false;
        }
        !ta.iter().any(|v| tb.contains(v))
    }
}

#[derive(Clone, Copy)]
struct Aabb {
    lo: Vector3<f64>,
    hi: Vector3<f64>,
}

impl Aabb {
    fn overlaps(&self, other: &Aabb) -> bool {
        (0..3).all(|k| self.lo[k] <= other.hi[k] && other.lo[k] <= self.hi[k])
    }
}

type Cell = [i64; 3];

/// Cells a box may cover before it is handled by brute force.
const MAX_CELLS_PER_BOX: f64 = 512.0;

/// Groups of grid cells searched in parallel, each into its own buffer (a fixed number, so the
/// work split does not depend on the thread count; the result is sorted anyway).
const CELL_GROUPS: usize = 64;

/// The hash grid and its buffers, kept between calls: once they have grown to the scene's
/// size, a call allocates nothing.
#[derive(Default)]
pub struct BroadPhase {
    boxes: Vec<Aabb>,
    /// `(cell, triangle)` for every cell each box covers, sorted: the grid.
    entries: Vec<(Cell, u32)>,
    /// Ranges of `entries` holding one cell with at least two triangles.
    cells: Vec<(usize, usize)>,
    /// Boxes spanning too many cells, tested against every box instead.
    oversized: Vec<usize>,
    /// The pairs found in each group of cells.
    found: Vec<Vec<(u32, u32)>>,
    pairs: Vec<(u32, u32)>,
    /// The grid's cell size (m).
    cell: f64,
}

/// The cell of the grid with cells of size `cell` (m) holding the point `p` (m).
fn cell_of(p: &Vector3<f64>, cell: f64) -> Cell {
    [0, 1, 2].map(|k| (p[k] / cell).floor() as i64)
}

/// How many grid cells the range `lo..=hi` covers, counted in `f64`: [`cell_of`] saturates
/// far out, and a box reaching infinity spans the whole `i64` range, which `i64` arithmetic
/// would wrap to a span of 0.
fn cells_spanned(lo: &Cell, hi: &Cell) -> f64 {
    (0..3).map(|k| hi[k] as f64 - lo[k] as f64 + 1.0).product()
}

impl BroadPhase {
    /// Triangle pairs `(a, b)`, `a < b`, whose boxes over the motion `start -> end`, each
    /// inflated by its `padding[triangle]` (m), overlap and that [`ContactMesh::may_touch`]
    /// allows, each once, in an order that depends only on the input (not on the thread
    /// count). Not sorted: a build finds tens of millions of pairs on large scenes, and the
    /// callers need no order.
    pub fn candidate_pairs(
        &mut self,
        start: &[Vector3<f64>],
        end: &[Vector3<f64>],
        mesh: &ContactMesh,
        padding: &[f64],
    ) -> &[(u32, u32)] {
        self.pairs.clear();
        self.entries.clear();
        self.oversized.clear();
        mesh.triangles
            .par_iter()
            .zip(padding)
            .map(|(t, &padding)| {
                let mut lo = Vector3::repeat(f64::INFINITY);
                let mut hi = Vector3::repeat(f64::NEG_INFINITY);
                for &v in t {
                    for p in [&start[v as usize], &end[v as usize]] {
                        lo = lo.inf(p);
                        hi = hi.sup(p);
                    }
                }
                let pad = Vector3::repeat(padding);
                Aabb {
                    lo: lo - pad,
                    hi: hi + pad,
                }
            })
            .collect_into_vec(&mut self.boxes);
        let boxes = &self.boxes;
        if boxes.len() < 2 {
            return &self.pairs;
        }
        let mean_extent =
            boxes.iter().map(|b| (b.hi - b.lo).max()).sum::<f64>() / boxes.len() as f64;
        let cell = 2.0 * mean_extent.max(f64::MIN_POSITIVE);
        self.cell = cell;
        let cell_of = |p: &Vector3<f64>| cell_of(p, cell);
        for (t, b) in boxes.iter().enumerate() {
            let (lo, hi) = (cell_of(&b.lo), cell_of(&b.hi));
            if cells_spanned(&lo, &hi) > MAX_CELLS_PER_BOX {
                self.oversized.push(t);
                continue;
            }
            for i in lo[0]..=hi[0] {
                for j in lo[1]..=hi[1] {
                    for k in lo[2]..=hi[2] {
                        self.entries.push(([i, j, k], t as u32));
                    }
                }
            }
        }
        self.entries.par_sort_unstable();
        let entries = &self.entries;
        self.cells.clear();
        let mut first = 0;
        for end in 1..=entries.len() {
            if end == entries.len() || entries[end].0 != entries[first].0 {
                if end - first > 1 {
                    self.cells.push((first, end));
                }
                first = end;
            }
        }

        // Each pair once: in the cell holding the lower corner of the two boxes' overlap.
        let cells = &self.cells;
        let per_group = cells.len().div_ceil(CELL_GROUPS).max(1);
        self.found.resize_with(CELL_GROUPS, Vec::new);
        self.found
            .par_iter_mut()
            .enumerate()
            .for_each(|(g, found)| {
                found.clear();
                let lo = (g * per_group).min(cells.len());
                let hi = ((g + 1) * per_group).min(cells.len());
                for &(first, end) in &cells[lo..hi] {
                    let key = entries[first].0;
                    let members = &entries[first..end];
                    for (n, &(_, a)) in members.iter().enumerate() {
                        for &(_, b) in &members[n + 1..] {
                            let (ba, bb) = (&boxes[a as usize], &boxes[b as usize]);
                            if !ba.overlaps(bb) || cell_of(&ba.lo.sup(&bb.lo)) != key {
                                continue;
                            }
                            if mesh.may_touch(a as usize, b as usize) {
                                found.push((a.min(b), a.max(b)));
                            }
                        }
                    }
                }
            });
        for found in &self.found {
            self.pairs.extend_from_slice(found);
        }
        let oversized = &self.oversized;
        for &a in oversized {
            self.pairs.extend((0..boxes.len()).filter_map(|b| {
                let other_oversized_first = oversized.contains(&b) && b < a;
                (b != a
                    && !other_oversized_first
                    && boxes[a].overlaps(&boxes[b])
                    && mesh.may_touch(a, b))
                .then(|| (a.min(b) as u32, a.max(b) as u32))
            }));
        }
        &self.pairs
    }

    /// Appends to `out` the triangles whose boxes of the last
    /// [`BroadPhase::candidate_pairs`] (inflated by their padding) overlap the box `lo..hi`
    /// (m), each once, increasing.
    pub fn overlapping(&self, lo: Vector3<f64>, hi: Vector3<f64>, out: &mut Vec<u32>) {
        let query = Aabb { lo, hi };
        let start = out.len();
        let (first, last) = (cell_of(&lo, self.cell), cell_of(&hi, self.cell));
        // No grid (fewer than two boxes, or all oversized) or a query too large for it.
        if self.entries.is_empty() || cells_spanned(&first, &last) > MAX_CELLS_PER_BOX {
            out.extend(
                (0..self.boxes.len() as u32).filter(|&t| self.boxes[t as usize].overlaps(&query)),
            );
            return;
        }
        let entries = &self.entries;
        for i in first[0]..=last[0] {
            for j in first[1]..=last[1] {
                for k in first[2]..=last[2] {
                    let key = [i, j, k];
                    let from = entries.partition_point(|e| e.0 < key);
                    out.extend(
                        entries[from..]
                            .iter()
                            .take_while(|e| e.0 == key)
                            .map(|&(_, t)| t)
                            .filter(|&t| self.boxes[t as usize].overlaps(&query)),
                    );
                }
            }
        }
        out.extend(
            self.oversized
                .iter()
                .filter(|&&t| self.boxes[t].overlaps(&query))
                .map(|&t| t as u32),
        );
        let mut found = out.split_off(start);
        found.sort_unstable();
        found.dedup();
        out.extend(found);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::distance::tests::Rng;

    /// The grid finds exactly the pairs a brute-force box test finds.
    #[test]
    fn grid_matches_brute_force() {
        let mut rng = Rng::new(3);
        let n = 300;
        let points: Vec<Vector3<f64>> = (0..3 * n).map(|_| rng.vector() * 2.0).collect();
        let end: Vec<Vector3<f64>> = points.iter().map(|p| p + rng.vector() * 0.05).collect();
        let triangles: Vec<[u32; 3]> = (0..n as u32)
            .map(|t| [3 * t, 3 * t + 1, (3 * t + 5) % (3 * n as u32)])
            .collect();
        let small: Vec<[u32; 3]> = triangles
            .iter()
            .map(|&[a, _, _]| [a, a + 1, a + 2])
            .collect();
        let body: Vec<u32> = (0..n as u32).map(|t| t % 2).collect();
        // One grid for all the calls: reused buffers must not leak pairs from call to call.
        let mut grid = BroadPhase::default();
        for (tris, self_contact) in [(&triangles, [true, false]), (&small, [true, true])] {
            let mesh = ContactMesh {
                triangles: tris,
                body: &body,
                self_contact: &self_contact,
            };
            // Triangles padded differently: 0.05 and 0.02 m by body.
            let padding: Vec<f64> = body.iter().map(|&b| [0.05, 0.02][b as usize]).collect();
            let mut found = grid
                .candidate_pairs(&points, &end, &mesh, &padding)
                .to_vec();
            found.sort_unstable();
            let boxes: Vec<Aabb> = tris
                .iter()
                .zip(&body)
                .map(|(t, &b)| {
                    let all: Vec<Vector3<f64>> = t
                        .iter()
                        .flat_map(|&v| [points[v as usize], end[v as usize]])
                        .collect();
                    let lo = all
                        .iter()
                        .fold(Vector3::repeat(f64::INFINITY), |a, p| a.inf(p));
                    let hi = all
                        .iter()
                        .fold(Vector3::repeat(f64::NEG_INFINITY), |a, p| a.sup(p));
                    let pad = Vector3::repeat([0.05, 0.02][b as usize]);
                    Aabb {
                        lo: lo - pad,
                        hi: hi + pad,
                    }
                })
                .collect();
            let mut brute = Vec::new();
            for a in 0..n {
                for b in a + 1..n {
                    if boxes[a].overlaps(&boxes[b]) && mesh.may_touch(a, b) {
                        brute.push((a as u32, b as u32));
                    }
                }
            }
            assert!(!brute.is_empty());
            assert_eq!(found, brute);
            // A far-flung vertex makes its triangles' boxes huge: same pairs as brute force.
            let mut far = points.clone();
            far[tris[0][0] as usize] = Vector3::new(1e6, 0.0, 0.0);
            let mut found = grid.candidate_pairs(&far, &far, &mesh, &padding).to_vec();
            found.sort_unstable();
            assert!(found.iter().any(|&(a, _)| a == 0));
            assert!(found.windows(2).all(|w| w[0] < w[1]), "no duplicates");
        }
    }

    /// A box query finds exactly the triangles whose inflated boxes a brute-force test finds
    /// overlapping it: small and large queries, queries too large for the grid, a grid with
    /// oversized boxes and one of a single triangle.
    #[test]
    fn overlapping_matches_brute_force() {
        let mut rng = Rng::new(8);
        let n = 400;
        let mut points: Vec<Vector3<f64>> = (0..3 * n).map(|_| rng.vector()).collect();
        points[7] = Vector3::new(1e3, 1e3, 1e3);
        let triangles: Vec<[u32; 3]> = (0..n as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect();
        let body = vec![0; n];
        let padding: Vec<f64> = (0..n).map(|t| 0.01 * (t % 5) as f64).collect();
        for count in [n, 1] {
            let mesh = ContactMesh {
                triangles: &triangles[..count],
                body: &body[..count],
                self_contact: &[true],
            };
            let mut grid = BroadPhase::default();
            grid.candidate_pairs(&points, &points, &mesh, &padding[..count]);
            let mut found = Vec::new();
            for k in 0..200 {
                let centre = rng.vector() * 1.2;
                let half = Vector3::repeat(match k % 4 {
                    0 => 0.001,
                    1 => 0.05,
                    2 => 0.3,
                    _ => 40.0,
                });
                let query = Aabb {
                    lo: centre - half,
                    hi: centre + half,
                };
                found.clear();
                found.push(u32::MAX);
                grid.overlapping(query.lo, query.hi, &mut found);
                let brute: Vec<u32> = (0..count as u32)
                    .filter(|&t| grid.boxes[t as usize].overlaps(&query))
                    .collect();
                assert_eq!(found[0], u32::MAX, "what was in `out` stays");
                assert_eq!(found[1..], brute, "query {k}");
            }
            // Queries whose cells reach the ends of `i64` (far out, or the whole space of a
            // box with a point that is not finite) find every triangle.
            for (lo, hi) in [
                (Vector3::repeat(-1e300), Vector3::repeat(1e300)),
                (
                    Vector3::repeat(f64::NEG_INFINITY),
                    Vector3::repeat(f64::INFINITY),
                ),
            ] {
                found.clear();
                grid.overlapping(lo, hi, &mut found);
                assert_eq!(
                    found,
                    (0..count as u32).collect::<Vec<_>>(),
                    "{lo:?}..{hi:?}"
                );
            }
        }
    }
}
