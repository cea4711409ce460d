//! What the last full filter of the build's cached primitive pairs (a *sweep*) saw, so that
//! the filters after it test again only the pairs whose distance bound may have fallen below
//! the barrier's reach since (see [`super::pair_cache`], "Skip"; the few pairs that repairs
//! add after a build are tested by every filter).
//!
//! A sweep at safe positions `s^0` and targets `y^0` (m) takes each near pair's distance
//! `d^0` at `s^0` and its relative distance bound ([`Pair::relative_distance_bound`])
//! `b^0 = d^0 - max_{a in A, b in B} max_sigma |u^0_a(sigma) - u^0_b(sigma)| - max_A A^0 -
//! max_B A^0`, with the ends of the path displaced from `s^0` by `u^0(0) = 0` and
//! `u^0(1) = y^0 - s^0` and `A^0` the allowances (m): measured from positions of this local
//! step, it is tight, so only the pairs that may come within reach on this step's path are
//! live. (Any lower bound of `b^0` serves as well in what follows, at the cost of more pairs
//! looked at again: a sweep records the cheaper bound from the build's distance and the moves
//! since it where that clears the reach by a margin, see `pair_cache/filter.rs`.)
//!
//! A later filter sees safe positions `s` and targets `y`, ends `u(0) = s - s^0` and
//! `u(1) = y - s^0`, and allowances `A`. For either new end `tau` and any old end `sigma`
//! (one for all vertices), with `delta_i = u_i(tau) - u^0_i(sigma)` and `m_B` its mean over
//! body `B`, the triangle inequality gives `|u_a(tau) - u_b(tau)|` at most
//! `|u^0_a(sigma) - u^0_b(sigma)|` plus `|delta_a - m_A| + |delta_b - m_B| + |m_A - m_B|`
//! (the last term 0 within a body), and each `max A` grows by at most `max_i (A_i - A^0_i)^+`.
//! So every bound has fallen by at most `F = max_tau min_sigma (2 max_i |delta_i - m_B| +
//! max_{A, B} |m_A - m_B|) + 2 max_i (A_i - A^0_i)^+` ([`Sweep::fall`]), and a pair whose
//! bound was at least `reach + F` at the sweep is still at least `reach`: it stays out of the
//! live list without a look. Where it was not, the same bound per pair
//! ([`Sweep::pair_fall`], over the pair's own vertices only, with `sigma` chosen per pair and
//! the pair's own allowance growth) costs a few vector differences and usually keeps it out;
//! the rest are looked at as a sweep would, from their distance at `s`.
//!
//! A third bound, per pair of patches ([`super::patches`], [`Sweep::patch_fall`]), costs two
//! lookups: with `P` and `Q` the patches whose halos hold the sides A and B, and
//! `m`, `rho` the patches' centres and radii of `delta` for each `tau` and `sigma`, the pair's
//! fall is at most `max_tau min_sigma (rho_P + |m_P - m_Q| + rho_Q) + g_P + g_Q`, with `g`
//! the largest allowance growth over a halo. Where a body bends or folds as a whole, every
//! vertex strays from the body's mean by millimetres and `F` keeps few pairs out; the
//! patches, a few centimetres across, stray much less from their own centres. None of the
//! three bounds dominates another (a halo's radius may reach twice the largest stray from
//! the body's mean, and `F` chooses `sigma` once for all pairs), so a filter takes the
//! cheapest first and looks at a pair only when all three let it through.
//!
//! The choice of `sigma` matters: the local step after a sweep starts where the sweep's path
//! ended (`s ~ y^0`), which the old end `sigma = 1` sees as no move at all. Only the common
//! part of a move is free otherwise: a body falling as a whole keeps `F` small, a skirt
//! swinging down costs its swing relative to the body's mean.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::patches::Patches;
use super::primitive_pairs::Pair;
use crate::geometry::bounds::nan_max;

