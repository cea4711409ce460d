//! The local step's primitive pairs, kept across local steps (and time steps) in the manner of
//! a Verlet neighbour list: the broad phase and the expansion into primitive pairs run only
//! when some vertex may have left the region the lists were built for.
//!
//! A build at reference positions `r` (m) with skin `R` (m) keeps every primitive pair of the
//! triangle pairs whose boxes around `r`, inflated by `R + reach / 2`, overlap, together with
//! its distance `d_r` at `r`. A local step then bounds, per vertex, how far from `r` it can get:
//! `b_i = |s_i - r_i| + |y_i - s_i| + D`, with `s` the safe positions, `y` the global step's
//! result and `D` a bound on the descent's total move of any vertex (m). Why `b_i` bounds
//! `|x_i - r_i|` at every position `x` the local step looks at: `|x_i - r_i| <= |s_i - r_i| +
//! |x_i - s_i|`, and `|z_i - s_i| <= |y_i - s_i| + drift_i` holds for the iterate `z`: it holds
//! at `z = y`, a clamp `z <- s + t (z - s)` with `t` in `[0, 1]` only shrinks `|z_i - s_i|`, and
//! a descent move (collider projection included) adds at most its length, which the drift
//! counts; the points `s + t (z - s)` the CCD visits are closer to `s` still.
//!
//! Two consequences, both conservative:
//! - **Reuse**: while `max_i b_i <= R`, every triangle stays inside its box around `r`
//!   inflated by `R` (its points are convex combinations of its vertices), so two triangles
//!   closer than `reach` have boxes inflated by `R + reach / 2` that overlap: the stored pairs
//!   are a superset of the ones a fresh broad phase would find.
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
use super::primitive_pairs::{primitive_pairs, Pair};

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
    /// Candidate triangle pairs of the last build.
    candidates: usize,
    pairs: Vec<Pair>,
    /// Per pair: distance at `reference` (m).
    distance: Vec<f64>,
    /// Per vertex: `b_i - D` (m), the bound without the descent's allowance.
    bound: Vec<f64>,
}

impl PairCache {
    /// Candidate triangle pairs of the last build.
    pub fn candidates(&self) -> usize {
        self.candidates
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
                .zip(&self.distance)
                .filter(|(pair, &d)| {
                    let lower = pair.distance_bound(d, bound, allowance);
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
    /// reused longer but keeps more pairs (their number grows with the square of the padding
    /// over the triangle size), each filtered at every local step.
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
        let candidates =
            self.broad_phase
                .candidate_pairs(reference, reference, mesh, reach + 2.0 * self.skin);
        self.candidates = candidates.len();
        primitive_pairs(mesh.triangles, candidates, &mut self.pairs);
        self.pairs
            .par_iter()
            .map(|p| p.closest(reference).separation.norm())
            .collect_into_vec(&mut self.distance);
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
        let all: Vec<(u32, u32)> = (0..n as u32)
            .flat_map(|a| (a + 1..n as u32).map(move |b| (a, b)))
            .collect();
        let mut every = Vec::new();
        primitive_pairs(&triangles, &all, &mut every);
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
            for t in [0.0, 0.3, 0.7, 1.0] {
                let x: Vec<_> = safe
                    .iter()
                    .zip(&target)
                    .map(|(s, y)| s + (y - s) * t + rng.vector() * (allowance / 3f64.sqrt()))
                    .collect();
                for p in &every {
                    if p.closest(&x).separation.norm() < reach {
                        within += 1;
                        assert!(live.binary_search(p).is_ok(), "step {k}: missed {p:?}");
                    }
                }
            }
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
