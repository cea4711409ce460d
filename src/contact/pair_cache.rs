//! The local step's primitive pairs, kept across local steps (and time steps) in the manner of
//! a Verlet neighbour list: the broad phase and the expansion into primitive pairs run only
//! when some vertex may have left the region the lists were built for.
//!
//! A build at reference positions `r` (m) with skin `R` (m) keeps, with its distance `d_r` at
//! `r`, every primitive pair closer than `reach + 2 R` at `r` that belongs to a candidate: a
//! triangle pair (sharing no vertex) whose boxes around `r`, inflated by `R + reach / 2`,
//! overlap and one of whose 15 primitive pairs is closer than `reach + 2 R` at `r`. The second
//! test matters on fine meshes: there the padding exceeds the triangle size, and a box
//! overlaps those of dozens of triangles of the same sheet that are much farther apart. A local step then bounds, per vertex, how far from `r` it can get:
//! `b_i = |s_i - r_i| + |y_i - s_i| + D`, with `s` the safe positions, `y` the global step's
//! result and `D` a bound on the descent's total move of any vertex (m). Why `b_i` bounds
//! `|x_i - r_i|` at every position `x` the local step looks at: `|x_i - r_i| <= |s_i - r_i| +
//! |x_i - s_i|`, and `|z_i - s_i| <= |y_i - s_i| + drift_i` holds for the iterate `z`: it holds
//! at `z = y`, a clamp `z <- s + t (z - s)` with `t` in `[0, 1]` only shrinks `|z_i - s_i|`, and
//! a descent move (collider projection included) adds at most its length, which the drift
//! counts; the points `s + t (z - s)` the CCD visits are closer to `s` still.
//!
//! Two consequences, both conservative:
//! - **Reuse**: while `max_i b_i <= R`, every point of a triangle stays within `R` of where it
//!   was at `r` (its points are convex combinations of its vertices), so a primitive pair
//!   within `reach` at `x` was closer than `reach + 2 R` at `r`: its triangle pairs had
//!   overlapping inflated boxes and a primitive pair (itself) that close, so they were
//!   candidates, and it was kept. The stored pairs are a superset of the ones a fresh broad
//!   phase would find.
//! - **Skip**: a point of a primitive moves at most the largest `b_i` of its vertices, so at
//!   every such `x` the pair's distance is at least `d_r - max_A b - max_B b` (A, B the two
//!   primitives). Where that is `>= reach` the pair feels no barrier (it acts only below
//!   `reach`), and it cannot come within the CCD's separations (`xi` and at most `eps xi`, both
//!   below `reach`), so it contributes nothing and is left out of the live list. (The additive
//!   CCD, which stops at a fraction of the initial gap, could report an early time for such a
//!   pair that never comes near: the skip removes that spurious clamp, nothing else.)

use nalgebra::Vector3;
use rayon::prelude::*;

use super::broad_phase::{BroadPhase, ContactMesh};
use super::primitive_pairs::{close_primitive_pairs, closest_primitive_distance, Pair};

/// The primitive pairs of the last build and their distances at its reference positions.
#[derive(Default)]
pub(super) struct PairCache {
    broad_phase: BroadPhase,
    /// The topology the lists were built for (a different mesh forces a build).
    triangles: Vec<[u32; 3]>,
    body: Vec<u32>,
    self_contact: Vec<bool>,
    /// `r`: positions of the last build (m); empty before the first.
    reference: Vec<Vector3<f64>>,
    /// `R`: how far a vertex may move from `reference` before the lists must be rebuilt (m).
    skin: f64,
    /// Triangle pairs of the last build whose inflated boxes overlap.
    box_pairs: usize,
    /// Those of them with a primitive pair closer than `reach + 2 R` at `reference`: the
    /// candidates.
    candidates: Vec<(u32, u32)>,
    /// The primitive pairs of the build, each with its distance at `reference` (m).
    pairs: Vec<(Pair, f64)>,
    /// Per vertex: `b_i - D` (m), the bound without the descent's allowance.
    bound: Vec<f64>,
}