/// Per body: the mean `[c_B^w, c_B^g]` of its vertices' displacements (m), `None` for a body
/// without triangles.
type CommonMotion = Vec<Option<[Vector3<f64>; 2]>>;

/// The body of a vertex that belongs to no triangle.
pub(super) const NO_BODY: u32 = u32::MAX;

/// The state of the last sweep of a build.
#[derive(Default)]
pub(super) struct Sweep {
    /// Whether a sweep of the current build is recorded and may still be used.
    pub valid: bool,
    /// `s^0` (m).
    safe: Vec<Vector3<f64>>,
    /// Per vertex: `y^0 - s^0`, the sweep's path (m).
    step: Vec<Vector3<f64>>,
    /// Per vertex: the allowance at the sweep (m).
    allowance: Vec<f64>,
    /// The sweep looked at the cached pairs `..near`.
    pub near: usize,
    /// How many of them it found within reach (a negative slack).
    pub within: usize,
    /// The work of the filters since the sweep, in fresh bounds (see
    /// [`super::pair_cache`]'s `refilter`): once it exceeds what a sweep costs, the next
    /// filter sweeps.
    pub rent: f64,
    /// Per cached pair `..near`: what the sweep saw of it.
    pub swept: Vec<SweptPair>,
    /// Per vertex: the ends `[u(0), u(1)]` of the last [`Sweep::measure`] (m).
    pub ends: Vec<[Vector3<f64>; 2]>,
    /// The safe positions `s` of the last [`Sweep::measure`] (m).
    pub safe_now: Vec<Vector3<f64>>,
    /// Per vertex: `[0, y - s]`, the ends of the last measured path displaced from its start
    /// (m): with the distances at `s`, the relative distance bound of a fresh sweep.
    pub path: Vec<[Vector3<f64>; 2]>,
    /// Per patch: the motion of the last [`Sweep::measure_patches`].
    patch_motion: Vec<PatchMotion>,
}

/// What a sweep keeps of a near pair: the filters after it read only this (and the patches
/// of its sides, see `pair_cache/patch_groups.rs`) until a bound says they must look at the
/// pair itself.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct SweptPair {
    /// `b^0 - reach` rounded down to `f32` (m), NaN where `b^0` is.
    pub slack: f32,
}

/// How the vertices of a patch's halo moved since the sweep (see [`Sweep::measure_patches`]).
#[derive(Clone, Copy, Default)]
struct PatchMotion {
    /// `[tau][sigma]`: the centre `m` (m) and radius `rho` (m) of `delta = u(tau) -
    /// u^0(sigma)` over the halo.
    centre: [[Vector3<f64>; 2]; 2],
    radius: [[f64; 2]; 2],
    /// `g`: the largest allowance growth `(A_i - A^0_i)^+` over the halo (m).
    growth: f64,
}

impl Sweep {
    /// Starts a sweep at the safe positions `safe`, targets `target` and allowances
    /// `allowance` (m) over the cached pairs `..near`, and measures its path; the caller then
    /// writes [`Sweep::swept`].
    pub fn record(
        &mut self,
        safe: &[Vector3<f64>],
        target: &[Vector3<f64>],
        allowance: &[f64],
        near: usize,
    ) {
        self.safe.clear();
        self.safe.extend_from_slice(safe);
        safe.par_iter()
            .zip(target)
            .map(|(s, y)| y - s)
            .collect_into_vec(&mut self.step);
        self.allowance.clear();
        self.allowance.extend_from_slice(allowance);
        self.near = near;
        self.rent = 0.0;
        self.valid = true;
        self.measure(safe, target);
    }

    /// Measures the path from `safe` to `target` (m): writes [`Sweep::ends`],
    /// [`Sweep::safe_now`] and [`Sweep::path`].
    pub fn measure(&mut self, safe: &[Vector3<f64>], target: &[Vector3<f64>]) {
        displacements(safe, target, &self.safe, &mut self.ends);
        safe.par_iter()
            .zip(target)
            .map(|(s, y)| [Vector3::zeros(), y - s])
            .collect_into_vec(&mut self.path);
        self.safe_now.clear();
        self.safe_now.extend_from_slice(safe);
    }

