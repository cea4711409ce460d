//! Primitive pairs of the local step: a candidate triangle pair expands into 6 point-triangle
//! and 9 edge-edge pairs (Lu et al. 2023, eq. 48); an edge or a vertex belongs to several
//! triangles, so a build expands each pair in one triangle pair only (see [`Owners`]).

use nalgebra::Vector3;
use rayon::prelude::*;

use super::broad_phase::ContactMesh;
use super::ccd::{edge_edge_ccd, point_triangle_ccd, AdditiveCcd};
use super::parallel_fade::edge_edge_fade;
use crate::geometry::bounds::{bounding_box, box_gap, nan_max, round_down};
use crate::geometry::distance::{edge_edge_closest, point_triangle_closest, Closest};
use crate::geometry::vertex_index::index_by_vertex;

/// A primitive pair: point-triangle `[p, t0, t1, t2]` or edge-edge `[a0, a1, b0, b1]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
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
    /// `moved[i] + extra[i]` (m) from where the distance was `distance` (m): a point of a
    /// primitive is a convex combination of its vertices, so it moves at most as far as the
    /// farthest of them, and the distance shrinks at most by the two primitives' moves. NaN
    /// if an input is NaN (callers keep the pair then).
    pub fn distance_bound(&self, distance: f64, moved: &[f64], extra: &[f64]) -> f64 {
        distance - self.spread_of(|v| moved[v] + extra[v])
    }

    /// `max_A values + max_B values` over the two primitives' vertices (each max at least 0),
    /// NaN if one of the values is.
    pub fn spread(&self, values: &[f64]) -> f64 {
        self.spread_of(|v| values[v])
    }

    /// [`Pair::spread`] of the per-vertex values `value(v)`.
    #[inline]
    fn spread_of(&self, value: impl Fn(usize) -> f64) -> f64 {
        let (a, b) = self.sides();
        farthest(a, &value) + farthest(b, &value)
    }

    /// A lower bound of the pair's distance (m) wherever each vertex `i` is displaced from
    /// where the distance was `distance` (m) by `u_i = (1 - tau) shift[i][0] + tau shift[i][1] +
    /// e_i`, with one `tau` in `[0, 1]` for all vertices and `|e_i| <= extra[i]` (m): the bound
    /// `distance - max_{a in A, b in B} max_k |shift[a][k] - shift[b][k]| - max_A extra - max_B
    /// extra` (A, B the two primitives). Why: a point of A minus a point of B, with barycentric
    /// weights `alpha` and `beta`, moves by `sum_{a, b} alpha_a beta_b (u_a - u_b)`, at most the
    /// largest `|u_a - u_b|`; the `tau` part of `u_a - u_b` is affine in `tau`, so its length is
    /// largest at `tau = 0` or 1, and the rest is at most `extra[a] + extra[b]`. A common motion
    /// (`shift` equal on all four vertices) costs nothing. NaN if an input is NaN (callers keep
    /// the pair then).
    pub fn relative_distance_bound(
        &self,
        distance: f64,
        shift: &[[Vector3<f64>; 2]],
        extra: &[f64],
    ) -> f64 {
        self.relative_distance_bound_of(distance, 0.0, |v| shift[v], |v| extra[v])
    }

    /// [`Pair::relative_distance_bound`] of the per-vertex displacements `shift(v)` (m) and
    /// allowances `extra(v)` (m), with the largest relative move taken `margin` (m) larger:
    /// `distance - (max_{a in A, b in B} max_k |shift(a)[k] - shift(b)[k]| + margin) - max_A
    /// extra - max_B extra`. A `margin` of 0 gives the bound itself (to the bit); a positive
    /// one keeps it a lower bound where each displacement given lies within somewhat less
    /// than `margin / 2` of the true one, the rest covering the round-off (the packed ones
    /// of the pair cache's sweep). NaN if an input is NaN.
    #[inline]
    pub fn relative_distance_bound_of(
        &self,
        distance: f64,
        margin: f64,
        shift: impl Fn(usize) -> [Vector3<f64>; 2],
        extra: impl Fn(usize) -> f64,
    ) -> f64 {
        let (a, b) = self.sides();
        let mut apart_squared = 0.0;
        for &i in a {
            let p = shift(i as usize);
            for &j in b {
                for (p, q) in p.iter().zip(&shift(j as usize)) {
                    apart_squared = nan_max(apart_squared, (p - q).norm_squared());
                }
            }
        }
        distance - (apart_squared.sqrt() + margin) - self.spread_of(extra)
    }

    /// The vertices of the two primitives.
    pub fn sides(&self) -> (&[u32], &[u32]) {
        self.v.split_at(if self.edge_edge { 2 } else { 1 })
    }

    /// A lower bound of the pair's distance (m) at its four points `p` (m) that costs a
    /// fraction of [`Pair::closest`]: the gap between the axis-aligned boxes of its two
    /// primitives (every point of a primitive lies in the box of its vertices). 0 if a
    /// position is NaN or infinite (see [`bounding_box`]): the distance decides then.
    fn box_gap(&self, p: &[Vector3<f64>; 4]) -> f64 {
        let (a, b) = p.split_at(self.sides().0.len());
        box_gap(bounding_box(a), bounding_box(b))
    }

    /// Closest points at the positions `x` (m).
    pub fn closest(&self, x: &[Vector3<f64>]) -> Closest {
        self.closest_of(&self.points(x))
    }

    /// [`Pair::closest`] of the pair's four points `p`.
    fn closest_of(&self, p: &[Vector3<f64>; 4]) -> Closest {
        if self.edge_edge {
            edge_edge_closest(&p[0], &p[1], &p[2], &p[3])
        } else {
            point_triangle_closest(&p[0], &p[1], &p[2], &p[3])
        }
    }

    /// The pair's distance (m) and fade at `x`: [`edge_edge_fade`] for an edge-edge pair
    /// with the fade limit `sin2_limit` (`sin^2` of the fade angle), 1 for a point-triangle
    /// pair.
    pub fn distance_and_fade(&self, x: &[Vector3<f64>], sin2_limit: f64) -> (f64, f64) {
        let p = self.points(x);
        let distance = self.closest_of(&p).separation.norm();
        if self.edge_edge {
            (
                distance,
                edge_edge_fade(&(p[1] - p[0]), &(p[3] - p[2]), sin2_limit),
            )
        } else {
            (distance, 1.0)
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

/// The largest `value(v)` over `vertices` (at least 0), NaN if one is NaN.
fn farthest(vertices: &[u32], value: &impl Fn(usize) -> f64) -> f64 {
    vertices
        .iter()
        .map(|&v| value(v as usize))
        .fold(0.0, nan_max)
}

/// The 6 point-triangle and 9 edge-edge pairs of the triangles `ti` and `tj` (eq. 48), each
/// edge-edge pair with its lower edge first (so that expansions of several triangle pairs
/// deduplicate).
fn expand(ti: &[u32; 3], tj: &[u32; 3]) -> [Pair; PER_TRIANGLE_PAIR] {
    let edge = |t: &[u32; 3], k: usize| {
        let (a, b) = (t[k], t[(k + 1) % 3]);
        [a.min(b), a.max(b)]
    };
    let mut out = [Pair {
        edge_edge: false,
        v: [0; 4],
    }; PER_TRIANGLE_PAIR];
    let mut slots = out.iter_mut();
    for (a, b) in [(ti, tj), (tj, ti)] {
        for &p in a {
            *slots.next().expect("15 slots") = Pair {
                edge_edge: false,
                v: [p, b[0], b[1], b[2]],
            };
        }
    }
    for ki in 0..3 {
        for kj in 0..3 {
            let (ea, eb) = (edge(ti, ki), edge(tj, kj));
            let (ea, eb) = if ea <= eb { (ea, eb) } else { (eb, ea) };
            *slots.next().expect("15 slots") = Pair {
                edge_edge: true,
                v: [ea[0], ea[1], eb[0], eb[1]],
            };
        }
    }
    out
}

/// The smallest of the 15 primitive distances (eq. 48) of the triangles `ti` and `tj` at the
/// positions `x` (m): their distance unless they cross (two disjoint triangles' closest points
/// lie on a vertex of one or on an edge of each), and at least the distance of every
/// primitive pair they expand into. NaN if a position is NaN.
pub fn closest_primitive_distance(x: &[Vector3<f64>], ti: &[u32; 3], tj: &[u32; 3]) -> f64 {
    expand(ti, tj)
        .iter()
        .map(|p| p.closest(x).separation.norm())
        .fold(
            f64::INFINITY,
            |m, d| if d.is_nan() || d < m { d } else { m },
        )
}

/// Triangle pairs and the primitive pairs they hold, with their distances (m) rounded down to
/// `f32`.
type CandidatesAndPairs = (Vec<(u32, u32)>, Vec<(Pair, f32)>);

/// Which triangle pair expands each primitive pair, so that a build computes each once (a
/// vertex belongs to about six triangles and an edge to two, so the 15 pairs of every
/// triangle pair repeat each about four times over the triangle pairs of a sheet).
///
/// The owner of a point-triangle pair `(v, F)` is `F` with the lowest-numbered triangle of
/// `v` that may touch `F`; of an edge-edge pair, the lowest `(min, max)` of the pairs of
/// triangles of its two edges that may touch. Every triangle holding a primitive has a box
/// holding it, so where the boxes of every triangle pair that may touch overlap whenever two
/// of their primitives come within those primitives' limit (as a padding of each triangle by
/// the largest of its vertices' shares of the limit provides), the owner's boxes overlap
/// whenever the pair is within its limit: expanding only the pairs a triangle pair owns then
/// finds every close pair once. (A triangle pair yields a pair only to a lower pair of
/// triangles it finds holding the two primitives and allowed to touch, so the lowest of all
/// always keeps it.)
#[derive(Default)]
pub(super) struct Owners {
    /// The triangles of vertex `v` are `incident[start[v]..start[v + 1]]`, increasing.
    start: Vec<u32>,
    incident: Vec<u32>,
    /// Per triangle and edge `k` (from corner `k` to corner `k + 1`): the other triangle
    /// holding the edge, [`NONE`] or [`MANY`].
    across: Vec<[u32; 3]>,
}

/// No other triangle holds the edge.
const NONE: u32 = u32::MAX;
/// Several other triangles hold the edge (a non-manifold edge): look them up.
const MANY: u32 = u32::MAX - 1;

impl Owners {
    /// Indexes the triangles of every vertex and edge of `mesh` (`vertices` vertices).
    pub fn index(&mut self, mesh: &ContactMesh, vertices: usize) {
        index_by_vertex(
            mesh.triangles.iter().copied(),
            vertices,
            &mut self.start,
            &mut self.incident,
        );
        let mut across = std::mem::take(&mut self.across);
        let this = &*self;
        mesh.triangles
            .par_iter()
            .enumerate()
            .map(|(k, t)| {
                [0, 1, 2].map(|e| {
                    let mut others = this
                        .of_edge(t[e], t[(e + 1) % 3])
                        .filter(|&o| o as usize != k);
                    match (others.next(), others.next()) {
                        (None, _) => NONE,
                        (Some(o), None) => o,
                        _ => MANY,
                    }
                })
            })
            .collect_into_vec(&mut across);
        self.across = across;
    }

    /// The triangles of vertex `v`, increasing.
    pub fn of(&self, v: u32) -> &[u32] {
        &self.incident[self.start[v as usize] as usize..self.start[v as usize + 1] as usize]
    }

    /// The triangles holding the edge `[a, b]`, increasing.
    fn of_edge(&self, a: u32, b: u32) -> impl Iterator<Item = u32> + Clone + '_ {
        let other = self.of(b);
        self.of(a)
            .iter()
            .copied()
            .filter(move |t| other.contains(t))
    }

    /// Whether `point`, a triangle of vertex `v` that may touch `face`, is the lowest-numbered
    /// such triangle.
    fn first_touching(&self, mesh: &ContactMesh, v: u32, point: u32, face: u32) -> bool {
        for &t in self.of(v) {
            if t == point {
                return true;
            }
            if mesh.may_touch(t as usize, face as usize) {
                return false;
            }
        }
        false
    }

    /// The triangles holding edge `k` of triangle `t`: `t` first.
    fn holders<'a>(
        &'a self,
        mesh: &ContactMesh,
        t: u32,
        k: usize,
    ) -> impl Iterator<Item = u32> + Clone + 'a {
        let across = self.across[t as usize][k];
        let tri = mesh.triangles[t as usize];
        let many = (across == MANY).then(|| {
            self.of_edge(tri[k], tri[(k + 1) % 3])
                .filter(move |&o| o != t)
        });
        std::iter::once(t)
            .chain((across != NONE && across != MANY).then_some(across))
            .chain(many.into_iter().flatten())
    }

    /// Whether the pair `(a, b)` (`a < b`, triangles that may touch) owns the edge-edge pair
    /// of edge `ka` of `a` and edge `kb` of `b`: no other pair of triangles holding the two
    /// edges that may touch comes before it in `(min, max)` order (only those that would are
    /// tested).
    fn owns_edges(&self, mesh: &ContactMesh, (a, ka): (u32, usize), (b, kb): (u32, usize)) -> bool {
        let earlier = |ta: u32, tb: u32| {
            (ta.min(tb), ta.max(tb)) < (a, b) && mesh.may_touch(ta as usize, tb as usize)
        };
        let (oa, ob) = (self.across[a as usize][ka], self.across[b as usize][kb]);
        if oa == MANY || ob == MANY {
            return !self
                .holders(mesh, a, ka)
                .flat_map(|ta| self.holders(mesh, b, kb).map(move |tb| (ta, tb)))
                .any(|(ta, tb)| earlier(ta, tb));
        }
        let (with_a, with_b) = (oa != NONE, ob != NONE);
        !((with_a && earlier(oa, b))
            || (with_b && earlier(a, ob))
            || (with_a && with_b && earlier(oa, ob)))
    }

    /// Which of the 15 pairs [`expand`] gives for the triangle pair `(i, j)` (`i < j`, triangles
    /// that may touch) it owns, in [`expand`]'s order.
    fn owned(&self, mesh: &ContactMesh, i: u32, j: u32) -> [bool; PER_TRIANGLE_PAIR] {
        let mut out = [false; PER_TRIANGLE_PAIR];
        let mut slots = out.iter_mut();
        for (point, face) in [(i, j), (j, i)] {
            for &v in &mesh.triangles[point as usize] {
                *slots.next().expect("15 slots") = self.first_touching(mesh, v, point, face);
            }
        }
        for ki in 0..3 {
            for kj in 0..3 {
                *slots.next().expect("15 slots") = self.owns_edges(mesh, (i, ki), (j, kj));
            }
        }
        out
    }
}

