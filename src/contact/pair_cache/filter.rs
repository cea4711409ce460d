//! Filters of the cached pairs into the live list: sweeps, refilters since the last sweep,
//! extensions for grown allowances, and the bounds they test.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::super::broad_phase::ContactMesh;
use super::super::primitive_pairs::Pair;
use super::super::sweep::SweptPair;
use super::{below, PairCache, Renewal};
use crate::geometry::bounds::round_down;

impl PairCache {
    /// Writes into `live` the pairs that may come within `reach` (m) at the positions the
    /// local step looks at while each vertex `i` stays within `allowance[i]` (m) of the path
    /// from the safe positions `safe` to the global step's result `target` (the `E_i <= A_i` of
    /// the module doc), in the cache's order; first repairs the lists ([`PairCache::repair`])
    /// or builds them afresh when they may miss a pair. Returns which it did.
    pub fn live_pairs(
        &mut self,
        safe: &[Vector3<f64>],
        target: &[Vector3<f64>],
        allowance: &[f64],
        mesh: &ContactMesh,
        reach: f64,
        live: &mut Vec<Pair>,
    ) -> Renewal {
        let fits = self.fits(mesh, safe.len(), reach);
        if fits {
            self.measure_motion(safe, target);
        }
        let holds = fits && self.regions.hold();
        let renewal = if holds && self.covers(allowance) {
            Renewal::Kept
        } else if holds && self.repair_to_cover(mesh, reach, allowance) {
            Renewal::Repaired
        } else {
            self.build(safe, target, allowance, mesh, reach);
            self.covers(allowance);
            Renewal::Built
        };
        self.apart = self.regions.largest_near_motion();
        let (near, outlying) = self.near(reach);
        self.is_live[..self.flagged].fill(false);
        // Ski rental: refilter until the refilters since the sweep have cost a sweep.
        let fall = if self.sweep.valid && self.sweep.rent <= near as f64 {
            self.sweep.measure(safe, target);
            let fall = self.sweep.fall(&self.vertex_body, self.bodies, allowance);
            if fall.is_some() {
                self.sweep.measure_patches(&self.patches, allowance);
            }
            fall
        } else {
            None
        };
        let mut found = match fall.and_then(|fall| self.refilter(near, fall, allowance, reach)) {
            Some(found) => found,
            None => self.sweep(safe, target, near, allowance, reach),
        };
        // Beyond the horizon, the build's pairs of the outlying vertices (after those before
        // it: `found` stays increasing).
        let this = &*self;
        let mut beyond: Vec<u32> = outlying
            .par_iter()
            .flat_map_iter(|&v| {
                this.pairs_of(v)
                    .iter()
                    .copied()
                    .filter(|&k| k as usize >= near)
            })
            .collect();
        beyond.par_sort_unstable();
        beyond.dedup();
        found.par_extend(
            beyond
                .into_par_iter()
                .filter(|&k| this.may_come_within(k as usize, allowance, reach)),
        );
        // The repaired pairs: each looked at on every filter.
        found.par_extend(
            this.repaired()
                .filter(|&k| this.may_come_within(k as usize, allowance, reach)),
        );
        self.flagged = found.last().map_or(0, |&k| k as usize + 1);
        live.clear();
        self.mark_live(&found, live);
        renewal
    }