    /// `F` of the module doc (m) for the ends last measured, the vertices' bodies
    /// `vertex_body` ([`NO_BODY`] for a vertex of no triangle, which is in no pair) of
    /// `bodies`, and the allowances `allowance` (m). `None` without a valid sweep or where a
    /// figure is NaN.
    pub fn fall(&self, vertex_body: &[u32], bodies: usize, allowance: &[f64]) -> Option<f64> {
        if !self.valid || self.ends.len() != self.safe.len() {
            return None;
        }
        let mut fall: f64 = 0.0;
        for tau in 0..2 {
            let mut least = f64::INFINITY;
            for sigma in 0..2 {
                let delta = |i: usize| self.delta(i, tau, sigma);
                let mean = body_means(vertex_body, bodies, delta);
                let strayed = (0..vertex_body.len())
                    .into_par_iter()
                    .map(|i| match vertex_body[i] {
                        NO_BODY => 0.0,
                        b => (delta(i) - mean[b as usize].unwrap_or_default()).norm(),
                    })
                    .reduce(|| 0.0, nan_max);
                let apart = largest_apart(&mean.iter().map(|m| m.map(|m| [m, m])).collect());
                least = least.min(2.0 * strayed + apart);
                if strayed.is_nan() || apart.is_nan() {
                    return None;
                }
            }
            fall = fall.max(least);
        }
        let grown = allowance
            .par_iter()
            .zip(&self.allowance)
            .map(|(a, a0)| nan_max(0.0, a - a0))
            .reduce(|| 0.0, nan_max);
        let fall = fall + 2.0 * grown;
        (!fall.is_nan()).then_some(fall)
    }
}

impl Sweep {
    /// `delta_i = u_i(tau) - u^0_i(sigma)` (m) for the ends last measured.
    fn delta(&self, i: usize, tau: usize, sigma: usize) -> Vector3<f64> {
        let end = self.ends[i][tau];
        if sigma == 0 {
            end
        } else {
            end - self.step[i]
        }
    }

    /// Measures every patch of `patches` (of the sweep's mesh) for the ends last measured and
    /// the allowances `allowance` (m), for [`Sweep::patch_fall`].
    pub fn measure_patches(&mut self, patches: &Patches, allowance: &[f64]) {
        let mut patch_motion = std::mem::take(&mut self.patch_motion);
        let this = &*self;
        (0..patches.count())
            .into_par_iter()
            .map(|p| {
                let mut motion = PatchMotion::default();
                for tau in 0..2 {
                    for sigma in 0..2 {
                        let (m, rho) = patches.centre_and_radius(p, |i| this.delta(i, tau, sigma));
                        motion.centre[tau][sigma] = m;
                        motion.radius[tau][sigma] = rho;
                    }
                }
                motion.growth = patches.halo(p).iter().fold(0.0, |g, &i| {
                    let i = i as usize;
                    nan_max(g, nan_max(0.0, allowance[i] - this.allowance[i]))
                });
                motion
            })
            .collect_into_vec(&mut patch_motion);
        self.patch_motion = patch_motion;
    }

    /// A bound (m) on [`Sweep::pair_fall`] from the patches `[P, Q]` of the pair's sides
    /// (module doc), as measured by the last [`Sweep::measure_patches`]: two lookups where the
    /// pair's own fall takes its vertices' ends. NaN where an input is.
    pub fn patch_fall(&self, [p, q]: [u32; 2]) -> f64 {
        let p = &self.patch_motion[p as usize];
        let q = &self.patch_motion[q as usize];
        let mut fall: f64 = 0.0;
        for tau in 0..2 {
            let mut least = f64::INFINITY;
            for sigma in 0..2 {
                let apart = p.radius[tau][sigma]
                    + (p.centre[tau][sigma] - q.centre[tau][sigma]).norm()
                    + q.radius[tau][sigma];
                if apart.is_nan() {
                    return f64::NAN;
                }
                least = least.min(apart);
            }
            fall = fall.max(least);
        }
        fall + p.growth + q.growth
    }

