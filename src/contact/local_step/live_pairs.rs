//! The live pairs of a local step: the cached primitive pairs that may come within the
//! barrier's reach while every vertex stays within its allowance (see
//! [`super::super::pair_cache`]), refreshed when a vertex outgrows it.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::super::broad_phase::ContactMesh;
use super::super::pair_cache::{PairCache, Renewal};
use super::super::primitive_pairs::Pair;
use super::refill;
use super::rest_gaps::RestGaps;
use super::stats::ContactStats;

/// The first allowance `A_i` of every vertex (see [`super::super::pair_cache`]), in descent
/// moves of `eps xi`: the live pairs cover iterates within it of the global step's result,
/// and are refreshed (the allowance raised by the deviation) when a vertex goes further. A
/// cost trade-off only: two primitives that keep their places relative to each other stay
/// out of the live list while their distance exceeds the reach by twice the allowance (a
/// flat sheet's own pairs lie a few moves of `eps xi` beyond the reach), and a vertex the
/// descent moves `k` times brings about `log2 k` refreshes.
pub(super) const FIRST_ALLOWANCE: f64 = 1.0;

/// The allowance a vertex starts a local step with, in deviations it reached in the last one
/// (see [`LivePairs::start`]). A cost trade-off only: with 1, a vertex whose deviation keeps
/// growing from one local step to the next (cloth folding on the floor) refreshes the live
/// list in each of them; 2 leaves it room to grow.
const CARRIED_DEVIATION: f64 = 2.0;

/// The largest shift of a vertex's safe position or target since the last filter, as a share
/// of its allowance, with which a local step keeps the live pairs as they are (see
/// [`LivePairs::start`]): the rest of the allowance is room for its own moves.
const REUSE_SHIFT: f64 = 0.5;

/// The largest share of the vertices that may shift by more than [`REUSE_SHIFT`] of their
/// allowance for a local step to keep the live pairs, adding those vertices' pairs: in the
/// late global iterations of a step a few vertices still shift while the rest are settled,
/// and with no room for strays they would stop the reuse.
const REUSE_STRAYS: f64 = 0.01;

/// The live pairs of a local step and the motion they cover (see [`super::super::pair_cache`]).
#[derive(Default)]
pub(super) struct LivePairs {
    pub(super) cache: PairCache,
    /// The pairs that may come within the barrier's reach.
    pub(super) pairs: Vec<Pair>,
    /// Per pair: distance at the safe positions `z^{k-1}` (m).
    pub(super) start: Vec<f64>,
    /// Per pair: its fade at the safe positions, held through the local step (1, or a nearly
    /// parallel edge-edge pair's, see [`super::super::parallel_fade`]).
    pub(super) fade: Vec<f64>,
    /// Per pair: the scale `s` of its barrier from its rest gap (see [`RestGaps`]); empty
    /// where no pair has one (every scale 1).
    pub(super) scale: Vec<f64>,
    /// The rest gaps of the pairs that started within the barrier's reach.
    pub(super) gaps: RestGaps,
    /// `sin^2` of the fade angle the fades are for.
    pub(super) sin2_limit: f64,
    /// Per vertex: the allowance `A_i` (m) the pairs were filtered for, around the path
    /// between `filtered_safe` and `filtered_target`.
    pub(super) allowance: Vec<f64>,
    /// The safe positions and the global step's result (m) the pairs were filtered for.
    pub(super) filtered_safe: Vec<Vector3<f64>>,
    pub(super) filtered_target: Vec<Vector3<f64>>,
    /// Per vertex: `max(|s_i - s_i^f|, |y_i - y_i^f|)` (m), how far this local step's safe
    /// position and target are from those the pairs were filtered for (0 after a filter).
    pub(super) shift: Vec<f64>,
    /// Per vertex: `E_i >= |z_i - y_i^k|` (m) at the current iterate `z`: 0 at `z = y^k`, a
    /// clamp to `z^{k-1} + t (z - z^{k-1})` makes it `(1 - t) |y_i^k - z_i^{k-1}| + t E_i`, a
    /// descent move adds its length.
    pub(super) deviation: Vec<f64>,
    /// The vertices whose allowance the last [`LivePairs::cover`] raised.
    pub(super) grown: Vec<u32>,
    /// Counts the changes to `pairs`: a list with the same version is the same list.
    pub(super) version: u64,
}

