//! Primitive pairs of the local step: a candidate triangle pair expands into 6 point-triangle
//! and 9 edge-edge pairs (Lu et al. 2023, eq. 48), deduplicated over all candidates (an edge or
//! a vertex belongs to several triangles).

use nalgebra::Vector3;
use rayon::prelude::*;

use super::ccd::{edge_edge_ccd, point_triangle_ccd, AdditiveCcd};
use super::distance::{edge_edge_closest, point_triangle_closest, Closest};

/// A primitive pair: point-triangle `[p, t0, t1, t2]` or edge-edge `[a0, a1, b0, b1]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(super) struct Pair {
    pub edge_edge: bool,
    pub v: [u32; 4],
}

/// Primitive pairs per triangle pair.
const PER_TRIANGLE_PAIR: usize = 15;

impl Pair {
    fn points(&self, x: &[Vector3<f64>]) -> [Vector3<f64>; 4] {
        self.v.map(|i| x[i as usize])
    }

    /// A lower bound of the pair's distance (m) wherever each vertex `i` is at most
    /// `moved[i] + extra` (m) from where the distance was `distance` (m): a point of a
    /// primitive is a convex combination of its vertices, so it moves at most as far as the
    /// farthest of them, and the distance shrinks at most by the two primitives' moves. NaN
    /// if an input is NaN (callers keep the pair then).
    pub fn distance_bound(&self, distance: f64, moved: &[f64], extra: f64) -> f64 {
        let (a, b) = self.v.split_at(if self.edge_edge { 2 } else { 1 });
        let farthest = |vertices: &[u32]| {
            vertices
                .iter()
                .map(|&v| moved[v as usize])
                .fold(0.0, |m: f64, x| if x.is_nan() || x > m { x } else { m })
        };
        distance - farthest(a) - farthest(b) - 2.0 * extra
    }

    /// Closest points at the positions `x` (m).
    pub fn closest(&self, x: &[Vector3<f64>]) -> Closest {
        let p = self.points(x);
        if self.edge_edge {
            edge_edge_closest(&p[0], &p[1], &p[2], &p[3])
        } else {
            point_triangle_closest(&p[0], &p[1], &p[2], &p[3])
        }
    }

    /// Additive CCD over the motion `start -> end` keeping the pair `min` (m) apart: the time
    /// of impact in `[0, 1]`, or `None`.
    pub fn ccd(
        &self,
        start: &[Vector3<f64>],
        end: &[Vector3<f64>],
        min: f64,
        ccd: &AdditiveCcd,
    ) -> Option<f64> {
        let (a, b) = (self.points(start), self.points(end));
        if self.edge_edge {
            edge_edge_ccd(&a, &b, min, ccd)
        } else {
            point_triangle_ccd(&a, &b, min, ccd)
        }
    }
}

/// Writes into `pairs` the primitive pairs of the candidate triangle pairs, sorted and
/// deduplicated (reusing its allocation).
pub(super) fn primitive_pairs(
    triangles: &[[u32; 3]],
    candidates: &[(u32, u32)],
    pairs: &mut Vec<Pair>,
) {
    let edge = |t: &[u32; 3], k: usize| {
        let (a, b) = (t[k], t[(k + 1) % 3]);
        [a.min(b), a.max(b)]
    };
    let blank = Pair {
        edge_edge: false,
        v: [0; 4],
    };
    pairs.clear();
    pairs.resize(PER_TRIANGLE_PAIR * candidates.len(), blank);
    pairs
        .par_chunks_mut(PER_TRIANGLE_PAIR)
        .zip(candidates)
        .for_each(|(out, &(i, j))| {
            let (ti, tj) = (&triangles[i as usize], &triangles[j as usize]);
            let mut out = out.iter_mut();
            for (a, b) in [(ti, tj), (tj, ti)] {
                for &p in a {
                    *out.next().expect("15 slots") = Pair {
                        edge_edge: false,
                        v: [p, b[0], b[1], b[2]],
                    };
                }
            }
            for ki in 0..3 {
                for kj in 0..3 {
                    let (ea, eb) = (edge(ti, ki), edge(tj, kj));
                    let (ea, eb) = if ea <= eb { (ea, eb) } else { (eb, ea) };
                    *out.next().expect("15 slots") = Pair {
                        edge_edge: true,
                        v: [ea[0], ea[1], eb[0], eb[1]],
                    };
                }
            }
        });
    pairs.par_sort_unstable();
    pairs.dedup();
}

#[cfg(test)]
mod tests {
    use super::super::distance::tests::Rng;
    use super::*;

    /// Moving every vertex by at most its bound never brings a pair closer than
    /// [`Pair::distance_bound`], and a NaN bound stays NaN.
    #[test]
    fn the_distance_bound_holds_under_bounded_moves() {
        let mut rng = Rng::new(11);
        for k in 0..2000 {
            let pair = Pair {
                edge_edge: k % 2 == 0,
                v: [0, 1, 2, 3],
            };
            let x: Vec<_> = (0..4).map(|_| rng.vector()).collect();
            let moved: Vec<f64> = (0..4).map(|_| 0.2 * (rng.uniform() + 1.0)).collect();
            let extra = 0.05 * (rng.uniform() + 1.0);
            let y: Vec<_> = x
                .iter()
                .zip(&moved)
                .map(|(p, &m)| {
                    let dir = rng.vector();
                    p + dir * ((m + extra) * rng.uniform().abs() / dir.norm())
                })
                .collect();
            let d = pair.closest(&x).separation.norm();
            let bound = pair.distance_bound(d, &moved, extra);
            assert!(
                pair.closest(&y).separation.norm() >= bound - 1e-12,
                "case {k}"
            );
        }
        let pair = Pair {
            edge_edge: false,
            v: [0, 1, 2, 3],
        };
        assert!(pair
            .distance_bound(1.0, &[0.0, f64::NAN, 0.0, 0.0], 0.0)
            .is_nan());
    }
}