impl PairCache {
    /// Candidate triangle pairs of the last build (see the module doc).
    pub fn candidates(&self) -> usize {
        self.candidates.len()
    }

    /// Triangle pairs of the last build whose inflated boxes overlap (the candidates before
    /// the distance test).
    pub fn box_pairs(&self) -> usize {
        self.box_pairs
    }

    /// Writes into `live` the pairs that may come within `reach` (m) while the descent moves no
    /// vertex more than `allowance` (m) in total, from the safe positions `safe` and the global
    /// step's result `target` (see the module doc); rebuilds the lists first when they may miss
    /// a pair. Returns whether it rebuilt.
    pub fn live_pairs(
        &mut self,
        safe: &[Vector3<f64>],
        target: &[Vector3<f64>],
        allowance: f64,
        mesh: &ContactMesh,
        reach: f64,
        live: &mut Vec<Pair>,
    ) -> bool {
        let rebuild = !self.fits(mesh, safe.len()) || {
            self.bound_motion(safe, target);
            let needed = largest(&self.bound) + allowance;
            needed > self.skin || needed.is_nan()
        };
        if rebuild {
            self.build(safe, target, allowance, mesh, reach);
        }
        let bound = &self.bound;
        live.clear();
        live.par_extend(
            self.pairs
                .par_iter()
                .filter(|(pair, d)| {
                    let lower = pair.distance_bound(*d, bound, allowance);
                    lower < reach || lower.is_nan()
                })
                .map(|(pair, _)| *pair),
        );
        rebuild
    }

    /// Whether the lists were built for this mesh and vertex count.
    fn fits(&self, mesh: &ContactMesh, vertices: usize) -> bool {
        self.reference.len() == vertices
            && self.triangles == mesh.triangles
            && self.body == mesh.body
            && self.self_contact == mesh.self_contact
    }

    /// Writes `|s_i - r_i| + |y_i - s_i|` into `bound` (NaN counts as infinitely far).
    fn bound_motion(&mut self, safe: &[Vector3<f64>], target: &[Vector3<f64>]) {
        let reference = &self.reference;
        safe.par_iter()
            .zip(target)
            .zip(reference)
            .map(|((s, y), r)| {
                let b = (s - r).norm() + (y - s).norm();
                if b.is_nan() {
                    f64::INFINITY
                } else {
                    b
                }
            })
            .collect_into_vec(&mut self.bound);
    }

    /// Builds the lists at `r = safe`. The skin `R = 2 max_i |y_i - s_i| + D + reach / 4` is a
    /// cost trade-off only (any `R >= max_i b_i` is correct): room for about one more global
    /// step's move, and a quarter reach of slow drift, before the next build; a larger skin is
    /// reused longer but keeps more pairs (all those within `reach + 2 R` on a sheet: their
    /// number grows with the square of `(reach + 2 R) / l`, `l` the edge length), each
    /// filtered at every local step.
    fn build(
        &mut self,
        safe: &[Vector3<f64>],
        target: &[Vector3<f64>],
        allowance: f64,
        mesh: &ContactMesh,
        reach: f64,
    ) {
        self.triangles.clear();
        self.triangles.extend_from_slice(mesh.triangles);
        self.body.clear();
        self.body.extend_from_slice(mesh.body);
        self.self_contact.clear();
        self.self_contact.extend_from_slice(mesh.self_contact);
        self.reference.clear();
        self.reference.extend_from_slice(safe);
        self.bound_motion(safe, target);
        self.skin = 2.0 * largest(&self.bound) + allowance + 0.25 * reach;
        let reference = &self.reference;
        let limit = reach + 2.0 * self.skin;
        // NaN distances (NaN positions) are kept.
        let boxes = self
            .broad_phase
            .candidate_pairs(reference, reference, mesh, limit);
        self.box_pairs = boxes.len();
        self.candidates.clear();
        self.candidates
            .par_extend(boxes.par_iter().copied().filter(|&(a, b)| {
                let (ta, tb) = (&mesh.triangles[a as usize], &mesh.triangles[b as usize]);
                let d = closest_primitive_distance(reference, ta, tb);
                d < limit || d.is_nan()
            }));
        // A primitive pair `reach + 2 R` apart cannot come within `reach` before the next build.
        close_primitive_pairs(
            mesh.triangles,
            &self.candidates,
            reference,
            limit,
            &mut self.pairs,
        );
    }
}