impl LivePairs {
    /// Starts a local step from the safe positions `safe` towards `target` (m): no deviation
    /// for every vertex, an allowance of at least `allowance` (m), and the pairs for them.
    ///
    /// A vertex starts with room for [`CARRIED_DEVIATION`] times the deviation it reached in
    /// the last local step (of the same vertex count): consecutive local steps of a step, and
    /// of neighbouring steps, need about the same, and at an impact a vertex held back by
    /// centimetres would otherwise refresh the list several times in every local step. A cost
    /// trade-off only: the pairs are correct for any allowance, as [`LivePairs::cover`]
    /// checks the deviations against them.
    ///
    /// **Reuse.** Where the mesh and the barrier's reach are the ones filtered for, the pairs
    /// are kept unless more than
    /// [`REUSE_STRAYS`] of the vertices have a safe position or target that moved by more
    /// than [`REUSE_SHIFT`] of their allowance since the last filter (`shift_i`); those few
    /// get their allowance raised by their shift and their pairs added
    /// ([`PairCache::extend_live`]), and the distances and fades at `safe` are measured again. A
    /// position this local step looks at, `(1 - tau) s_i + tau y_i + e_i` with
    /// `|e_i| <= E_i`, is `(1 - tau) s_i^f + tau y_i^f + e'_i` with
    /// `e'_i = (1 - tau) (s_i - s_i^f) + tau (y_i - y_i^f) + e_i`, so `|e'_i| <= shift_i + E_i`:
    /// the pairs cover it while `E_i + shift_i <= A_i`, which [`LivePairs::cover`] checks. The
    /// late global iterations of a step move the vertices by micrometres, against allowances
    /// of `eps xi`: their local steps then skip the filter.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn start(
        &mut self,
        safe: &[Vector3<f64>],
        target: &[Vector3<f64>],
        allowance: f64,
        mesh: &ContactMesh,
        reach: f64,
        sin2_limit: f64,
        stats: &mut ContactStats,
    ) {
        let n = safe.len();
        self.sin2_limit = sin2_limit;
        let reused = (self.filtered_safe.len() == n && self.cache.fits(mesh, n, reach))
            .then(|| self.reuse(safe, target, mesh, reach))
            .flatten();
        if let Some(renewal) = reused {
            refill(&mut self.deviation, n, 0.0);
            self.measure(0, safe);
            if self.grown.is_empty() {
                self.count(stats);
            } else {
                self.refreshed(renewal, self.pairs.len(), safe, stats);
            }
            return;
        }
        if self.deviation.len() == n {
            self.allowance.clear();
            self.allowance
                .par_extend(self.deviation.par_iter().map(|&e| {
                    if e.is_finite() {
                        (CARRIED_DEVIATION * e).max(allowance)
                    } else {
                        allowance
                    }
                }));
        } else {
            refill(&mut self.allowance, n, allowance);
        }
        refill(&mut self.deviation, n, 0.0);
        self.filter(safe, target, mesh, reach, stats);
    }

    /// The reuse test of [`LivePairs::start`]: measures the shifts and, where few vertices
    /// stray, raises their allowances and adds their pairs (they are left in `grown`).
    /// Returns, where the pairs are kept, what the extension did to the cached pairs.
    fn reuse(
        &mut self,
        safe: &[Vector3<f64>],
        target: &[Vector3<f64>],
        mesh: &ContactMesh,
        reach: f64,
    ) -> Option<Renewal> {
        self.shift.clear();
        self.shift.par_extend(
            safe.par_iter()
                .zip(target)
                .zip(self.filtered_safe.par_iter().zip(&self.filtered_target))
                .map(|((s, y), (sf, yf))| (s - sf).norm().max((y - yf).norm())),
        );
        self.grown.clear();
        self.grown.par_extend(
            self.shift
                .par_iter()
                .zip(&self.allowance)
                .enumerate()
                .filter_map(|(i, (&shift, &a))| {
                    let finite = shift.is_finite() && a.is_finite();
                    (!finite || shift > REUSE_SHIFT * a).then_some(i as u32)
                }),
        );
        if self.grown.len() as f64 > REUSE_STRAYS * safe.len() as f64 {
            return None;
        }
        if self.grown.is_empty() {
            return Some(Renewal::Kept);
        }
        for &i in &self.grown {
            let (shift, a) = (self.shift[i as usize], &mut self.allowance[i as usize]);
            if !(shift.is_finite() && a.is_finite()) {
                return None;
            }
            *a += shift;
        }
        self.cache
            .extend_live(&self.allowance, &self.grown, mesh, reach, &mut self.pairs)
    }

    /// Filters the pairs afresh for the allowances, around the path from `safe` to `target`
    /// ([`PairCache::live_pairs`]), and measures their distances and fades at `safe`.
    pub(super) fn filter(
        &mut self,
        safe: &[Vector3<f64>],
        target: &[Vector3<f64>],
        mesh: &ContactMesh,
        reach: f64,
        stats: &mut ContactStats,
    ) {
        let (cache, live) = (&mut self.cache, &mut self.pairs);
        let sweeps = cache.sweeps();
        let renewal = cache.live_pairs(safe, target, &self.allowance, mesh, reach, live);
        stats.sweeps += cache.sweeps() - sweeps;
        self.filtered_safe.clear();
        self.filtered_safe.extend_from_slice(safe);
        self.filtered_target.clear();
        self.filtered_target.extend_from_slice(target);
        refill(&mut self.shift, safe.len(), 0.0);
        self.refreshed(renewal, 0, safe, stats);
    }

    /// Where a vertex's deviation `E_i`, plus its shift since the filter, exceeds its
    /// allowance `A_i` (or is NaN), raises the allowance to `A_i + E_i + shift_i` (room for
    /// the deviation and as much drift again as the old allowance gave: it doubles under a
    /// steady drift, and a clamp's jump is not doubled) and refreshes the pairs (before
    /// anything looks at the positions they may not cover): adds those of the grown vertices
    /// ([`PairCache::extend_live`]), or filters afresh. Returns, where it refreshed, how many
    /// of the pairs before it are still in their places at its head (all of them after an
    /// extension, none after a filter).
    pub(super) fn cover(
        &mut self,
        safe: &[Vector3<f64>],
        target: &[Vector3<f64>],
        mesh: &ContactMesh,
        reach: f64,
        stats: &mut ContactStats,
    ) -> Option<usize> {
        debug_assert_eq!(self.shift.len(), self.allowance.len());
        self.grown.clear();
        // Called after every clamp and descent pass, and nearly always nothing has grown: a
        // test that collects nothing first.
        let beyond = |(&a, &e, &shift): (&f64, &f64, &f64)| e.is_nan() || e + shift > a;
        if !(
            self.allowance.par_iter(),
            self.deviation.par_iter(),
            self.shift.par_iter(),
        )
            .into_par_iter()
            .any(beyond)
        {
            return None;
        }
        self.grown.par_extend(
            self.allowance
                .par_iter_mut()
                .zip(&self.deviation)
                .zip(&self.shift)
                .enumerate()
                .filter_map(|(i, ((a, &e), &shift))| {
                    let beyond = e.is_nan() || e + shift > *a;
                    if beyond {
                        *a += e + shift;
                    }
                    beyond.then_some(i as u32)
                }),
        );
        if self.grown.is_empty() {
            return None;
        }
        let (cache, live) = (&mut self.cache, &mut self.pairs);
        let kept = live.len();
        if let Some(renewal) = cache.extend_live(&self.allowance, &self.grown, mesh, reach, live) {
            self.refreshed(renewal, kept, safe, stats);
            Some(kept)
        } else {
            self.filter(safe, target, mesh, reach, stats);
            Some(0)
        }
    }

    /// Counts a refresh of the live pairs (and what it did to the cached pairs) in `stats`
    /// and measures the pairs from `new` on at the safe positions (those before it were live
    /// before the refresh, at the same safe positions: an extension keeps them in place).
    fn refreshed(
        &mut self,
        renewal: Renewal,
        new: usize,
        safe: &[Vector3<f64>],
        stats: &mut ContactStats,
    ) {
        stats.broad_phase_builds += usize::from(renewal == Renewal::Built);
        stats.cache_repairs += usize::from(renewal == Renewal::Repaired);
        stats.live_refreshes += 1;
        self.version += 1;
        self.count(stats);
        self.measure(new, safe);
    }

    /// Writes the distance and the fade at the safe positions of the pairs from `new` on,
    /// keeping those before it (one pass over the pairs' points for both).
    fn measure(&mut self, new: usize, safe: &[Vector3<f64>]) {
        self.start.truncate(new);
        self.fade.truncate(new);
        let sin2_limit = self.sin2_limit;
        let mut measured = (
            std::mem::take(&mut self.start),
            std::mem::take(&mut self.fade),
        );
        measured.par_extend(
            self.pairs[new..]
                .par_iter()
                .map(|p| p.distance_and_fade(safe, sin2_limit)),
        );
        (self.start, self.fade) = measured;
        self.rescale(new);
    }

    /// Writes the barrier scales of the pairs from `new` on from their rest gaps, keeping
    /// those before it (none where no pair has a rest gap).
    pub(super) fn rescale(&mut self, new: usize) {
        if self.gaps.is_empty() {
            self.scale.clear();
            return;
        }
        if self.scale.len() < new {
            // The scales were not kept (no gaps then): the pairs before `new` have scale 1.
            self.scale.resize(new, 1.0);
        }
        self.scale.truncate(new);
        let gaps = &self.gaps;
        self.scale
            .par_extend(self.pairs[new..].par_iter().map(|p| gaps.scale(p)));
    }

    /// Counts the cached and live pairs in `stats` (the largest of the step).
    fn count(&self, stats: &mut ContactStats) {
        let cache = &self.cache;
        stats.candidate_pairs = stats.candidate_pairs.max(cache.candidates());
        stats.box_pairs = stats.box_pairs.max(cache.box_pairs());
        stats.cached_pairs = stats.cached_pairs.max(cache.cached_pairs());
        stats.primitive_pairs = stats.primitive_pairs.max(self.pairs.len());
    }
}