    /// The fall of one pair's bound since the sweep (m): `f = max_tau min_sigma max_{a in A,
    /// b in B} |delta_a - delta_b| + spread(A) - spread(A^0)` (module doc; `spread` the sum of
    /// the two primitives' largest allowances), at most [`Sweep::fall`] and usually much less:
    /// neighbours move alike. NaN where an input is.
    pub fn pair_fall(&self, pair: &Pair, allowance: &[f64]) -> f64 {
        let (a, b) = pair.sides();
        let mut fall: f64 = 0.0;
        for tau in 0..2 {
            let mut least = f64::INFINITY;
            for sigma in 0..2 {
                let mut largest = 0.0;
                for &i in a {
                    for &j in b {
                        let apart =
                            self.delta(i as usize, tau, sigma) - self.delta(j as usize, tau, sigma);
                        largest = nan_max(largest, apart.norm_squared());
                    }
                }
                if largest.is_nan() {
                    return f64::NAN;
                }
                least = least.min(largest);
            }
            fall = fall.max(least);
        }
        fall.sqrt() + pair.spread(allowance) - pair.spread(&self.allowance)
    }
}

/// Writes into `ends` the displacements `[s_i - o_i, y_i - o_i]` (m) of the safe positions
/// `safe` and targets `target` from the origins `origin`.
pub(super) fn displacements(
    safe: &[Vector3<f64>],
    target: &[Vector3<f64>],
    origin: &[Vector3<f64>],
    ends: &mut Vec<[Vector3<f64>; 2]>,
) {
    safe.par_iter()
        .zip(target)
        .zip(origin)
        .map(|((s, y), o)| [s - o, y - o])
        .collect_into_vec(ends);
}

/// Per body of `bodies`: the mean of `value(i)` over its vertices (`vertex_body`), `None`
/// for a body without vertices. The sums run over fixed chunks in a fixed order, so the
/// result does not depend on the thread count or scheduling.
fn body_means(
    vertex_body: &[u32],
    bodies: usize,
    value: impl Fn(usize) -> Vector3<f64> + Sync,
) -> Vec<Option<Vector3<f64>>> {
    const CHUNK: usize = 4096;
    let partial: Vec<Vec<(Vector3<f64>, usize)>> = vertex_body
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(c, chunk)| {
            let mut sums = vec![(Vector3::zeros(), 0usize); bodies];
            for (k, &b) in chunk.iter().enumerate() {
                if let Some((sum, n)) = sums.get_mut(b as usize) {
                    *sum += value(c * CHUNK + k);
                    *n += 1;
                }
            }
            sums
        })
        .collect();
    let mut total = vec![(Vector3::zeros(), 0usize); bodies];
    for sums in partial {
        for ((sum, n), (other, m)) in total.iter_mut().zip(sums) {
            *sum += other;
            *n += m;
        }
    }
    total
        .into_iter()
        .map(|(sum, n)| (n > 0).then(|| sum / n as f64))
        .collect()
}

/// `max_{A, B} max(|c_A^w - c_B^w|, |c_A^g - c_B^g|)` over pairs of bodies with triangles (0
/// for fewer than two), NaN if a motion is.
fn largest_apart(common: &CommonMotion) -> f64 {
    let common: Vec<_> = common.iter().flatten().collect();
    let mut apart = 0.0;
    for (k, a) in common.iter().enumerate() {
        for b in &common[k + 1..] {
            for (p, q) in a.iter().zip(*b) {
                apart = nan_max(apart, (p - q).norm());
            }
        }
    }
    apart
}

#[cfg(test)]
mod tests {
    use super::super::test_meshes::spiral;
    use super::*;
    use crate::geometry::distance::tests::Rng;