/// The largest entry, infinite if any is NaN or infinite.
fn largest(values: &[f64]) -> f64 {
    values
        .par_iter()
        .map(|&v| if v.is_nan() { f64::INFINITY } else { v })
        .reduce(|| 0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::super::distance::tests::Rng;
    use super::*;

    /// Brute force: every triangle pair of `mesh` that may touch, and every primitive pair
    /// they hold (whatever their distance at `positions`).
    fn brute_force_pairs(
        mesh: &ContactMesh,
        positions: &[Vector3<f64>],
    ) -> (Vec<(u32, u32)>, Vec<Pair>) {
        let nt = mesh.triangles.len();
        let all: Vec<(u32, u32)> = (0..nt)
            .flat_map(|a| (a + 1..nt).map(move |b| (a, b)))
            .filter(|&(a, b)| mesh.may_touch(a, b))
            .map(|(a, b)| (a as u32, b as u32))
            .collect();
        let mut every = Vec::new();
        close_primitive_pairs(mesh.triangles, &all, positions, f64::INFINITY, &mut every);
        (all, every.into_iter().map(|(p, _)| p).collect())
    }

    /// Checks, at points along the way from `safe` to `target` each moved by up to
    /// `allowance` (m), that every pair of `every` within `reach` (m) is in `live`; returns how
    /// many were within reach.
    #[allow(clippy::too_many_arguments)]
    fn assert_live_hold_every_pair_within_reach(
        every: &[Pair],
        live: &[Pair],
        safe: &[Vector3<f64>],
        target: &[Vector3<f64>],
        allowance: f64,
        reach: f64,
        rng: &mut Rng,
        step: usize,
    ) -> usize {
        let mut within = 0;
        for t in [0.0, 0.3, 0.7, 1.0] {
            let x: Vec<_> = safe
                .iter()
                .zip(target)
                .map(|(s, y)| s + (y - s) * t + rng.vector() * (allowance / 3f64.sqrt()))
                .collect();
            for p in every {
                if p.closest(&x).separation.norm() < reach {
                    within += 1;
                    assert!(live.binary_search(p).is_ok(), "step {step}: missed {p:?}");
                }
            }
        }
        within
    }

    /// A rolled-up grid (a spiral of one and a half turns, its layers a little more than the
    /// barrier's reach apart, jittered) moving over several local steps: the live pairs hold
    /// every primitive pair of non-adjacent triangles that a brute-force search finds within
    /// `reach` along the way; each build's candidates are exactly the triangle pairs with a
    /// primitive pair closer than `reach + 2 R` (brute force), at the first build fewer than
    /// three quarters of the box pairs, and its stored primitive pairs are all closer than that.
    #[test]
    fn crumpled_grid_keeps_every_pair_a_brute_force_search_finds() {
        let mut rng = Rng::new(19);
        let n = 14u32;
        let gap = 0.03;
        let mut safe = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let theta = 3.0 * std::f64::consts::PI * f64::from(i) / f64::from(n - 1);
                let r = 0.1 + gap * theta / (2.0 * std::f64::consts::PI);
                let (u, v) = (r * theta.cos(), r * theta.sin());
                safe.push(Vector3::new(u, f64::from(j) * 0.04, v) + rng.vector() * 0.003);
            }
        }
        let mut triangles = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let v = j * n + i;
                triangles.push([v, v + 1, v + n + 1]);
                triangles.push([v, v + n + 1, v + n]);
            }
        }
        let body = vec![0; triangles.len()];
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &body,
            self_contact: &[true],
        };
        let (all, every) = brute_force_pairs(&mesh, &safe);
        let (reach, allowance) = (0.02, 0.002);
        let mut cache = PairCache::default();
        let mut live = Vec::new();
        let mut builds = Vec::new();
        let mut within = 0;
        for (k, size) in [0.002, 0.004, 0.015, 0.002, 0.004].into_iter().enumerate() {
            let target: Vec<_> = safe.iter().map(|p| p + rng.vector() * size).collect();
            let built = cache.live_pairs(&safe, &target, allowance, &mesh, reach, &mut live);
            builds.push(built);
            if built {
                let limit = reach + 2.0 * cache.skin;
                let r = &cache.reference;
                let near: Vec<_> = all
                    .iter()
                    .copied()
                    .filter(|&(a, b)| {
                        closest_primitive_distance(
                            r,
                            &triangles[a as usize],
                            &triangles[b as usize],
                        ) < limit
                    })
                    .collect();
                assert_eq!(cache.candidates, near, "step {k}");
                assert!(
                    k > 0 || 4 * cache.candidates() < 3 * cache.box_pairs(),
                    "step {k}: {} candidates of {} box pairs",
                    cache.candidates(),
                    cache.box_pairs()
                );
                assert!(cache.pairs.iter().all(|&(_, d)| d < limit));
            }
            within += assert_live_hold_every_pair_within_reach(
                &every, &live, &safe, &target, allowance, reach, &mut rng, k,
            );
            safe = target;
        }
        assert!(within > 100, "the scene has pairs within reach: {within}");
        assert_eq!(builds, [true, false, true, false, false]);
    }

    /// Over a sequence of local steps (small moves that reuse the build, a large one that
    /// forces a new build), the live pairs hold every primitive pair a fresh brute-force
    /// search finds within `reach` anywhere on the way from the safe positions to the target
    /// moved by up to the allowance, and the small moves reuse the build.
    #[test]
    fn live_pairs_hold_every_pair_that_comes_within_reach() {
        let mut rng = Rng::new(7);
        let n = 100;
        let mut safe = Vec::new();
        for _ in 0..n {
            let centre = rng.vector() * 0.6;
            safe.extend((0..3).map(|_| centre + rng.vector() * 0.08));
        }
        let triangles: Vec<[u32; 3]> = (0..n as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect();
        let body = vec![0; n];
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &body,
            self_contact: &[true],
        };
        let (all, every) = brute_force_pairs(&mesh, &safe);
        assert_eq!(
            all.len(),
            n * (n - 1) / 2,
            "a soup: every triangle pair may touch"
        );
        let (reach, allowance) = (0.03, 0.005);
        let mut cache = PairCache::default();
        let mut live = Vec::new();
        let mut builds = Vec::new();
        let mut within = 0;
        for (k, size) in [0.01, 0.005, 0.005, 0.3, 0.01].into_iter().enumerate() {
            let target: Vec<_> = safe.iter().map(|p| p + rng.vector() * size).collect();
            builds.push(cache.live_pairs(&safe, &target, allowance, &mesh, reach, &mut live));
            if k < 3 {
                // Before the large move: the bounds are small, so few pairs are live.
                assert!(
                    live.len() < every.len() / 10,
                    "step {k}: {} live",
                    live.len()
                );
            }
            within += assert_live_hold_every_pair_within_reach(
                &every, &live, &safe, &target, allowance, reach, &mut rng, k,
            );
            safe = target;
        }
        assert!(within > 100, "the scene has pairs within reach: {within}");
        assert_eq!(builds, [true, false, false, true, false]);
        // Another mesh (self-contact off) forces a build and finds nothing.
        let mesh = ContactMesh {
            self_contact: &[false],
            ..mesh
        };
        assert!(cache.live_pairs(&safe, &safe, allowance, &mesh, reach, &mut live));
        assert!(live.is_empty() && cache.candidates() == 0);
    }
}