    /// After [`PairCache::live_pairs`] (the allowances still measured around the path between
    /// the safe and target positions it was given, with the same mesh, even where later local
    /// steps have kept its list), the allowances of the vertices `grown` have grown and the
    /// others are as they were: appends to `live` the pairs that may now come within `reach`
    /// (only pairs with a grown vertex can, as the bounds of the others are unchanged and
    /// allowances only grow) and returns what it did to the cached pairs: kept them, or
    /// repaired them first ([`PairCache::repair`]) where a few grown vertices strayed beyond
    /// their skins. Returns `None`, leaving `live` alone, when a repair does not make the
    /// build cover the allowances (then [`PairCache::live_pairs`] must filter afresh, and may
    /// build). `grown` is increasing; `mesh` is the one the last filter was given. The
    /// build's pairs of the grown vertices are found by their index by vertex; the pairs
    /// repairs added, not indexed, are each looked at.
    ///
    /// The repair here saves a full filter: the region pairs' motions are the ones the last
    /// filter measured (they still hold), and a pair that the filter left out without a look
    /// (beyond its horizon `reach + 2 D + max T`, no vertex beyond `D`, which a filter
    /// afresh might now set larger) has a grown vertex if its bound has fallen below
    /// `reach`, so the index finds it. A local step's allowances can outgrow the build several
    /// times in a row, and a full filter each time would look again at every cached pair for
    /// a repair that costs a small fraction of that.
    pub fn extend_live(
        &mut self,
        allowance: &[f64],
        grown: &[u32],
        mesh: &ContactMesh,
        reach: f64,
        live: &mut Vec<Pair>,
    ) -> Option<Renewal> {
        debug_assert!(
            self.fits(mesh, allowance.len(), reach),
            "the mesh filtered for"
        );
        let renewal = if self.covers(allowance) {
            Renewal::Kept
        } else {
            // The last filter left every vertex covered, and only the grown ones' deviations
            // have grown since: the strays, and the sides of every pair the repair adds, are
            // among them.
            debug_assert!(
                (0..self.skin.len()).all(|i| self.deviation[i] <= self.skin[i]
                    || grown.binary_search(&(i as u32)).is_ok()),
                "a stray that did not grow"
            );
            if !self.repair_to_cover(mesh, reach, allowance) {
                return None;
            }
            Renewal::Repaired
        };
        debug_assert!(grown.windows(2).all(|w| w[0] < w[1]), "grown is increasing");
        let this = &*self;
        let wanted = |k: u32| {
            !this.is_live[k as usize] && this.may_come_within(k as usize, allowance, reach)
        };
        let mut found: Vec<u32> = grown
            .par_iter()
            .flat_map_iter(|&v| this.pairs_of(v).iter().copied().filter(|&k| wanted(k)))
            .collect();
        // The repaired pairs are not indexed by vertex: few enough to look at each.
        found.par_extend(this.repaired().filter(|&k| {
            let pair = &this.pairs[k as usize].0;
            pair.v.iter().any(|v| grown.binary_search(v).is_ok()) && wanted(k)
        }));
        found.par_sort_unstable();
        found.dedup();
        if let Some(&last) = found.last() {
            self.flagged = self.flagged.max(last as usize + 1);
        }
        self.mark_live(&found, live);
        Some(renewal)
    }

    /// Filters the cached pairs `..near` afresh for the path from `safe` to `target` and the
    /// allowances `allowance` (m) and records the sweep (see [`super::super::sweep`]): returns the
    /// pairs that may come within `reach` (m), increasing.
    fn sweep(
        &mut self,
        safe: &[Vector3<f64>],
        target: &[Vector3<f64>],
        near: usize,
        allowance: &[f64],
        reach: f64,
    ) -> Vec<u32> {
        self.sweeps += 1;
        let mut swept = std::mem::take(&mut self.sweep.swept);
        self.sweep.record(safe, target, allowance, near);
        self.packed_shift
            .pack(&self.shift, allowance, &self.patches);
        let this = &*self;
        let packed = &self.packed_shift;
        (0..near)
            .into_par_iter()
            .map(|k| {
                let (pair, at_build) = &this.pairs[k];
                // The bound from the build's distance and the moves since (`shift`, measured
                // for this filter, packed) costs no closest points; it is lower than the fresh
                // bound, which is taken only where it might be needed.
                let cheap = packed.bound(pair, f64::from(*at_build));
                let bound = if cheap - reach >= CHEAP_SLACK * reach {
                    cheap
                } else {
                    this.fresh_bound(k, allowance)
                };
                SweptPair {
                    slack: round_down(bound - reach),
                }
            })
            .collect_into_vec(&mut swept);
        if self.patch_groups.is_empty() {
            let pairs = &self.pairs[..self.arranged];
            self.patch_groups.group(pairs.par_iter().map(|(pair, _)| {
                let (a, b) = pair.sides();
                [a, b].map(|side| packed.patch(side))
            }));
        }
        self.patch_groups.record(&swept);
        self.sweep.swept = swept;
        self.sweep.within = self
            .sweep
            .swept
            .par_iter()
            .filter(|p| p.slack < 0.0)
            .count();
        let (this, sweep) = (&*self, &self.sweep);
        let found: Vec<u32> = (0..near as u32)
            .into_par_iter()
            .filter(|&k| {
                below(f64::from(sweep.swept[k as usize].slack), 0.0)
                    && below(this.common_bound(k as usize), reach)
            })
            .collect();
        found
    }