    /// Random sweeps and later paths over two bodies: no pair's relative distance bound falls
    /// by more than its own [`Sweep::pair_fall`], which is at most [`Sweep::fall`]; a common
    /// motion of each body costs only the bodies' motion relative to each other, and a path
    /// that starts where the sweep's ended costs only its own move.
    #[test]
    fn no_bound_falls_by_more_than_the_fall() {
        let mut rng = Rng::new(5);
        let n = 40;
        let vertex_body: Vec<u32> = (0..n).map(|i| u32::from(i >= 20)).collect();
        let mut checked = 0;
        for round in 0..300 {
            let safe0: Vec<_> = (0..n).map(|_| rng.vector()).collect();
            let target0: Vec<_> = safe0.iter().map(|s| s + rng.vector() * 0.3).collect();
            let a0: Vec<f64> = (0..n).map(|_| rng.vector().x.abs() * 0.1).collect();
            let mut sweep = Sweep::default();
            sweep.record(&safe0, &target0, &a0, 0);
            let ends0 = sweep.ends.clone();
            // Round kinds: 0 a common motion per body, 1 the next local step (starts at
            // the sweep's targets), 2 anything.
            let kind = round % 3;
            let common = [rng.vector() * 3.0, rng.vector() * 3.0];
            let small = 0.01;
            let (safe, target): (Vec<_>, Vec<_>) = (0..n)
                .map(|i| {
                    let c = common[vertex_body[i] as usize];
                    match kind {
                        0 => (safe0[i] + c, target0[i] + c),
                        1 => (target0[i], target0[i] + rng.vector() * small),
                        _ => (
                            safe0[i] + rng.vector() * 0.2,
                            target0[i] + rng.vector() * 0.2,
                        ),
                    }
                })
                .unzip();
            let a1: Vec<f64> = a0
                .iter()
                .map(|a| a + if kind == 2 { rng.vector().x * 0.1 } else { 0.0 })
                .collect();
            sweep.measure(&safe, &target);
            let fall = sweep.fall(&vertex_body, 2, &a1).expect("finite");
            match kind {
                0 => {
                    let apart = (common[0] - common[1]).norm();
                    assert!(fall <= apart + 1e-9, "{fall} against {apart}");
                }
                1 => assert!(fall <= 4.0 * small, "{fall}"),
                _ => {}
            }
            for _ in 0..50 {
                let v = [0; 4].map(|_| (rng.vector().x.abs() * 1e6) as u32 % n as u32);
                let pair = Pair {
                    edge_edge: round % 2 == 0,
                    v,
                };
                let then = pair.relative_distance_bound(1.0, &ends0, &a0);
                let now = pair.relative_distance_bound(1.0, &sweep.ends, &a1);
                let own = sweep.pair_fall(&pair, &a1);
                assert!(then - now <= own + 1e-12, "{then} -> {now}, its fall {own}");
                assert!(own <= fall + 1e-12, "{own} against {fall}");
                checked += 1;
            }
        }
        assert_eq!(checked, 15_000);
        assert_eq!(Sweep::default().fall(&[], 0, &[]), None);
    }

    /// Two vertices of a point-triangle pair stray in opposite directions and both their
    /// allowances grow: the pair's bound falls by exactly [`Sweep::fall`] (both factors 2
    /// are needed).
    #[test]
    fn the_fall_is_reached_by_opposite_strays() {
        let n = 8;
        let rest = vec![Vector3::zeros(); n];
        let mut sweep = Sweep::default();
        sweep.record(&rest, &rest, &vec![0.0; n], 0);
        let ends0 = sweep.ends.clone();
        let (s, grow) = (0.01, 0.003);
        let mut target = rest.clone();
        target[0] = Vector3::new(s, 0.0, 0.0);
        target[1] = Vector3::new(-s, 0.0, 0.0);
        let mut allowance = vec![0.0; n];
        allowance[0] = grow;
        allowance[1] = grow;
        sweep.measure(&rest, &target);
        let fall = sweep.fall(&vec![0; n], 1, &allowance).expect("finite");
        let pair = Pair {
            edge_edge: false,
            v: [0, 1, 2, 3],
        };
        let then = pair.relative_distance_bound(1.0, &ends0, &vec![0.0; n]);
        let now = pair.relative_distance_bound(1.0, &sweep.ends, &allowance);
        assert!(
            ((then - now) - fall).abs() < 1e-12,
            "{then} -> {now}, fall {fall}"
        );
        let own = sweep.pair_fall(&pair, &allowance);
        assert!((own - fall).abs() < 1e-12, "{own} against {fall}");
        assert!((fall - (2.0 * s + 2.0 * grow)).abs() < 1e-12, "{fall}");
    }