/// Triangle pairs of `boxes` per chunk of [`close_primitive_pairs`].
const BOXES_PER_CHUNK: usize = 4096;

/// Writes into `found` the primitive pairs `p` of the triangle pairs `(i, j)` (`i < j`) of
/// `boxes` whose distance `d` (m, NaN where a position is) at the positions `x` (m) is below
/// `limit(p)` (m) or NaN and passes `keep(p, d)`, each with that distance rounded down to `f32`
/// (a lower bound in 4 bytes instead of 8; NaN stays NaN), in the order of `boxes`, in chunks
/// (one per [`BOXES_PER_CHUNK`] triangle pairs: concatenating them is left to the caller, who
/// orders them anyway); returns the triangle pairs that hold one of them (the candidates), in the
/// same order. With `owners`, a triangle pair expands only the pairs it owns (see
/// [`Owners`]): each close pair is found once (and only if the boxes of its owner are in
/// `boxes`); without, a pair shared by several triangle pairs is found once for each. A pair
/// whose [`Pair::box_gap`] is at least its limit is left out without its distance: most pairs
/// of a build's boxes are beyond their limit, and their closest points cost several times
/// the gap.
pub(super) fn close_primitive_pairs(
    mesh: &ContactMesh,
    owners: Option<&Owners>,
    boxes: &[(u32, u32)],
    x: &[Vector3<f64>],
    limit: impl Fn(&Pair) -> f64 + Sync,
    keep: impl Fn(&Pair, f64) -> bool + Sync,
    found: &mut Vec<Vec<(Pair, f32)>>,
) -> Vec<(u32, u32)> {
    let triangles = mesh.triangles;
    let chunks: Vec<CandidatesAndPairs> = boxes
        .par_chunks(BOXES_PER_CHUNK)
        .map(|chunk| {
            let (mut candidates, mut close) = (Vec::new(), Vec::new());
            for &(i, j) in chunk {
                let before = close.len();
                let owned = owners.map_or([true; PER_TRIANGLE_PAIR], |o| o.owned(mesh, i, j));
                close.extend(
                    expand(&triangles[i as usize], &triangles[j as usize])
                        .into_iter()
                        .zip(owned)
                        .filter_map(|(p, owned)| owned.then_some(p))
                        .filter_map(|p| {
                            let (limit, q) = (limit(&p), p.points(x));
                            // A NaN gap or limit compares false: the distance decides then.
                            if p.box_gap(&q) >= limit {
                                return None;
                            }
                            let d = p.closest_of(&q).separation.norm();
                            ((d < limit || d.is_nan()) && keep(&p, d)).then_some((p, d))
                        })
                        .map(|(p, d)| (p, round_down(d))),
                );
                if close.len() > before {
                    candidates.push((i, j));
                }
            }
            (candidates, close)
        })
        .collect();
    let mut candidates = Vec::with_capacity(chunks.iter().map(|(c, _)| c.len()).sum());
    found.clear();
    for (c, close) in chunks {
        candidates.extend_from_slice(&c);
        found.push(close);
    }
    candidates
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::distance::tests::Rng;

    /// For triangles on either side of a plane (so they do not cross), the closest primitive
    /// distance is the smallest distance between their points: never above the distance of
    /// sampled points on them, close to the sampled minimum, and exact for a triangle lifted
    /// along its normal.
    #[test]
    fn closest_primitive_distance_is_the_distance_of_disjoint_triangles() {
        let mut rng = Rng::new(5);
        let sample = |x: &[Vector3<f64>], t: &[u32; 3], rng: &mut Rng| {
            let (mut a, mut b) = (rng.uniform().abs(), rng.uniform().abs());
            if a + b > 1.0 {
                (a, b) = (1.0 - a, 1.0 - b);
            }
            let [p, q, r] = t.map(|v| x[v as usize]);
            p + (q - p) * a + (r - p) * b
        };
        let (ti, tj) = ([0, 1, 2], [3, 4, 5]);
        for k in 0..300 {
            // Below and above the plane z = 0.
            let x: Vec<_> = (0..6)
                .map(|v| {
                    let mut p = rng.vector();
                    p.z = p.z.abs() * if v < 3 { -1.0 } else { 1.0 };
                    p
                })
                .collect();
            let d = closest_primitive_distance(&x, &ti, &tj);
            let a: Vec<_> = (0..60).map(|_| sample(&x, &ti, &mut rng)).collect();
            let b: Vec<_> = (0..60).map(|_| sample(&x, &tj, &mut rng)).collect();
            let sampled = a
                .iter()
                .flat_map(|p| b.iter().map(move |q| (p - q).norm()))
                .fold(f64::INFINITY, f64::min);
            assert!(
                d <= sampled + 1e-12,
                "case {k}: {d} above sampled {sampled}"
            );
            assert!(
                sampled - d < 0.4,
                "case {k}: {d} far below sampled {sampled}"
            );
            // The first triangle lifted by 0.25 along its normal: exactly 0.25 apart.
            let normal = (x[1] - x[0]).cross(&(x[2] - x[0])).normalize();
            let lifted: Vec<_> = (0..6)
                .map(|v| x[v % 3] + normal * (0.25 * (v / 3) as f64))
                .collect();
            let d = closest_primitive_distance(&lifted, &ti, &tj);
            assert!((d - 0.25).abs() < 1e-9, "case {k}: {d}");
        }
        let mut x = vec![Vector3::zeros(); 6];
        x[4].x = f64::NAN;
        assert!(closest_primitive_distance(&x, &ti, &tj).is_nan());
    }

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
            let extra: Vec<f64> = (0..4).map(|_| 0.05 * (rng.uniform() + 1.0)).collect();
            let y: Vec<_> = x
                .iter()
                .zip(moved.iter().zip(&extra))
                .map(|(p, (&m, &e))| {
                    let dir = rng.vector();
                    p + dir * ((m + e) * rng.uniform().abs() / dir.norm())
                })
                .collect();
            let d = pair.closest(&x).separation.norm();
            let bound = pair.distance_bound(d, &moved, &extra);
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
            .distance_bound(1.0, &[0.0, f64::NAN, 0.0, 0.0], &[0.0; 4])
            .is_nan());
    }

    /// Moving the vertices along `(1 - tau) shift_0 + tau shift_1` (one `tau` for all, the
    /// ends included) plus a move of at most `extra` each never brings a pair closer than
    /// [`Pair::relative_distance_bound`]; the bound is often positive despite a common shift
    /// beyond the pair's size (which takes the absolute bound of the same moves far below it),
    /// and a NaN shift gives NaN.
    #[test]
    fn the_relative_distance_bound_holds_under_bounded_relative_moves() {
        let mut rng = Rng::new(13);
        let mut informative = 0;
        for k in 0..3000 {
            let pair = Pair {
                edge_edge: k % 2 == 0,
                v: [0, 1, 2, 3],
            };
            let x: Vec<_> = (0..4).map(|_| rng.vector()).collect();
            // A common motion longer than 1.2 (beyond the pair's size) and relative parts:
            let common = [
                Vector3::new(3.0, 0.0, 0.0) + rng.vector(),
                Vector3::new(0.0, -3.0, 0.0) + rng.vector(),
            ];
            // One end's relative part larger than the other's, so that a bound that missed
            // either end would fail.
            let relative = if k % 4 < 2 { [0.3, 0.01] } else { [0.01, 0.3] };
            let shift: Vec<[Vector3<f64>; 2]> = (0..4)
                .map(|_| {
                    [
                        common[0] + rng.vector() * relative[0],
                        common[1] + rng.vector() * relative[1],
                    ]
                })
                .collect();
            let extra: Vec<f64> = (0..4).map(|_| 0.05 * (rng.uniform() + 1.0)).collect();
            let d = pair.closest(&x).separation.norm();
            let bound = pair.relative_distance_bound(d, &shift, &extra);
            for tau in [0.0, 1.0, rng.uniform().abs()] {
                let y: Vec<_> = (0..4)
                    .map(|i| {
                        let dir = rng.vector();
                        let e = dir * (extra[i] * rng.uniform().abs().sqrt() / dir.norm());
                        x[i] + shift[i][0] * (1.0 - tau) + shift[i][1] * tau + e
                    })
                    .collect();
                let moved = pair.closest(&y).separation.norm();
                assert!(moved >= bound - 1e-12, "case {k}, tau {tau}");
            }
            informative += usize::from(bound > 0.0);
            let absolute: Vec<f64> = (0..4)
                .map(|i| shift[i][0].norm().max(shift[i][1].norm()) + extra[i])
                .collect();
            assert!(
                bound - pair.distance_bound(d, &absolute, &[0.0; 4]) > 1.0,
                "case {k}"
            );
        }
        // The bound is not vacuous: often above 0.
        assert!(informative > 1000, "{informative}");
        let pair = Pair {
            edge_edge: true,
            v: [0, 1, 2, 3],
        };
        let mut shift = vec![[Vector3::zeros(); 2]; 4];
        shift[3][1].y = f64::NAN;
        assert!(pair
            .relative_distance_bound(1.0, &shift, &[0.0; 4])
            .is_nan());
    }

    /// The box gap never exceeds the pair's distance, is often a large part of it for
    /// primitives apart, equals it for a point straight above a triangle in a plane `z = c`,
    /// and is 0 where a position is NaN or infinite (the distance is NaN there).
    #[test]
    fn the_box_gap_is_a_lower_bound_of_the_distance() {
        let mut rng = Rng::new(17);
        let mut tight = 0;
        for k in 0..4000 {
            let pair = Pair {
                edge_edge: k % 2 == 0,
                v: [0, 1, 2, 3],
            };
            let split = if pair.edge_edge { 2 } else { 1 };
            let offset = rng.vector() * 3.0;
            let x: Vec<_> = (0..4)
                .map(|i| rng.vector() + if i < split { offset } else { Vector3::zeros() })
                .collect();
            let (gap, d) = (
                pair.box_gap(&pair.points(&x)),
                pair.closest(&x).separation.norm(),
            );
            assert!(
                gap >= 0.0 && gap <= d + 1e-12,
                "case {k}: gap {gap}, distance {d}"
            );
            tight += usize::from(gap > 0.5 * d);
        }
        assert!(tight > 1000, "{tight}");
        let pair = Pair {
            edge_edge: false,
            v: [0, 1, 2, 3],
        };
        let mut x = vec![
            Vector3::new(0.2, 0.3, 0.7),
            Vector3::new(0.0, 0.0, 0.1),
            Vector3::new(1.0, 0.0, 0.1),
            Vector3::new(0.0, 1.0, 0.1),
        ];
        assert!((pair.box_gap(&pair.points(&x)) - 0.6).abs() < 1e-12);
        x[2].z = f64::INFINITY;
        assert_eq!(pair.box_gap(&pair.points(&x)), 0.0);
        assert!(pair.closest(&x).separation.norm().is_nan());
        x[2].z = f64::NAN;
        assert_eq!(pair.box_gap(&pair.points(&x)), 0.0);
    }

    /// Leaving out pairs by their box gap changes nothing: over every triangle pair of a soup
    /// of random triangles (one vertex NaN), the pairs found with per-pair limits are exactly
    /// those whose distance is below their limit or NaN and that pass `keep`.
    #[test]
    fn close_pairs_are_those_within_their_limit() {
        let mut rng = Rng::new(19);
        let x: Vec<_> = (0..90)
            .map(|v| {
                if v == 40 {
                    Vector3::new(f64::NAN, 0.0, 0.0)
                } else {
                    rng.vector() * 2.0
                }
            })
            .collect();
        let triangles: Vec<[u32; 3]> = (0..30).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
        let body = vec![0; triangles.len()];
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &body,
            self_contact: &[true],
        };
        let all: Vec<(u32, u32)> = (0..30)
            .flat_map(|a| (a + 1..30).map(move |b| (a, b)))
            .collect();
        let limit = |p: &Pair| 0.2 + 0.1 * f64::from(p.v[0] % 7 + p.v[3] % 3);
        let keep = |p: &Pair, d: f64| p.edge_edge || d >= 0.1 || d.is_nan();
        let found = |limit: &(dyn Fn(&Pair) -> f64 + Sync),
                     keep: &(dyn Fn(&Pair, f64) -> bool + Sync)| {
            let mut chunks = Vec::new();
            close_primitive_pairs(&mesh, None, &all, &x, limit, keep, &mut chunks);
            let mut pairs: Vec<Pair> = chunks.into_iter().flatten().map(|(p, _)| p).collect();
            pairs.sort_unstable();
            pairs
        };
        let every = found(&|_| f64::INFINITY, &|_, _| true);
        let expected: Vec<Pair> = every
            .iter()
            .copied()
            .filter(|p| {
                let d = p.closest(&x).separation.norm();
                (d < limit(p) || d.is_nan()) && keep(p, d)
            })
            .collect();
        let got = found(&limit, &keep);
        assert_eq!(got, expected);
        // Both ways out are taken: pairs beyond their box gap, pairs within their box gap but
        // beyond their distance, and pairs kept.
        let beyond_gap = every
            .iter()
            .filter(|p| p.box_gap(&p.points(&x)) >= limit(p))
            .count();
        assert!(beyond_gap > 1000 && got.len() > 1000 && beyond_gap + got.len() < every.len());
        assert!(got.iter().any(|p| p.v.contains(&40)));
    }
}