    /// Filters the cached pairs `..near` for the allowances `allowance` (m) looking again only at
    /// those whose bound may have fallen below `reach` (m) since the sweep, by at most `fall` (m)
    /// for every pair and by at most [`super::super::sweep::Sweep::patch_fall`] and
    /// [`super::super::sweep::Sweep::pair_fall`] for each (see [`super::super::sweep`]; the cheaper
    /// test first), and at those beyond the sweep's: the pairs that may come within `reach`,
    /// increasing, or `None` (and nothing done) when, beyond the pairs within reach at the sweep,
    /// more than [`REFILTER_SHARE`] of the others would be looked at again: the sweep's positions
    /// are then far enough behind that every filter until the next sweep would look at that many,
    /// and a sweep afresh costs a few of them. Adds the filter's work beyond what it costs right
    /// after the sweep (a look at each pair within reach there) to the sweep's rent.
    fn refilter(
        &mut self,
        near: usize,
        fall: f64,
        allowance: &[f64],
        reach: f64,
    ) -> Option<Vec<u32>> {
        let swept = self.sweep.near.min(near);
        // The pairs beyond the sweep's are all looked at again: where they alone are too many,
        // the sweep is due whatever the swept pairs' tests say (the same decision as below).
        if swept == self.sweep.near {
            let within = self.sweep.within;
            if (near - swept) as f64 > REFILTER_SHARE * (self.sweep.near - within) as f64 {
                return None;
            }
        }
        // The pairs to look at again. Counted: the pairs within reach at the sweep (no test
        // can leave them out), the patch falls taken and the members that took the patch
        // test, and those that took a pair test. By patch
        // pair (see `patch_groups.rs`): one patch fall per group, and the members only of the
        // groups whose least slack is below both falls.
        let (sweep, patch_groups) = (&self.sweep, &self.patch_groups);
        let chunks: Vec<(Vec<u32>, [usize; 3])> = patch_groups
            .groups()
            .par_chunks(REFILTER_CHUNK)
            .map(|chunk| {
                let (mut again, mut tests) = (Vec::new(), [0_usize; 3]);
                for group in chunk {
                    let least = f64::from(group.least);
                    if least >= 0.0 && !below(least, fall) {
                        continue;
                    }
                    let patch_fall = sweep.patch_fall(group.patches);
                    tests[1] += 1;
                    if least >= 0.0 && !below(least, patch_fall) {
                        continue;
                    }
                    for member in patch_groups.members(group, swept) {
                        let (k, s) = (member.pair as usize, f64::from(member.slack));
                        if s < 0.0 {
                            tests[0] += 1;
                            again.push(k as u32);
                        } else if below(s, fall) {
                            tests[1] += 1;
                            if below(s, patch_fall) {
                                tests[2] += 1;
                                if below(s, sweep.pair_fall(&self.pairs[k].0, allowance)) {
                                    again.push(k as u32);
                                }
                            }
                        }
                    }
                }
                (again, tests)
            })
            .collect();
        let mut tests = [0_usize; 3];
        let mut again = Vec::with_capacity(chunks.iter().map(|(a, _)| a.len()).sum());
        for (more, more_tests) in chunks {
            again.extend(more);
            tests = [0, 1, 2].map(|t| tests[t] + more_tests[t]);
        }
        again.extend(swept as u32..near as u32);
        again.par_sort_unstable();
        let [within, patch_tests, pair_tests] = tests;
        let sweep = &mut self.sweep;
        let beyond = again.len() - within;
        if beyond as f64 > REFILTER_SHARE * (sweep.near - within) as f64 {
            return None;
        }
        sweep.rent += PATCH_TEST_COST * patch_tests as f64
            + PAIR_TEST_COST * pair_tests as f64
            + beyond as f64;
        let this = &*self;
        Some(
            again
                .into_par_iter()
                .filter(|&k| this.may_come_within(k as usize, allowance, reach))
                .collect(),
        )
    }

    /// The indices of the pairs that repairs added since the build, increasing.
    fn repaired(&self) -> rayon::range::Iter<u32> {
        (self.arranged as u32..self.pairs.len() as u32).into_par_iter()
    }

    /// Marks the cached pairs `found` live and appends them to `live` (in the order of
    /// `found`: the pairs already live keep their places).
    fn mark_live(&mut self, found: &[u32], live: &mut Vec<Pair>) {
        for &k in found {
            self.is_live[k as usize] = true;
            live.push(self.pairs[k as usize].0);
        }
    }

    /// Whether the cached pair `k` may come within `reach` (m) for the allowances `allowance`
    /// (m) on the path the sweep last measured: neither the bound from its regions' common
    /// motions nor the fresh bound reaches `reach` (NaN counts as below).
    pub(super) fn may_come_within(&self, k: usize, allowance: &[f64], reach: f64) -> bool {
        below(self.common_bound(k), reach) && below(self.fresh_bound(k, allowance), reach)
    }

    /// The cached pair `k`'s relative distance bound (m) on the path the sweep last measured,
    /// from its distance at the path's start `s` (module doc "Skip", with `s` for `r`): the
    /// tightest of the bounds, as it sees only this path's moves.
    fn fresh_bound(&self, k: usize, allowance: &[f64]) -> f64 {
        let pair = &self.pairs[k].0;
        let sweep = &self.sweep;
        let d = pair.closest(&sweep.safe_now).separation.norm();
        pair.relative_distance_bound(d, &sweep.path, allowance)
    }