    /// A rolled sheet bends (each vertex moved by a smooth field, plus jitter) and its
    /// allowances grow, or stays put while only they grow: for random vertex-triangle and
    /// edge-edge pairs of its mesh, the pair's own fall is at most [`Sweep::patch_fall`],
    /// which for most pairs of nearby triangles is less than a quarter of [`Sweep::fall`] (no
    /// bound dominates the other in general: the module doc).
    #[test]
    fn the_patch_fall_bounds_each_pair_fall() {
        let mut rng = Rng::new(12);
        let (safe0, triangles) = spiral(60, 0.01, &mut rng);
        let n = safe0.len();
        let patches = Patches::new(&triangles, n);
        let bend = |x: &Vector3<f64>, k: f64| Vector3::new(k * x.y * x.y, k * x.x * x.y, -k * x.x);
        let vertex_body = vec![0; n];
        let mut tighter = 0;
        for round in 0..25 {
            // The last rounds: no motion at all, only the allowances grow.
            let curl = if round < 20 {
                0.05 * f64::from(round + 1)
            } else {
                0.0
            };
            let target0: Vec<_> = safe0.iter().map(|s| s + bend(s, curl)).collect();
            let a0: Vec<f64> = (0..n).map(|_| rng.vector().x.abs() * 1e-4).collect();
            let mut sweep = Sweep::default();
            sweep.record(&safe0, &target0, &a0, 0);
            let jitter = if round % 2 == 0 && curl > 0.0 {
                1e-4
            } else {
                0.0
            };
            let (safe, target): (Vec<_>, Vec<_>) = (0..n)
                .map(|i| {
                    let s = target0[i] + rng.vector() * jitter;
                    (s, s + bend(&s, -0.5 * curl) + rng.vector() * jitter)
                })
                .unzip();
            let grow = if curl > 0.0 { 1e-4 } else { 1e-3 };
            let a1: Vec<f64> = a0.iter().map(|a| a + rng.vector().x.abs() * grow).collect();
            sweep.measure(&safe, &target);
            sweep.measure_patches(&patches, &a1);
            let fall = sweep.fall(&vertex_body, 1, &a1).expect("finite");
            for _ in 0..200 {
                // Two triangles a few triangles apart in the grid (the pairs a build keeps).
                let k = (rng.vector().x.abs() * 1e6) as usize % (triangles.len() - 20);
                let (s, t) = (triangles[k], triangles[k + 4 + k % 16]);
                let edge_edge = rng.vector().x > 0.0;
                let v = if edge_edge {
                    [s[0], s[1], t[1], t[2]]
                } else {
                    [s[2], t[0], t[1], t[2]]
                };
                let pair = Pair { edge_edge, v };
                let (a, b) = pair.sides();
                let own = sweep.pair_fall(&pair, &a1);
                let bound = sweep.patch_fall([a, b].map(|side| patches.of_side(side) as u32));
                assert!(own <= bound + 1e-12, "{own} against its patches' {bound}");
                tighter += usize::from(curl > 0.0 && bound < 0.25 * fall);
            }
        }
        assert!(tighter > 3000, "{tighter} of 4000 pairs");
    }
}
