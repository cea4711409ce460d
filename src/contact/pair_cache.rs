//! The local step's primitive pairs, kept across local steps (and time steps) in the manner of
//! a Verlet neighbour list: the broad phase and the expansion into primitive pairs run only
//! when some vertex may have left the region the lists were built for.
//!
//! A build at reference positions `r` (m) with skin `R` (m) keeps, with its distance `d_r` at
//! `r`, every primitive pair closer than `reach + 2 R` at `r` that belongs to a candidate: a
//! triangle pair (sharing no vertex) whose boxes around `r`, inflated by `R + reach / 2`,
//! overlap and one of whose 15 primitive pairs is closer than `reach + 2 R` at `r`. The second
//! test matters on fine meshes: there the padding exceeds the triangle size, and a box
//! overlaps those of dozens of triangles of the same sheet that are much farther apart.
//!
//! **What a local step looks at.** With `s` the safe positions and `y` the global step's result
//! (m), the local step (see [`super::local_step`]) evaluates pairs at its iterates `z` and runs
//! the CCD on the straight paths `s + tau (z - s)`, `tau` in `[0, 1]`. It tracks per vertex a
//! bound `E_i >= |z_i - y_i|` (m) through every place an iterate moves: `E_i = 0` at `z = y`;
//! a clamp `z_i <- s_i + t (z_i - s_i)` (`t` in `[0, 1]`, in the descent and in the final
//! pass) gives `|z_i - y_i| <= (1 - t) |y_i - s_i| + t E_i`, the new `E_i`; a descent move
//! (collider projection included) adds its length. Every such position `x` is then
//! `x_i = r_i + (1 - tau) w_i + tau g_i + e_i` with `w_i = s_i - r_i`, `g_i = y_i - r_i`,
//! `|e_i| <= E_i` and one `tau` for all vertices (the iterates: `tau = 1`). Each live list is
//! filtered for per-vertex allowances `A_i` (m) and the local step refreshes it (with larger
//! allowances) before it looks at a position where some `E_i > A_i`.
//!
//! Two consequences, both conservative:
//! - **Reuse**: `|x_i - r_i| <= b_i + A_i` with `b_i = |s_i - r_i| + |y_i - s_i|`. While
//!   `max_i (b_i + A_i) <= R`, every point of a triangle stays within `R` of where it was at
//!   `r` (its points are convex combinations of its vertices), so a primitive pair within
//!   `reach` at `x` was closer than `reach + 2 R` at `r`: its triangle pairs had overlapping
//!   inflated boxes and a primitive pair (itself) that close, so they were candidates, and it
//!   was kept. The stored pairs are a superset of the ones a fresh broad phase would find.
//! - **Skip**: the pair's distance at every such `x` is at least
//!   `d_r - max_{a in A, b in B} max(|w_a - w_b|, |g_a - g_b|) - max_A A - max_B A` (A, B the
//!   two primitives; [`Pair::relative_distance_bound`]): only the primitives' motion relative
//!   to each other counts, so a sheet falling as a whole keeps its own pairs out of the list.
//!   Where that is `>= reach` the pair feels no barrier (it acts only below `reach`), and it
//!   cannot come within the CCD's separations (`xi` and at most `eps xi`, both below
//!   `reach`), so it contributes nothing and is left out of the live list. (The additive
//!   CCD, which stops at a fraction of the initial gap, could report an early time for such a
//!   pair that never comes near: the skip removes that spurious clamp, nothing else.) The
//!   absolute bound `d_r - max_A b - max_B b - max_A A - max_B A` is never larger
//!   (`max(|w_a - w_b|, |g_a - g_b|) <= b_a + b_b`), so a pair it keeps at or above `reach` is
//!   skipped without the relative test.

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
    /// Per vertex: `b_i = |s_i - r_i| + |y_i - s_i|` (m), its motion from `reference` without
    /// the allowance.
    bound: Vec<f64>,
    /// Per vertex: `[w_i, g_i] = [s_i - r_i, y_i - r_i]` (m), its displacements from
    /// `reference` at the two ends of the global step's path.
    shift: Vec<[Vector3<f64>; 2]>,
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

    /// Writes into `live` the pairs that may come within `reach` (m) at the positions the
    /// local step looks at while each vertex `i` stays within `allowance[i]` (m) of the path
    /// from the safe positions `safe` to the global step's result `target` (the `E_i <= A_i` of
    /// the module doc); rebuilds the lists first when they may miss a pair. Returns whether it
    /// rebuilt.
    pub fn live_pairs(
        &mut self,
        safe: &[Vector3<f64>],
        target: &[Vector3<f64>],
        allowance: &[f64],
        mesh: &ContactMesh,
        reach: f64,
        live: &mut Vec<Pair>,
    ) -> bool {
        let rebuild = !self.fits(mesh, safe.len()) || {
            self.bound_motion(safe, target);
            let needed = self
                .bound
                .par_iter()
                .zip(allowance)
                .map(|(b, a)| b + a)
                .map(|v| if v.is_nan() { f64::INFINITY } else { v })
                .reduce(|| 0.0, f64::max);
            needed > self.skin
        };
        if rebuild {
            self.build(safe, target, allowance, mesh, reach);
        }
        let (bound, shift) = (&self.bound, &self.shift);
        live.clear();
        live.par_extend(
            self.pairs
                .par_iter()
                .filter(|(pair, d)| {
                    // The absolute bound first: it is cheaper, and never above the relative one.
                    let spread = pair.spread(allowance);
                    let absolute = d - pair.spread(bound) - spread;
                    if absolute >= reach {
                        return false;
                    }
                    let lower = pair.relative_distance_bound(*d, shift, allowance);
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

    /// Writes `b_i = |s_i - r_i| + |y_i - s_i|` into `bound` (NaN counts as infinitely far)
    /// and `[s_i - r_i, y_i - r_i]` into `shift`.
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
        safe.par_iter()
            .zip(target)
            .zip(reference)
            .map(|((s, y), r)| [s - r, y - r])
            .collect_into_vec(&mut self.shift);
    }

    /// Builds the lists at `r = safe`. The skin `R = 2 max_i |y_i - s_i| + max_i A_i + reach /
    /// 4` is a cost trade-off only (any `R >= max_i (b_i + A_i)` is correct): room for about
    /// one more global step's move, and a quarter reach of slow drift, before the next build; a
    /// larger skin is
    /// reused longer but keeps more pairs (all those within `reach + 2 R` on a sheet: their
    /// number grows with the square of `(reach + 2 R) / l`, `l` the edge length), each
    /// filtered at every local step.
    fn build(
        &mut self,
        safe: &[Vector3<f64>],
        target: &[Vector3<f64>],
        allowance: &[f64],
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
        self.skin = 2.0 * largest(&self.bound) + largest(allowance) + 0.25 * reach;
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
pub(super) mod tests {
    use super::super::distance::tests::Rng;
    use super::*;

    /// Brute force: every triangle pair of `mesh` that may touch, and every primitive pair
    /// they hold (whatever their distance at `positions`).
    pub(in crate::contact) fn brute_force_pairs(
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

    /// One local step's moves: the safe positions, the global step's result, per vertex the
    /// clamp factor `t_i` in `[0, 1]` (1: not clamped) and the allowance `A_i` (m), at least
    /// `(1 - t_i) |y_i - s_i|`.
    struct Moves<'a> {
        safe: &'a [Vector3<f64>],
        target: &'a [Vector3<f64>],
        clamp: &'a [f64],
        allowance: &'a [f64],
    }

    impl Moves<'_> {
        /// Checks that every pair of `every` within `reach` (m) is in `live`, at points along
        /// the paths `s + tau (z - s)` (the ends included) to iterates `z_i = s_i + t_i (y_i -
        /// s_i) + e_i`, with `|e_i|` up to what the allowance leaves, `A_i - (1 - t_i) |y_i -
        /// s_i|` (so `|z_i - y_i| <= A_i`, as the local step keeps it); returns how many were
        /// within reach.
        fn assert_live_hold_every_pair_within_reach(
            &self,
            every: &[Pair],
            live: &[Pair],
            reach: f64,
            rng: &mut Rng,
            step: usize,
        ) -> usize {
            let mut within = 0;
            let z: Vec<_> = (0..self.safe.len())
                .map(|i| {
                    let (s, y, t) = (self.safe[i], self.target[i], self.clamp[i]);
                    let slack = self.allowance[i] - (1.0 - t) * (y - s).norm();
                    assert!(slack >= 0.0, "vertex {i}: the allowance misses the clamp");
                    s + (y - s) * t + rng.vector() * (slack / 3f64.sqrt())
                })
                .collect();
            for tau in [0.0, 0.3, 0.7, 1.0] {
                let x: Vec<_> = self
                    .safe
                    .iter()
                    .zip(&z)
                    .map(|(s, z)| s + (z - s) * tau)
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
    }

    /// A rolled-up grid of `n x n` vertices (a spiral of one and a half turns, its layers
    /// `gap` (m) apart, jittered by up to 3 mm) and its triangles.
    fn spiral(n: u32, gap: f64, rng: &mut Rng) -> (Vec<Vector3<f64>>, Vec<[u32; 3]>) {
        let mut x = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let theta = 3.0 * std::f64::consts::PI * f64::from(i) / f64::from(n - 1);
                let r = 0.1 + gap * theta / (2.0 * std::f64::consts::PI);
                let (u, v) = (r * theta.cos(), r * theta.sin());
                x.push(Vector3::new(u, f64::from(j) * 0.04, v) + rng.vector() * 0.003);
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
        (x, triangles)
    }

    /// The rolled-up grid (layers a little more than the barrier's reach apart) moving over
    /// several local steps: the live pairs hold every primitive pair of non-adjacent triangles
    /// that a brute-force search finds within `reach` along the way; each build's candidates
    /// are exactly the triangle pairs with a primitive pair closer than `reach + 2 R` (brute
    /// force), at the first build fewer than three quarters of the box pairs, and its stored
    /// primitive pairs are all closer than that.
    #[test]
    fn crumpled_grid_keeps_every_pair_a_brute_force_search_finds() {
        let mut rng = Rng::new(19);
        let (mut safe, triangles) = spiral(14, 0.03, &mut rng);
        let body = vec![0; triangles.len()];
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &body,
            self_contact: &[true],
        };
        let (all, every) = brute_force_pairs(&mesh, &safe);
        let (reach, allowance) = (0.02, vec![0.002; safe.len()]);
        let clamp = vec![1.0; safe.len()];
        let mut cache = PairCache::default();
        let mut live = Vec::new();
        let mut builds = Vec::new();
        let mut within = 0;
        for (k, size) in [0.002, 0.004, 0.015, 0.002, 0.004].into_iter().enumerate() {
            let target: Vec<_> = safe.iter().map(|p| p + rng.vector() * size).collect();
            let built = cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live);
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
            let moves = Moves {
                safe: &safe,
                target: &target,
                clamp: &clamp,
                allowance: &allowance,
            };
            within +=
                moves.assert_live_hold_every_pair_within_reach(&every, &live, reach, &mut rng, k);
            safe = target;
        }
        assert!(within > 100, "the scene has pairs within reach: {within}");
        assert_eq!(builds, [true, false, true, false, false]);
    }

    /// The rolled-up grid falling fast (5 reaches per local step, each vertex jittered by up
    /// to 3 mm on top), first freely, then with every other vertex clamped back towards its
    /// safe position by its own factor: the live pairs hold every pair a brute-force search
    /// finds within `reach` on the local step's paths. Falling freely, the motion relative to
    /// each other is small, and fewer than a tenth of the cached pairs are live (the absolute
    /// motion of 0.1 m would keep every one of them); clamped, vertices lag behind their
    /// neighbours by up to 0.1 m, and more than three times as many pairs are live.
    #[test]
    fn a_falling_grid_keeps_few_pairs_live_unless_clamped() {
        let mut rng = Rng::new(23);
        let (mut safe, triangles) = spiral(12, 0.03, &mut rng);
        let body = vec![0; triangles.len()];
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &body,
            self_contact: &[true],
        };
        let (_, every) = brute_force_pairs(&mesh, &safe);
        let (reach, drift) = (0.02, 0.001);
        let fall = Vector3::new(0.0, 0.0, -0.1);
        let mut cache = PairCache::default();
        let mut live = Vec::new();
        let mut within = [0, 0];
        // The most live pairs of a free fall.
        let mut free = 0;
        for k in 0..6 {
            let clamped = k >= 3;
            let target: Vec<_> = safe
                .iter()
                .map(|p| p + fall + rng.vector() * 0.003)
                .collect();
            let clamp: Vec<f64> = (0..safe.len())
                .map(|i| {
                    if clamped && i % 2 == 0 {
                        rng.uniform().abs()
                    } else {
                        1.0
                    }
                })
                .collect();
            let allowance: Vec<f64> = (0..safe.len())
                .map(|i| (1.0 - clamp[i]) * (target[i] - safe[i]).norm() + drift)
                .collect();
            cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live);
            let cached = cache.pairs.len();
            if clamped {
                assert!(
                    live.len() > 3 * free,
                    "step {k}: {} of {cached}",
                    live.len()
                );
            } else {
                assert!(
                    live.len() < cached / 10,
                    "step {k}: {} of {cached}",
                    live.len()
                );
                free = free.max(live.len());
            }
            let moves = Moves {
                safe: &safe,
                target: &target,
                clamp: &clamp,
                allowance: &allowance,
            };
            within[usize::from(clamped)] +=
                moves.assert_live_hold_every_pair_within_reach(&every, &live, reach, &mut rng, k);
            // The next local step starts where this one ended (unclamped: the whole fall).
            safe = (0..safe.len())
                .map(|i| safe[i] + (target[i] - safe[i]) * clamp[i])
                .collect();
        }
        assert!(
            within[0] > 100 && within[1] > within[0],
            "the scene has pairs within reach: {within:?}"
        );
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
        let (reach, allowance) = (0.03, vec![0.005; safe.len()]);
        let clamp = vec![1.0; safe.len()];
        let mut cache = PairCache::default();
        let mut live = Vec::new();
        let mut builds = Vec::new();
        let mut within = 0;
        for (k, size) in [0.01, 0.005, 0.005, 0.3, 0.01].into_iter().enumerate() {
            let target: Vec<_> = safe.iter().map(|p| p + rng.vector() * size).collect();
            builds.push(cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live));
            if k < 3 {
                // Before the large move: the bounds are small, so few pairs are live.
                assert!(
                    live.len() < every.len() / 10,
                    "step {k}: {} live",
                    live.len()
                );
            }
            let moves = Moves {
                safe: &safe,
                target: &target,
                clamp: &clamp,
                allowance: &allowance,
            };
            within +=
                moves.assert_live_hold_every_pair_within_reach(&every, &live, reach, &mut rng, k);
            safe = target;
        }
        assert!(within > 100, "the scene has pairs within reach: {within}");
        assert_eq!(builds, [true, false, false, true, false]);
        // Another mesh (self-contact off) forces a build and finds nothing.
        let mesh = ContactMesh {
            self_contact: &[false],
            ..mesh
        };
        assert!(cache.live_pairs(&safe, &safe, &allowance, &mesh, reach, &mut live));
        assert!(live.is_empty() && cache.candidates() == 0);
    }
}