    /// The cached pair `k`'s distance bound from its regions' common motions (m, module doc
    /// "Skip"): cheaper than the relative bound, which is at least as large.
    fn common_bound(&self, k: usize) -> f64 {
        let (pair, d) = &self.pairs[k];
        let (a, b) = pair.sides();
        let regions = &self.regions;
        f64::from(*d)
            - pair.spread(&self.deviation)
            - regions.relative_motion(regions.of_side(a), regions.of_side(b))
    }

    /// The filter's horizon: how many of the build's arranged pairs are closer at `r` than
    /// `reach + 2 D + max T` (m; NaN distances, first, count as near), and the vertices
    /// deviating by more than `D` ([`PairCache::outlying`]). Only those pairs, and the
    /// pairs of those vertices, can pass the first test.
    pub(super) fn near(&self, reach: f64) -> (usize, Vec<u32>) {
        let (typical, outlying) = self.outlying();
        let horizon = reach + 2.0 * typical + self.apart;
        let horizon = if horizon.is_nan() {
            f64::INFINITY
        } else {
            horizon
        };
        (self.order.within(horizon), outlying)
    }

    /// The build's pairs of the vertex `v` (indices into `pairs`, below `arranged`).
    fn pairs_of(&self, v: u32) -> &[u32] {
        let v = v as usize;
        &self.by_vertex[self.by_vertex_start[v] as usize..self.by_vertex_start[v + 1] as usize]
    }

    /// Splits the vertices by their deviations `dev_i` (as [`PairCache::covers`] last
    /// measured them) for a filter's horizon: returns `D`, the least deviation that at most
    /// [`OUTLYING_SHARE`] of the vertices exceed, and those vertices (increasing).
    fn outlying(&self) -> (f64, Vec<u32>) {
        let n = self.deviation.len();
        let most = (OUTLYING_SHARE * n as f64) as usize;
        let Some(rank) = n.checked_sub(most + 1) else {
            return (0.0, Vec::new());
        };
        let mut sorted = self.deviation.clone();
        let (_, &mut typical, _) = sorted.select_nth_unstable_by(rank, f64::total_cmp);
        let outlying = (0..n as u32)
            .into_par_iter()
            .filter(|&i| self.deviation[i as usize] > typical)
            .collect();
        (typical, outlying)
    }
}

/// How far beyond the reach, as a share of it, a pair's bound from the build
/// ([`PairCache::sweep`]: its distance at the reference positions and the moves since) must be
/// for a sweep to record it instead of the bound from the pair's distance at the safe
/// positions (its closest points). A cost trade-off only: any lower bound is a correct slack
/// (see [`super::super::sweep`]), and a pair recorded with one looser than its fresh bound by
/// more than a refilter's fall is looked at again by that refilter; the sweep's live pairs, all
/// within the reach, always get the fresh bound. A flat sheet's own cached pairs lie a
/// fraction of the reach beyond it and move little relative to each other between builds.
const CHEAP_SLACK: f64 = 0.25;

/// The most vertices, as a share of all, whose deviations a filter's horizon may leave out
/// (see [`PairCache::outlying`]; the module doc, "Skip"). A cost trade-off only: the filter
/// looks at every pair of such a vertex by the index by vertex (on stacked layers a vertex
/// has about a thousand, so 1/512 of the vertices cost a few percent of a sweep), and where
/// the deviations of a few vertices reach centimetres (strays hitting the floor) the horizon
/// from the rest is several times nearer.
pub(super) const OUTLYING_SHARE: f64 = 1.0 / 512.0;

/// The largest share of a sweep's pairs that were not live that a filter looks at again
/// before it sweeps instead (a cost trade-off only: once a filter looks at a large share again,
/// so does every filter after it until the next sweep, which would have cost a few of them
/// and made the next filters cheap).
const REFILTER_SHARE: f64 = 1.0 / 16.0;

/// The patch groups a refilter's task takes at a time (a cost trade-off only).
const REFILTER_CHUNK: usize = 1 << 6;

/// The costs of a refilter's patch and pair tests ([`super::super::sweep::Sweep::patch_fall`],
/// [`super::super::sweep::Sweep::pair_fall`]) in fresh bounds (a sweep costs one per near pair),
/// for its rent (a cost trade-off only): their measured run times relative to a fresh bound.
const PATCH_TEST_COST: f64 = 0.055;
const PAIR_TEST_COST: f64 = 0.55;
