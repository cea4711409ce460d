//! The local step's primitive pairs, kept across local steps (and time steps) in the manner of
//! a Verlet neighbour list: the broad phase and the expansion into primitive pairs run only
//! when some vertex may have left the region the lists were built for.
//!
//! A build at reference positions `r` (m) with a skin `R_i` (m) per vertex and a skin `S_PQ`
//! (m) per pair of regions (see [`super::regions`]) keeps, with its distance `d_r` at `r`,
//! every primitive pair closer than its limit `L = reach + max_A R + max_B R + S_PQ` (sides
//! `A` and `B`, of the regions `P` and `Q`) at `r` that belongs to a candidate: a triangle
//! pair (sharing no vertex) whose boxes around `r`, each inflated by the largest `R` of its
//! vertices plus `reach / 2` plus half the largest `S` of its vertices' regions with the
//! regions near them, overlap and one of whose 15 primitive pairs is within its limit. The
//! second test matters on fine meshes: there the padding exceeds the triangle size, and a box
//! overlaps those of dozens of triangles of the same sheet that are much farther apart. Each
//! primitive pair is expanded in one such triangle pair only, its owner (see
//! [`Owners`]); the candidates counted are the triangle pairs that own a kept pair.
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
//! allowances) before it looks at a position where some `E_i > A_i`. (A later local step that
//! keeps the list, its safe positions and target `s'`, `y'` shifted by at most `shift_i` from
//! `s`, `y`, writes its positions the same way with `E_i` plus `shift_i`, see
//! [`super::local_step`].)
//!
//! Two consequences, both conservative:
//! - **Reuse**: the skins are measured from the common motions of *regions*, connected groups
//!   of a few hundred vertices of one body (see [`super::regions`]), so that a part moving as
//!   a whole keeps its build. Take any per-region translations `c_G^w`, `c_G^g` (the build
//!   uses the means of `w_i` and `g_i` over the region's halo) and `c_G(tau) = (1 - tau)
//!   c_G^w + tau c_G^g`. Then `|x_i - r_i - c_G(tau)| <= dev_i = max_G max(|w_i - c_G^w|,
//!   |g_i - c_G^g|) + A_i` for every region `G` whose halo holds `i` (the first part is affine
//!   in `tau`), and `|c_P(tau) - c_Q(tau)| <= T_PQ = max(|c_P^w - c_Q^w|, |c_P^g - c_Q^g|)`.
//!   Each side of a primitive pair lies in the halo of one region ([`Regions::of_side`]), and
//!   a point of a triangle is a convex combination of its vertices, so a primitive pair
//!   within `reach` at `x`, of the regions `P` and `Q`, was closer than
//!   `reach + max_A dev + max_B dev + T_PQ` at `r` (`T_PP = 0`). While `dev_i <= R_i` for every
//!   vertex and `T_PQ <= S_PQ` for every two regions, that is below the pair's limit
//!   `L = reach + max_A R + max_B R + S_PQ`: its triangles' inflated boxes overlapped (a box
//!   holds its triangle's points), so they were a candidate, and the pair was kept (regions
//!   too far apart for `L` to reach them keep no pair, see [`super::regions`]). The stored
//!   pairs are a superset of the ones a fresh broad phase would find.
//! - **Repair**: where every region pair still holds but a few vertices strayed beyond
//!   their skins (a vertex at rest in a region falling past it, say), the build is repaired
//!   instead of made afresh ([`PairCache::repair`]): their skins are raised, and the pairs
//!   that the raised limits reach are added, found by a search around those vertices'
//!   triangles only. On the paper's six layers over the ball (steps 138-146 from a saved
//!   state) each of the four builds after the first was forced by one to three of the 240K
//!   vertices, by at most 0.21 mm. There repairs defer the build by one or two steps (steps
//!   127-133 and 153-155 of a later run): then some region pairs outgrow their skins (by at
//!   most 0.26 mm), which only a build puts right. The pairs a repair adds (hundreds) go
//!   after the build's (20M there), which keep their order, index and sweep, and every
//!   filter looks at each of them: arranging and indexing all the pairs afresh made a repair
//!   cost 1.3-2 s, a third of a build (steps 153 and 154 from a saved state, with one and two
//!   repairs: broad phase 1.9 and 1.0 s, against 5.6 and 6.8 s before).
//! - **Skip**: the pair's distance at every such `x` is at least
//!   `d_r - max_{a in A, b in B} max(|w_a - w_b|, |g_a - g_b|) - max_A A - max_B A` (A, B the
//!   two primitives; [`Pair::relative_distance_bound`]): only the primitives' motion relative
//!   to each other counts, so a sheet falling as a whole keeps its own pairs out of the list.
//!   Where that is `>= reach` the pair feels no barrier (it acts only below `reach`), and it
//!   cannot come within the CCD's separations (`xi` and at most `eps xi`, both below
//!   `reach`), so it contributes nothing and is left out of the live list. (The additive
//!   CCD, which stops at a fraction of the initial gap, could report an early time for such a
//!   pair that never comes near: the skip removes that spurious clamp, nothing else.) The
//!   reuse argument gives a second, cheaper bound, `d_r - max_A dev - max_B dev - T_PQ`; a
//!   pair is skipped when either bound is at least `reach`. The build's pairs are grouped by
//!   `d_r` ([`DistanceOrder`]), so those beyond `reach + 2 D + max T` (`T` over the region
//!   pairs that may hold a stored pair, `D` a deviation that all but a few vertices stay
//!   within; where the cheaper bound skips every pair of vertices within `D`) are looked at
//!   only where a vertex deviates by more than `D`, found by the index by vertex: a local
//!   step costs what the pairs near the reach cost, not what the whole cache holds, and a few
//!   fast vertices do not make every pair near. (The few pairs that repairs add since are
//!   looked at by every filter.)
//! - **Sweeps**: a filter applies the first bound with `s`, the safe positions of its own
//!   local step, for `r` (each pair's distance at `s`, the moves along this local step's
//!   path only): the live list then holds little more than the pairs near the reach, where a
//!   bound from `r` lets through every pair whose vertices moved apart since the build. Such
//!   a full filter (a sweep) measures every near pair of the build; the filters after it look
//!   again only at the pairs whose bound may have fallen below the reach since (see
//!   [`super::sweep`]), and at every pair repairs added. A
//!   filter sweeps afresh once the filters since the last sweep have cost as much as a sweep
//!   (ski rental): as a sweep's positions fall behind, its filters cost more and more, and on
//!   the three layers of 200 x 200 the first global iterations of each step move the
//!   layers' parts millimetres apart, so that each of the 20 filters of a step looked again
//!   at 2M of 25M near pairs (480 ms each) when only a sweep's share rule decided.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::bounds::{bounding_box, box_gap, nan_max, round_down};
use super::broad_phase::{BroadPhase, ContactMesh};
use super::distance_order::DistanceOrder;
use super::patches::Patches;
use super::primitive_pairs::{close_primitive_pairs, Owners, Pair};
use super::regions::Regions;
use super::sweep::{displacements, Sweep, SweptPair, NO_BODY};
use super::vertex_index::index_by_vertex;

/// The primitive pairs of the last build and their distances at its reference positions.
#[derive(Default)]
pub(super) struct PairCache {
    broad_phase: BroadPhase,
    /// The topology the lists were built for (a different mesh forces a build).
    triangles: Vec<[u32; 3]>,
    body: Vec<u32>,
    self_contact: Vec<bool>,
    /// The body of every vertex of a triangle ([`NO_BODY`] for the others).
    vertex_body: Vec<u32>,
    /// `r`: positions of the last build (m); empty before the first.
    reference: Vec<Vector3<f64>>,
    /// Bodies of the mesh the lists were built for.
    bodies: usize,
    /// The barrier's reach the lists were built for (m): the limits, skins and region skins
    /// all grow with it, so another reach forces a build.
    built_reach: f64,
    /// `R_i` per vertex: how far it may stray from its regions' common motions since the
    /// build before the lists must be rebuilt (m).
    skin: Vec<f64>,
    /// The regions whose common motions the skins are measured from, and the skins of their
    /// pairs (see [`super::regions`]).
    regions: Regions,
    /// Triangle pairs of the last build whose inflated boxes overlap.
    box_pairs: usize,
    /// Those of them that own (see [`Owners`]) a primitive pair within the build's limit at
    /// `reference`: the candidates.
    candidates: Vec<(u32, u32)>,
    /// The triangles of each vertex, for [`Owners`].
    owners: Owners,
    /// The primitive pairs of the build, each with its distance at `reference` (m) rounded
    /// down to `f32`: the build's `..arranged` in buckets of increasing distance (NaN first),
    /// then those that repairs added since, in no order.
    pairs: Vec<(Pair, f32)>,
    /// Where the distance buckets of `pairs[..arranged]` end.
    order: DistanceOrder,
    /// How many of `pairs` the build arranged in `order`; every filter looks at each of the
    /// others (hundreds on the paper's six layers: only the pairs of the at most
    /// [`MOST_RAISED`] of the vertices whose skins repairs raised).
    arranged: usize,
    /// Per vertex: `dev_i = max_G max(|w_i - c_G^w|, |g_i - c_G^g|) + A_i` (m) over the
    /// regions `G` whose halos hold it, how far it may stray from their common motions (NaN
    /// counts as infinitely far).
    deviation: Vec<f64>,
    /// `max T_PQ` over the near region pairs (m), how far the common motions of two regions
    /// that may hold a cached pair may have moved relative to each other.
    apart: f64,
    /// The build's pairs by vertex: those of vertex `v` are `by_vertex[by_vertex_start[v]..
    /// by_vertex_start[v + 1]]` (indices into `pairs`, below `arranged`).
    by_vertex: Vec<u32>,
    by_vertex_start: Vec<u32>,
    /// Per cached pair: whether it is in the live list; false from `flagged` on.
    is_live: Vec<bool>,
    flagged: usize,
    /// Per vertex: `[w_i, g_i] = [s_i - r_i, y_i - r_i]` (m), its displacements from
    /// `reference` at the two ends of the global step's path.
    shift: Vec<[Vector3<f64>; 2]>,
    /// The last full filter of the cached pairs into the live list.
    sweep: Sweep,
    /// Sweeps since the cache was made (a count, for [`super::local_step::ContactStats`]).
    sweeps: usize,
    /// The mesh's vertices in patches, for [`Sweep::patch_fall`].
    patches: Patches,
    /// Per region: the largest skin `S_PQ` over the regions near it at the last build (m).
    near_skin: Vec<f64>,
    /// The vertices whose skins repairs have raised since the last build, increasing.
    raised: Vec<u32>,
}

/// What [`PairCache::live_pairs`] did to the cached pairs before it filtered them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Renewal {
    /// Kept them as they were.
    Kept,
    /// Raised the skins of a few vertices and added the pairs that then came within the
    /// limit ([`PairCache::repair`]).
    Repaired,
    /// Built them afresh.
    Built,
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

    /// Primitive pairs in the lists: the last build's and those repairs added since.
    pub fn cached_pairs(&self) -> usize {
        self.pairs.len()
    }

    /// Sweeps since the cache was made: filters that looked at every cached pair near
    /// enough afresh ([`super::sweep`]) instead of only those whose bound may have fallen
    /// below the reach since the last sweep.
    pub fn sweeps(&self) -> usize {
        self.sweeps
    }

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
    /// `reach`, so the index finds it. On the paper's six
    /// layers landing on the floor (steps 476-478 from a saved state), a local step's
    /// allowances outgrew the build six times in a row, and each full filter looked again at
    /// all 76M cached pairs (about 2 s each) for a repair that itself took 10 ms.
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
    /// allowances `allowance` (m) and records the sweep (see [`super::sweep`]): returns the
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
        let this = &*self;
        (0..near)
            .into_par_iter()
            .map(|k| {
                let (a, b) = this.pairs[k].0.sides();
                SweptPair {
                    slack: round_down(this.fresh_bound(k, allowance) - reach),
                    patches: [a, b].map(|side| this.patches.of_side(side) as u32),
                }
            })
            .collect_into_vec(&mut swept);
        self.sweep.swept = swept;
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

    /// Filters the cached pairs `..near` for the allowances `allowance` (m) looking again only
    /// at those whose bound may have fallen below `reach` (m) since the sweep, by at most
    /// `fall` (m) for every pair and by at most [`Sweep::patch_fall`] and
    /// [`Sweep::pair_fall`] for each (see [`super::sweep`]; the cheaper test first), and at
    /// those beyond the sweep's: the pairs that may come within `reach`, increasing, or `None`
    /// (and nothing done) when, beyond the pairs within reach at the sweep, more than
    /// [`REFILTER_SHARE`] of the others would be looked at again: the sweep's positions are
    /// then far enough behind that every filter until the next sweep would look at that many,
    /// and a sweep afresh costs a few of them. Adds the filter's work beyond what it costs
    /// right after the sweep (a look at each pair within reach there) to the sweep's rent.
    fn refilter(
        &mut self,
        near: usize,
        fall: f64,
        allowance: &[f64],
        reach: f64,
    ) -> Option<Vec<u32>> {
        let swept = self.sweep.near.min(near);
        // The pairs to look at again. Counted: the pairs within reach at the sweep (no test
        // can leave them out), and those that took a patch test and a pair test.
        let (mut again, tests) = self.sweep.swept[..swept]
            .par_iter()
            .enumerate()
            .fold(
                || (Vec::new(), [0_usize; 3]),
                |(mut again, mut tests), (k, swept)| {
                    let s = f64::from(swept.slack);
                    if s < 0.0 {
                        tests[0] += 1;
                        again.push(k as u32);
                    } else if below(s, fall) {
                        tests[1] += 1;
                        if below(s, self.sweep.patch_fall(swept.patches)) {
                            tests[2] += 1;
                            if below(s, self.sweep.pair_fall(&self.pairs[k].0, allowance)) {
                                again.push(k as u32);
                            }
                        }
                    }
                    (again, tests)
                },
            )
            .reduce(
                || (Vec::new(), [0; 3]),
                |(mut again, tests), (more, more_tests)| {
                    again.extend(more);
                    (again, [0, 1, 2].map(|t| tests[t] + more_tests[t]))
                },
            );
        again.extend(swept as u32..near as u32);
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
    fn may_come_within(&self, k: usize, allowance: &[f64], reach: f64) -> bool {
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

    /// Whether the lists were built for this mesh, vertex count and barrier reach (m).
    pub(super) fn fits(&self, mesh: &ContactMesh, vertices: usize, reach: f64) -> bool {
        self.built_reach == reach
            && self.reference.len() == vertices
            && self.triangles == mesh.triangles
            && self.body == mesh.body
            && self.self_contact == mesh.self_contact
    }

    /// Whether the build still holds every pair the local step may look at, as far as the
    /// vertices go (the reuse test of the module doc; the region pairs' part,
    /// [`Regions::hold`], depends only on the motion): per vertex `dev_i <= R_i`; writes
    /// `dev_i`. False if a figure is NaN.
    fn covers(&mut self, allowance: &[f64]) -> bool {
        let (shift, vertex_body, regions) = (&self.shift, &self.vertex_body, &self.regions);
        allowance
            .par_iter()
            .enumerate()
            .map(|(i, a)| {
                if vertex_body[i] == NO_BODY {
                    return 0.0;
                }
                let dev = regions.deviation(i, &shift[i]) + a;
                if dev.is_nan() {
                    f64::INFINITY
                } else {
                    dev
                }
            })
            .collect_into_vec(&mut self.deviation);
        self.deviation
            .par_iter()
            .zip(&self.skin)
            .all(|(&d, &r)| d <= r)
    }

    /// Repairs the build ([`PairCache::repair`]) and tells whether it then covers the
    /// allowances `allowance` (m), its region pairs' motions included.
    fn repair_to_cover(&mut self, mesh: &ContactMesh, reach: f64, allowance: &[f64]) -> bool {
        self.repair(mesh, reach) && self.regions.hold() && self.covers(allowance)
    }

    /// The filter's horizon: how many of the build's arranged pairs are closer at `r` than
    /// `reach + 2 D + max T` (m; NaN distances, first, count as near), and the vertices
    /// deviating by more than `D` ([`PairCache::outlying`]). Only those pairs, and the
    /// pairs of those vertices, can pass the first test.
    fn near(&self, reach: f64) -> (usize, Vec<u32>) {
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

    /// Writes `[s_i - r_i, y_i - r_i]` into `shift` and measures the regions' common
    /// motions, the means of `shift` over their halos (any choice is correct; the means keep
    /// the vertices' deviations small).
    fn measure_motion(&mut self, safe: &[Vector3<f64>], target: &[Vector3<f64>]) {
        displacements(safe, target, &self.reference, &mut self.shift);
        self.regions.measure(&self.shift);
    }

    /// Builds the lists at `r = safe`. The skins are a cost trade-off only (any that pass the
    /// reuse test are correct): per vertex `R_i = q_i + reach / 4` with `q_i` the largest
    /// `M max_G |g_j - c_G^g| + A_j` (over the regions `G` whose halos hold `j`) within
    /// [`SKIN_RINGS`] triangle rings of `i`, and per region pair the `S_PQ` of
    /// [`Regions::set_skins`] with `K_PQ = M |c_P^g - c_Q^g| + reach / 4`, `M` =
    /// [`SKIN_MOVES`]: room for several more moves like the build's (for the vertex and the
    /// ones around it, so that motion spreading through a sheet does not force a build at
    /// once) and a quarter reach of slow drift. (With skins from the bodies' means, `M` = 8
    /// rather than 2 on 3 x 90^2 cloths draping over the ball, 110 steps: builds 21 -> 10,
    /// broad phase 14.8 -> 8.6 s, 33 % more candidates, peak memory 302 -> 357 MB; 16: 7
    /// builds, 7.5 s, 54 % more candidates. With skins from the regions', 4 rather than 8 on
    /// 3 x 115^2, 300 steps: builds 38 -> 63, broad phase 121 -> 131 s, the largest cache
    /// 2.9M -> 1.6M candidates, peak 33 -> 20 KB per vertex: memory is what limits the
    /// paper's six layers, and cheaper filtering pays for the builds.) A vertex moving with the vertices around it keeps
    /// a small skin. A larger skin is reused longer but keeps more pairs (all those within the
    /// limit on a sheet: their number grows with the square of `limit / l`, `l` the edge
    /// length), each filtered at every local step.
    fn build(
        &mut self,
        safe: &[Vector3<f64>],
        target: &[Vector3<f64>],
        allowance: &[f64],
        mesh: &ContactMesh,
        reach: f64,
    ) {
        if self.patches.vertices() != safe.len() || self.triangles != mesh.triangles {
            self.patches = Patches::new(mesh.triangles, safe.len());
            self.regions = Regions::new(mesh.triangles, safe.len());
        }
        self.triangles.clear();
        self.triangles.extend_from_slice(mesh.triangles);
        self.body.clear();
        self.body.extend_from_slice(mesh.body);
        self.self_contact.clear();
        self.self_contact.extend_from_slice(mesh.self_contact);
        self.vertex_body.clear();
        self.vertex_body.resize(safe.len(), NO_BODY);
        for (t, &b) in mesh.triangles.iter().zip(mesh.body) {
            for &v in t {
                self.vertex_body[v as usize] = b;
            }
        }
        self.reference.clear();
        self.reference.extend_from_slice(safe);
        self.bodies = mesh.self_contact.len();
        self.built_reach = reach;
        self.measure_motion(safe, target);
        let finite = |v: f64| if v.is_nan() { f64::INFINITY } else { v };
        let (shift, vertex_body, regions) = (&self.shift, &self.vertex_body, &self.regions);
        (0..safe.len())
            .into_par_iter()
            .map(|i| match vertex_body[i] {
                NO_BODY => 0.0,
                _ => finite(SKIN_MOVES * regions.target_deviation(i, &shift[i][1]) + allowance[i]),
            })
            .collect_into_vec(&mut self.skin);
        spread_over_rings(&mut self.skin, mesh.triangles, SKIN_RINGS);
        self.skin.iter_mut().for_each(|r| *r += 0.25 * reach);
        self.near_skin = self.regions.set_skins(
            &self.reference,
            &self.skin,
            &self.vertex_body,
            mesh.self_contact,
            SKIN_MOVES,
            reach,
        );
        self.raised.clear();

        // NaN distances (NaN positions) are kept.
        let padding: Vec<f64> = mesh
            .triangles
            .par_iter()
            .map(|t| self.padding(t, reach))
            .collect();
        let (reference, skin, regions) = (&self.reference, &self.skin, &self.regions);
        let boxes = self
            .broad_phase
            .candidate_pairs(reference, reference, mesh, &padding);
        self.box_pairs = boxes.len();
        // The padding takes the largest skin of the regions near a triangle's; the limits of
        // a triangle pair's primitive pairs are at most `reach + (max R + max R) + max S_PQ`
        // over its own vertices' regions (`S` is symmetric and a primitive pair's regions are
        // those of a vertex of either triangle; the sums are in the order of [`limit`], so
        // rounding keeps the bound above every limit): where its triangles' boxes are farther
        // apart, none of them is kept, and their 15 distances are not worth computing.
        let triangles = mesh.triangles;
        let boxes: Vec<(u32, u32)> = boxes
            .par_iter()
            .copied()
            .filter(|&(i, j)| {
                let (a, b) = (&triangles[i as usize], &triangles[j as usize]);
                let largest = |t: &[u32; 3]| t.iter().map(|&v| skin[v as usize]).fold(0.0, nan_max);
                let bound = reach + (largest(a) + largest(b)) + regions.largest_skin_between(a, b);
                below(box_distance(reference, a, b), bound)
            })
            .collect();
        // A primitive pair beyond the limit cannot come within `reach` before the next build.
        self.owners.index(mesh, safe.len());
        let mut chunks = Vec::new();
        self.candidates = close_primitive_pairs(
            mesh,
            Some(&self.owners),
            &boxes,
            reference,
            |p| limit(skin, regions, reach, p),
            |_, _| true,
            &mut chunks,
        );
        self.order
            .arrange(&chunks, |&(_, d)| f64::from(d), &mut self.pairs);
        self.arranged = self.pairs.len();
        drop(chunks);
        self.index_pairs();
    }

    /// Repairs the build where the motion still fits every region pair's skin but a few
    /// vertices strayed beyond their own (`dev_i > R_i`, as [`PairCache::covers`] last
    /// measured): raises their skins to `R_i = 2 dev_i + reach / 4` (room for as much stray
    /// again, and a quarter reach) or less, so that every far region pair keeps half its
    /// slack ([`Regions::most_raised_skin`]), lowers the far region pairs' skins to match
    /// ([`Regions::raise`]) and adds the primitive pairs that the raised limits now reach.
    /// Such a pair has a side with a raised vertex, so its owner ([`Owners`]) is a pair of a
    /// triangle of that vertex with another whose box overlaps: the build's box for a
    /// triangle without a raised vertex, and among the triangles of raised vertices (of this
    /// repair and the ones before it since the build) the boxes with their raised padding.
    /// It keeps the pairs within their new limit and not within their old one (the cache
    /// holds those already). Returns false where the build must be made afresh instead: a NaN
    /// or infinite stray, one beyond the skin the far region pairs leave room for, or more
    /// raised vertices since the build than [`MOST_RAISED`] allows (then the skins may have
    /// changed and only a build puts them right).
    fn repair(&mut self, mesh: &ContactMesh, reach: f64) -> bool {
        let strayed: Vec<u32> = (0..self.skin.len() as u32)
            .filter(|&i| self.deviation[i as usize] > self.skin[i as usize])
            .collect();
        if strayed.is_empty()
            || strayed
                .iter()
                .any(|&i| !self.deviation[i as usize].is_finite())
            || (self.raised.len() + strayed.len()) as f64 > MOST_RAISED * self.skin.len() as f64
        {
            return false;
        }
        let raised_skins: Vec<f64> = strayed
            .iter()
            .map(|&i| {
                let wanted = 2.0 * self.deviation[i as usize] + 0.25 * reach;
                wanted.min(self.regions.most_raised_skin(i as usize))
            })
            .collect();
        if strayed
            .iter()
            .zip(&raised_skins)
            .any(|(&i, r)| r.is_nan() || self.deviation[i as usize] > *r)
        {
            return false;
        }
        let before = self.skin.clone();
        for (&i, &r) in strayed.iter().zip(&raised_skins) {
            self.skin[i as usize] = r;
        }
        self.regions.raise(&self.skin, &strayed, reach);
        self.raised.extend_from_slice(&strayed);
        self.raised.sort_unstable();
        self.raised.dedup();
        let triangles_of = |vertices: &[u32]| {
            let mut of: Vec<u32> = vertices
                .iter()
                .flat_map(|&v| self.owners.of(v).iter().copied())
                .collect();
            of.sort_unstable();
            of.dedup();
            of
        };
        let (fresh, raised) = (triangles_of(&strayed), triangles_of(&self.raised));
        let reference = &self.reference;
        let triangles = mesh.triangles;
        let mut boxes: Vec<(u32, u32)> = fresh
            .par_iter()
            .flat_map_iter(|&t| {
                let t3 = &triangles[t as usize];
                let (lo, hi) = triangle_box(reference, t3, self.padding(t3, reach));
                let mut near = Vec::new();
                self.broad_phase.overlapping(lo, hi, &mut near);
                near.into_iter()
                    .filter(move |&u| mesh.may_touch(t as usize, u as usize))
                    .map(move |u| (t.min(u), t.max(u)))
            })
            .collect();
        let raised_triangles: Vec<[u32; 3]> =
            raised.iter().map(|&t| triangles[t as usize]).collect();
        let raised_body: Vec<u32> = raised.iter().map(|&t| mesh.body[t as usize]).collect();
        let raised_padding: Vec<f64> = raised_triangles
            .iter()
            .map(|t| self.padding(t, reach))
            .collect();
        let among_raised = ContactMesh {
            triangles: &raised_triangles,
            body: &raised_body,
            self_contact: mesh.self_contact,
        };
        boxes.extend(
            BroadPhase::default()
                .candidate_pairs(reference, reference, &among_raised, &raised_padding)
                .iter()
                .map(|&(a, b)| (raised[a as usize], raised[b as usize]))
                .map(|(a, b)| (a.min(b), a.max(b))),
        );
        boxes.par_sort_unstable();
        boxes.dedup();
        let mut chunks = Vec::new();
        let (skin, regions) = (&self.skin, &self.regions);
        close_primitive_pairs(
            mesh,
            Some(&self.owners),
            &boxes,
            reference,
            |p| limit(skin, regions, reach, p),
            |p, d| !within_limit(&before, regions, reach, p, d),
            &mut chunks,
        );
        // Appended after the arranged pairs, which keep their places, their order, their
        // index by vertex and the sweep's record of them: arranging the build's millions
        // afresh cost 1.3-2 s for a few hundred pairs on the paper's six layers.
        self.pairs.extend(chunks.into_iter().flatten());
        self.is_live.resize(self.pairs.len(), false);
        true
    }

    /// The padding (m) of the triangle `t`'s box at the reference positions: its largest
    /// vertex skin, half the reach and half the largest region pair skin of its vertices'
    /// regions (a primitive pair's regions are those of its sides' first vertices), so that
    /// the boxes of two triangles overlap wherever two of their primitives are within their
    /// limit.
    fn padding(&self, t: &[u32; 3], reach: f64) -> f64 {
        t.iter().map(|&v| self.skin[v as usize]).fold(0.0, f64::max)
            + 0.5 * reach
            + 0.5 * self.regions.largest_of(t, &self.near_skin)
    }

    /// Indexes the build's pairs by vertex (the four vertices of a pair are distinct: its
    /// primitives share none) and marks none of them live, none swept.
    fn index_pairs(&mut self) {
        index_by_vertex(
            self.pairs.iter().map(|(pair, _)| pair.v),
            self.reference.len(),
            &mut self.by_vertex_start,
            &mut self.by_vertex,
        );
        self.is_live.clear();
        self.is_live.resize(self.pairs.len(), false);
        self.flagged = 0;
        self.sweep.valid = false;
    }
}

/// The most vertices, as a share of all, whose deviations a filter's horizon may leave out
/// (see [`PairCache::outlying`]; the module doc, "Skip"). A cost trade-off only: the filter
/// looks at every pair of such a vertex by the index by vertex (about 1300 pairs per vertex
/// on the paper's six layers landing, so 1/512 of the vertices cost a few percent of a
/// sweep), and where the deviations of a few vertices reach centimetres (strays hitting the
/// floor) the horizon from the rest is several times nearer.
const OUTLYING_SHARE: f64 = 1.0 / 512.0;

/// The most vertices, as a share of all, that a build may have raised skins for by
/// [`PairCache::repair`] before it is built afresh instead (a cost trade-off only: a repair
/// costs what the raised vertices' triangles cost, a build what the whole mesh costs, and
/// every raised skin keeps more pairs, each looked at by every filter until the next build).
const MOST_RAISED: f64 = 1.0 / 64.0;

/// The limit of a build (m) for the primitive pair `p`: `reach + max_A R + max_B R + S_PQ`,
/// with the vertex skins `skin` (m) over its sides `A`, `B` and the skin `S_PQ` (m) of their
/// regions `P`, `Q` (see [`super::regions`]).
fn limit(skin: &[f64], regions: &Regions, reach: f64, p: &Pair) -> f64 {
    let (a, b) = p.sides();
    reach + p.spread(skin) + regions.skin(regions.of_side(a), regions.of_side(b))
}

/// Whether a build with the skins `skin` and `regions` keeps the primitive pair `p` at the
/// distance `d` (m): closer than its [`limit`], or NaN.
fn within_limit(skin: &[f64], regions: &Regions, reach: f64, p: &Pair, d: f64) -> bool {
    d < limit(skin, regions, reach, p) || d.is_nan()
}

/// The distance (m) between the bounding boxes of the triangles `a` and `b` at `x` (m): at
/// most the distance between any of their points, 0 where a position is not finite (see
/// [`bounding_box`]).
fn box_distance(x: &[Vector3<f64>], a: &[u32; 3], b: &[u32; 3]) -> f64 {
    let bounds = |t: &[u32; 3]| bounding_box(t.iter().map(|&v| &x[v as usize]));
    box_gap(bounds(a), bounds(b))
}

/// The box `(lo, hi)` of the triangle `t` at `x` (m), inflated by `pad` (m) on every side
/// (the whole space where a position is not finite, see [`bounding_box`]).
fn triangle_box(x: &[Vector3<f64>], t: &[u32; 3], pad: f64) -> (Vector3<f64>, Vector3<f64>) {
    let (lo, hi) = bounding_box(t.iter().map(|&v| &x[v as usize]));
    let pad = Vector3::repeat(pad);
    (lo - pad, hi + pad)
}

/// Whether `x < limit`, NaN counting as below (a NaN bound keeps its pair).
fn below(x: f64, limit: f64) -> bool {
    x < limit || x.is_nan() || limit.is_nan()
}

/// The largest share of a sweep's pairs that were not live that a filter looks at again
/// before it sweeps instead (a cost trade-off only: on the paper's cloth draping over the ball
/// at 200 x 200, 13M near pairs, the first filter of a time step looked at 23 % of them again,
/// 400 ms, and so did the eight after it, against a sweep of 1 s and then 12 ms each).
const REFILTER_SHARE: f64 = 1.0 / 16.0;

/// The costs of a refilter's patch and pair tests ([`Sweep::patch_fall`],
/// [`Sweep::pair_fall`]) in fresh bounds (a sweep costs one per near pair), for its rent (a
/// cost trade-off only): measured with `perf` on the three layers of 200 x 200 over the ball
/// (steps 510-512, where the refilters made 20M patch tests, 3M pair tests and 2M fresh
/// bounds each, 480 ms, and did so 20 times per step).
const PATCH_TEST_COST: f64 = 0.055;
const PAIR_TEST_COST: f64 = 0.55;

/// Triangle rings over which a build spreads each vertex's skin (see [`PairCache::build`]).
const SKIN_RINGS: usize = 2;

/// How many times its motion in the build's global step a build gives each vertex as skin
/// (see [`PairCache::build`]).
const SKIN_MOVES: f64 = 4.0;

/// Replaces each value by the largest within `rings` triangle rings of its vertex (NaN counts
/// as the largest).
fn spread_over_rings(values: &mut [f64], triangles: &[[u32; 3]], rings: usize) {
    for _ in 0..rings {
        let largest: Vec<f64> = triangles
            .par_iter()
            .map(|t| t.iter().map(|&v| values[v as usize]).fold(0.0, nan_max))
            .collect();
        for (t, m) in triangles.iter().zip(largest) {
            for &v in t {
                values[v as usize] = nan_max(values[v as usize], m);
            }
        }
    }
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
        close_primitive_pairs(
            mesh,
            None,
            &all,
            positions,
            |_| f64::INFINITY,
            |_, _| true,
            &mut every,
        );
        let mut every: Vec<Pair> = every.into_iter().flatten().map(|(p, _)| p).collect();
        every.sort_unstable();
        every.dedup();
        (all, every)
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

    impl<'a> Moves<'a> {
        fn new(
            safe: &'a [Vector3<f64>],
            target: &'a [Vector3<f64>],
            clamp: &'a [f64],
            allowance: &'a [f64],
        ) -> Self {
            Moves {
                safe,
                target,
                clamp,
                allowance,
            }
        }

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
            let mut live = live.to_vec();
            live.sort_unstable();
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

    impl PairCache {
        /// Checks that every cached pair whose bounds may come within `reach` (m) for the
        /// allowances `allowance` (m), on the path the sweep last measured, is in `live`;
        /// returns how many of them repairs added.
        fn assert_live_hold_every_cached_pair_that_may_come_within(
            &self,
            live: &[Pair],
            allowance: &[f64],
            reach: f64,
            step: usize,
        ) -> usize {
            let mut live = live.to_vec();
            live.sort_unstable();
            let mut repaired = 0;
            for (k, (p, _)) in self.pairs.iter().enumerate() {
                if self.may_come_within(k, allowance, reach) {
                    assert!(
                        live.binary_search(p).is_ok(),
                        "step {step}: cached pair {k} of {} ({} arranged) is not live",
                        self.pairs.len(),
                        self.arranged
                    );
                    repaired += usize::from(k >= self.arranged);
                }
            }
            repaired
        }

        /// Checks that the stored pairs are exactly those of `every` closer than their limit
        /// at the reference positions (brute force), each with its distance there rounded
        /// down.
        fn assert_stores_exactly_the_pairs_within_their_limit(
            &self,
            every: &[Pair],
            reach: f64,
            step: usize,
        ) {
            let r = &self.reference;
            let limit = |p: &Pair| limit(&self.skin, &self.regions, reach, p);
            for (p, d) in &self.pairs {
                assert!(
                    f64::from(*d) <= p.closest(r).separation.norm(),
                    "step {step}"
                );
                assert!(f64::from(*d) < limit(p), "step {step}");
            }
            let mut stored: Vec<Pair> = self.pairs.iter().map(|(p, _)| *p).collect();
            stored.sort_unstable();
            let mut close: Vec<Pair> = every
                .iter()
                .copied()
                .filter(|p| p.closest(r).separation.norm() < limit(p))
                .collect();
            close.sort_unstable();
            assert_eq!(stored, close, "step {step}");
        }
    }

    /// The triangles of a grid of `side x side` vertices (numbered row by row), two per quad.
    pub(in crate::contact) fn grid_triangles(side: u32) -> Vec<[u32; 3]> {
        let quads = (0..side - 1).flat_map(|j| (0..side - 1).map(move |i| j * side + i));
        quads
            .flat_map(|v| [[v, v + 1, v + side], [v + 1, v + side + 1, v + side]])
            .collect()
    }

    /// The triangles of two copies of a mesh of `n` vertices and triangles `triangles` (the
    /// second's vertices numbered after the first's), and the body of each (0 and 1).
    pub(in crate::contact) fn two_copies(
        triangles: &[[u32; 3]],
        n: u32,
    ) -> (Vec<[u32; 3]>, Vec<u32>) {
        let both: Vec<[u32; 3]> = triangles
            .iter()
            .copied()
            .chain(triangles.iter().map(|t| t.map(|v| v + n)))
            .collect();
        let body = (0..both.len())
            .map(|t| u32::from(t >= triangles.len()))
            .collect();
        (both, body)
    }

    /// A rolled-up grid of `n x n` vertices (a spiral of one and a half turns, its layers
    /// `gap` (m) apart, jittered by up to 3 mm) and its triangles.
    pub(in crate::contact) fn spiral(
        n: u32,
        gap: f64,
        rng: &mut Rng,
    ) -> (Vec<Vector3<f64>>, Vec<[u32; 3]>) {
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

    /// A test mesh: positions (m), triangles, the body of each triangle and whether each body
    /// has self-contact.
    struct TestMesh {
        positions: Vec<Vector3<f64>>,
        triangles: Vec<[u32; 3]>,
        body: Vec<u32>,
        self_contact: Vec<bool>,
    }

    impl TestMesh {
        /// The rolled-up grid of [`spiral`], one body.
        fn rolled(n: u32, gap: f64, rng: &mut Rng) -> Self {
            let (positions, triangles) = spiral(n, gap, rng);
            let body = vec![0; triangles.len()];
            TestMesh {
                positions,
                triangles,
                body,
                self_contact: vec![true],
            }
        }

        /// Two flat square sheets of `side x side` vertices 2 cm apart, in the planes `x = 0`
        /// and `x = apart` (m), bodies 0 and 1.
        fn two_sheets(side: u32, apart: f64) -> Self {
            let sheet = |x: f64| {
                (0..side * side).map(move |v| {
                    Vector3::new(x, 0.02 * f64::from(v / side), 0.02 * f64::from(v % side))
                })
            };
            let positions = sheet(0.0).chain(sheet(apart)).collect();
            let (triangles, body) = two_copies(&grid_triangles(side), side * side);
            TestMesh {
                positions,
                triangles,
                body,
                self_contact: vec![true, true],
            }
        }

        fn mesh(&self) -> ContactMesh<'_> {
            ContactMesh {
                triangles: &self.triangles,
                body: &self.body,
                self_contact: &self.self_contact,
            }
        }
    }

    /// A non-manifold mesh: the rolled-up grid with a fin on some of its edges (a third
    /// triangle on an edge two triangles already share, its tip 4 mm off the grid). A build
    /// stores exactly the primitive pairs closer than their limit (brute force over all
    /// primitive pairs), as on a manifold mesh: the owners of pairs on such edges are looked up
    /// among all their triangles.
    #[test]
    fn a_build_on_non_manifold_edges_stores_every_close_pair() {
        let mut rng = Rng::new(23);
        let mut rolled = TestMesh::rolled(10, 0.03, &mut rng);
        let fins: Vec<[u32; 3]> = rolled.triangles.iter().step_by(7).copied().collect();
        for [a, b, c] in fins {
            let tip = rolled.positions[c as usize] + Vector3::new(0.0, 0.0, 0.004);
            rolled.triangles.push([a, b, rolled.positions.len() as u32]);
            rolled.positions.push(tip);
            rolled.body.push(0);
        }
        let mesh = rolled.mesh();
        let safe = rolled.positions.clone();
        let (_, every) = brute_force_pairs(&mesh, &safe);
        let (reach, allowance) = (0.02, vec![0.002; safe.len()]);
        let mut cache = PairCache::default();
        let mut live = Vec::new();
        assert_eq!(
            cache.live_pairs(&safe, &safe, &allowance, &mesh, reach, &mut live),
            Renewal::Built
        );
        let limit = |p: &Pair| limit(&cache.skin, &cache.regions, reach, p);
        let mut stored: Vec<Pair> = cache.pairs.iter().map(|(p, _)| *p).collect();
        stored.sort_unstable();
        let mut close: Vec<Pair> = every
            .iter()
            .copied()
            .filter(|p| p.closest(&safe).separation.norm() < limit(p))
            .collect();
        close.sort_unstable();
        assert!(close.len() > 100, "{} close pairs", close.len());
        assert_eq!(stored, close);
    }

    /// The rolled-up grid (layers a little more than the barrier's reach apart) moving over
    /// several local steps: the live pairs hold every primitive pair of non-adjacent triangles
    /// that a brute-force search finds within `reach` along the way; each build's candidates
    /// are exactly the triangle pairs that own (see [`Owners`]) a primitive pair closer than
    /// its limit `reach + max_P R + max_Q R` (brute force), at the first build fewer than three
    /// quarters of the box pairs, and its stored primitive pairs are exactly those closer than
    /// their limit (brute force over all primitive pairs): expanding only the owned pairs loses
    /// none.
    #[test]
    fn crumpled_grid_keeps_every_pair_a_brute_force_search_finds() {
        let mut rng = Rng::new(19);
        let rolled = TestMesh::rolled(14, 0.03, &mut rng);
        let mesh = rolled.mesh();
        let mut safe = rolled.positions.clone();
        let (all, every) = brute_force_pairs(&mesh, &safe);
        let (reach, allowance) = (0.02, vec![0.002; safe.len()]);
        let clamp = vec![1.0; safe.len()];
        let mut cache = PairCache::default();
        let mut live = Vec::new();
        let mut builds = Vec::new();
        let mut within = 0;
        for (k, size) in [0.002, 0.004, 0.015, 0.002, 0.004].into_iter().enumerate() {
            let target: Vec<_> = safe.iter().map(|p| p + rng.vector() * size).collect();
            let renewal = cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live);
            builds.push(renewal);
            if renewal == Renewal::Built {
                let r = &cache.reference;
                let limit = |p: &Pair| limit(&cache.skin, &cache.regions, reach, p);
                let near: Vec<_> = all
                    .iter()
                    .copied()
                    .filter(|&pair| {
                        let mut owned = Vec::new();
                        let candidates = close_primitive_pairs(
                            &mesh,
                            Some(&cache.owners),
                            &[pair],
                            r,
                            limit,
                            |_, _| true,
                            &mut owned,
                        );
                        !candidates.is_empty()
                    })
                    .collect();
                let mut candidates = cache.candidates.clone();
                candidates.sort_unstable();
                assert_eq!(candidates, near, "step {k}");
                assert!(
                    k > 0 || 4 * cache.candidates() < 3 * cache.box_pairs(),
                    "step {k}: {} candidates of {} box pairs",
                    cache.candidates(),
                    cache.box_pairs()
                );
                cache.assert_stores_exactly_the_pairs_within_their_limit(&every, reach, k);
            }
            let moves = Moves::new(&safe, &target, &clamp, &allowance);
            within +=
                moves.assert_live_hold_every_pair_within_reach(&every, &live, reach, &mut rng, k);
            safe = target;
        }
        assert!(within > 100, "the scene has pairs within reach: {within}");
        use Renewal::{Built, Kept};
        assert_eq!(builds, [Built, Kept, Built, Kept, Kept]);
    }

    /// The rolled-up grid falling fast (5 reaches per local step, each vertex jittered by up
    /// to 3 mm on top), first freely, then with every other vertex clamped back towards its
    /// safe position by its own factor, beside the same moves without the fall: the live
    /// pairs hold every pair a brute-force search finds within `reach` on the local step's
    /// paths. Falling freely, the common motion costs nothing: the build is kept as long as at
    /// rest (the absolute motion of 0.1 m per step would force one every step), and it caches
    /// and keeps live as many pairs as at rest. Clamped, vertices lag behind their neighbours
    /// by up to 0.1 m, and more than three times as many pairs are live.
    #[test]
    fn a_falling_grid_keeps_few_pairs_live_unless_clamped() {
        /// Per local step: whether it built, the cached and the live pairs.
        fn run(fall: Vector3<f64>, within: &mut [usize; 2]) -> Vec<(bool, usize, usize)> {
            let mut rng = Rng::new(23);
            let rolled = TestMesh::rolled(12, 0.03, &mut rng);
            let mesh = rolled.mesh();
            let mut safe = rolled.positions.clone();
            let (_, every) = brute_force_pairs(&mesh, &safe);
            let (reach, drift) = (0.02, 0.001);
            let mut cache = PairCache::default();
            let mut live = Vec::new();
            let mut steps = Vec::new();
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
                let built = cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live)
                    != Renewal::Kept;
                steps.push((built, cache.pairs.len(), live.len()));
                let moves = Moves::new(&safe, &target, &clamp, &allowance);
                within[usize::from(clamped)] += moves
                    .assert_live_hold_every_pair_within_reach(&every, &live, reach, &mut rng, k);
                // The next local step starts where this one ended (unclamped: the whole move).
                safe = (0..safe.len())
                    .map(|i| safe[i] + (target[i] - safe[i]) * clamp[i])
                    .collect();
            }
            steps
        }
        let mut within = [0, 0];
        let falling = run(Vector3::new(0.0, 0.0, -0.1), &mut within);
        let resting = run(Vector3::zeros(), &mut [0, 0]);
        assert!(falling[0].0);
        let close = |a: usize, b: usize| a.abs_diff(b) * 100 <= b;
        for (k, (f, r)) in falling.iter().zip(&resting).enumerate().take(3) {
            assert_eq!(f.0, r.0, "step {k}: built {f:?} at rest {r:?}");
            assert!(
                close(f.1, r.1) && close(f.2, r.2),
                "step {k}: {f:?} at rest {r:?}"
            );
        }
        assert_eq!(falling[1..3].iter().filter(|f| f.0).count(), 0);
        let free = falling[..3].iter().map(|f| f.2).max().unwrap();
        for (k, f) in falling.iter().enumerate().skip(3) {
            assert!(
                f.2 > 3 * free,
                "step {k}: {f:?}, free fall at most {free} live"
            );
        }
        assert!(
            within[0] > 100 && within[1] > within[0],
            "the scene has pairs within reach: {within:?}"
        );
    }

    /// Two rolled-up grids (two bodies) flying into each other (8 reaches per local step
    /// relative to each other, each vertex jittered by up to 3 mm): the live pairs hold every
    /// pair a brute-force search finds within `reach`, across the bodies included; the
    /// approach renews the build every [`SKIN_MOVES`] steps or one sooner (the skins of the
    /// region pairs across hold about that many steps of it), and each build keeps no more
    /// pairs within a body than the same grid alone at rest.
    #[test]
    fn two_bodies_flying_into_each_other_keep_every_pair_across() {
        let mut rng = Rng::new(31);
        let (one, triangles_one) = spiral(10, 0.03, &mut rng);
        let (other, _) = spiral(10, 0.03, &mut rng);
        let n = one.len() as u32;
        let offset = Vector3::new(0.45, 0.0, 0.0);
        let mut safe: Vec<_> = one
            .iter()
            .copied()
            .chain(other.iter().map(|p| p + offset))
            .collect();
        let (triangles, body) = two_copies(&triangles_one, n);
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &body,
            self_contact: &[true, true],
        };
        let (_, every) = brute_force_pairs(&mesh, &safe);
        let across = |p: &Pair| (p.v[0] < n) != (p.v[3] < n);
        let (reach, allowance) = (0.02, vec![0.001; safe.len()]);
        let clamp = vec![1.0; safe.len()];
        // One grid alone, resting with the same jitter: its cached pairs.
        let alone = {
            let mesh = ContactMesh {
                triangles: &triangles_one,
                body: &body[..triangles_one.len()],
                self_contact: &[true],
            };
            let jittered: Vec<_> = one.iter().map(|p| p + rng.vector() * 0.003).collect();
            let mut cache = PairCache::default();
            cache.live_pairs(
                &one,
                &jittered,
                &allowance[..one.len()],
                &mesh,
                reach,
                &mut Vec::new(),
            );
            cache.pairs.len()
        };
        let mut cache = PairCache::default();
        let mut live = Vec::new();
        let mut builds = Vec::new();
        let mut within = [0, 0];
        let steps = 3 * SKIN_MOVES as usize;
        for k in 0..steps {
            let target: Vec<_> = (0..safe.len())
                .map(|i| {
                    let towards = if i < n as usize { 0.08 } else { -0.08 };
                    safe[i] + Vector3::new(towards, 0.0, 0.0) + rng.vector() * 0.003
                })
                .collect();
            let built = cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live)
                != Renewal::Kept;
            builds.push(built);
            if built {
                let own = cache.pairs.iter().filter(|(p, _)| !across(p)).count();
                assert!(
                    own <= 2 * alone + alone / 10,
                    "step {k}: {own} pairs within the bodies, {alone} alone"
                );
            }
            let moves = Moves::new(&safe, &target, &clamp, &allowance);
            let (own, apart): (Vec<Pair>, Vec<Pair>) = every.iter().partition(|p| !across(p));
            within[0] +=
                moves.assert_live_hold_every_pair_within_reach(&own, &live, reach, &mut rng, k);
            within[1] +=
                moves.assert_live_hold_every_pair_within_reach(&apart, &live, reach, &mut rng, k);
            safe = target;
        }
        assert!(
            within[0] > 100 && within[1] > 100,
            "pairs within reach: {within:?}"
        );
        // The jitter of the regions' means eats into the room of the last step or so.
        let at: Vec<usize> = (0..steps).filter(|&k| builds[k]).collect();
        assert_eq!(at[0], 0);
        assert!(
            at.windows(2)
                .all(|w| (SKIN_MOVES as usize - 1..=SKIN_MOVES as usize).contains(&(w[1] - w[0]))),
            "builds at steps {at:?}"
        );
    }

    /// Two flat sheets facing each other at rest, 0.2 m apart, until one sets off towards
    /// the other (5 mm per local step, each vertex jittered by up to 0.5 mm, allowances of
    /// 1 cm): the build at rest keeps no pair across (their regions are far, and the skins of
    /// far regions hold the approach until they come near), a second build comes before the
    /// first pair across within reach, and the live pairs hold every pair a brute-force
    /// search finds within `reach` all the way into contact. Flat sheets make the boxes of
    /// the regions' halos as close as their triangles, so every term of a far region pair's
    /// skin counts.
    #[test]
    fn a_body_setting_off_renews_the_build_before_it_comes_near() {
        let mut rng = Rng::new(37);
        let side = 12u32;
        let n = side * side;
        let sheets = TestMesh::two_sheets(side, 0.2);
        let (mesh, mut safe) = (sheets.mesh(), sheets.positions.clone());
        let (_, every) = brute_force_pairs(&mesh, &safe);
        let across: Vec<Pair> = every
            .iter()
            .copied()
            .filter(|p| (p.v[0] < n) != (p.v[3] < n))
            .collect();
        let (reach, allowance) = (0.02, vec![0.01; safe.len()]);
        let clamp = vec![1.0; safe.len()];
        let (mut cache, mut live, mut builds, mut within) =
            (PairCache::default(), Vec::new(), Vec::new(), Vec::new());
        for k in 0..40 {
            let target: Vec<_> = (0..safe.len())
                .map(|i| {
                    let set_off = i >= n as usize && k >= 2;
                    let towards = if set_off { -0.005 } else { 0.0 };
                    safe[i] + Vector3::new(towards, 0.0, 0.0) + rng.vector() * 0.0005
                })
                .collect();
            let built = cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live)
                != Renewal::Kept;
            builds.push(built);
            if k == 0 {
                let kept = cache.pairs.iter();
                assert!(kept.clone().all(|(p, _)| (p.v[0] < n) == (p.v[3] < n)));
            }
            let moves = Moves::new(&safe, &target, &clamp, &allowance);
            within.push(
                moves.assert_live_hold_every_pair_within_reach(&across, &live, reach, &mut rng, k),
            );
            safe = target;
        }
        let first_within = within.iter().position(|&w| w > 0).expect("contact");
        assert!(
            within.iter().sum::<usize>() > 50,
            "pairs across within reach: {within:?}"
        );
        assert!(
            builds[0] && builds[1..=first_within].contains(&true),
            "builds {builds:?}, pairs within reach {within:?}"
        );
    }

    /// Two sheets 5 cm apart at rest, first with a reach of 2 cm (no pair across is stored),
    /// then with a reach of 8 cm (as after `Solver.set_params`): the lists are built afresh,
    /// and every pair across that a brute-force search finds within the new reach is live.
    #[test]
    fn a_longer_reach_renews_the_build() {
        let side = 6u32;
        let n = side * side;
        let sheets = TestMesh::two_sheets(side, 0.05);
        let (mesh, safe) = (sheets.mesh(), sheets.positions.clone());
        let (_, every) = brute_force_pairs(&mesh, &safe);
        let across = |p: &Pair| (p.v[0] < n) != (p.v[3] < n);
        let allowance = vec![1e-3; safe.len()];
        let (mut cache, mut live) = (PairCache::default(), Vec::new());
        cache.live_pairs(&safe, &safe, &allowance, &mesh, 0.02, &mut live);
        assert!(!cache.pairs.iter().any(|(p, _)| across(p)));
        let renewal = cache.live_pairs(&safe, &safe, &allowance, &mesh, 0.08, &mut live);
        assert_eq!(renewal, Renewal::Built);
        let wanted: Vec<Pair> = every
            .iter()
            .copied()
            .filter(|p| across(p) && p.closest(&safe).separation.norm() < 0.08)
            .collect();
        let missed = wanted.iter().filter(|p| !live.contains(p)).count();
        assert!(wanted.len() > 100, "{} pairs across", wanted.len());
        assert_eq!(
            missed,
            0,
            "{missed} of {} pairs across missed",
            wanted.len()
        );
    }

    /// Two flat sheets 2.5 cm apart, at rest but for a jitter of up to 0.3 mm, while two
    /// vertices of one set off towards the other, faster at every local step (allowances of
    /// 2 mm): they stray beyond their skins while their regions' motions still fit, and the
    /// build is repaired rather than built afresh; after every repair (and build) the stored
    /// pairs are exactly those within their raised limits (brute force), and the live pairs
    /// hold every pair a brute-force search finds within `reach` until the strays are 3 mm
    /// from the other sheet. The live pairs also hold every cached pair whose bounds may come
    /// within reach, before and after the strays' allowances grow by 1 mm and the list is
    /// extended; among them are pairs that repairs added, and the extensions add some (such
    /// pairs are not indexed by vertex, see [`PairCache::extend_live`]).
    #[test]
    fn a_few_strays_repair_the_build_and_miss_no_pair() {
        let mut rng = Rng::new(41);
        let side = 12u32;
        let n = side * side;
        let sheets = TestMesh::two_sheets(side, 0.025);
        let (mesh, mut safe) = (sheets.mesh(), sheets.positions.clone());
        let (_, every) = brute_force_pairs(&mesh, &safe);
        let strays = [n + 5 * side + 5, n + 7 * side + 6];
        let (reach, allowance) = (0.01, vec![0.002; safe.len()]);
        let clamp = vec![1.0; safe.len()];
        let (mut cache, mut live, mut renewals, mut within) =
            (PairCache::default(), Vec::new(), Vec::new(), 0);
        let (mut repaired_live, mut repaired_added) = (0, 0);
        for k in 0..8 {
            let target: Vec<_> = (0..safe.len())
                .map(|i| {
                    let towards = if strays.contains(&(i as u32)) && k >= 1 {
                        -0.0008 * k as f64
                    } else {
                        0.0
                    };
                    safe[i] + Vector3::new(towards, 0.0, 0.0) + rng.vector() * 0.0003
                })
                .collect();
            let renewal = cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live);
            renewals.push(renewal);
            if renewal != Renewal::Kept {
                cache.assert_stores_exactly_the_pairs_within_their_limit(&every, reach, k);
            }
            let moves = Moves::new(&safe, &target, &clamp, &allowance);
            within +=
                moves.assert_live_hold_every_pair_within_reach(&every, &live, reach, &mut rng, k);
            repaired_live += cache.assert_live_hold_every_cached_pair_that_may_come_within(
                &live, &allowance, reach, k,
            );
            let mut grown_allowance = allowance.clone();
            for &v in &strays {
                grown_allowance[v as usize] += 0.001;
            }
            let mut extended = live.clone();
            if let Some(renewal) =
                cache.extend_live(&grown_allowance, &strays, &mesh, reach, &mut extended)
            {
                assert_eq!(renewal, Renewal::Kept, "step {k}: the grown allowances fit");
                cache.assert_live_hold_every_cached_pair_that_may_come_within(
                    &extended,
                    &grown_allowance,
                    reach,
                    k,
                );
                let mut repaired: Vec<Pair> = cache.pairs[cache.arranged..]
                    .iter()
                    .map(|(p, _)| *p)
                    .collect();
                repaired.sort_unstable();
                repaired_added += extended[live.len()..]
                    .iter()
                    .filter(|p| repaired.binary_search(p).is_ok())
                    .count();
            }
            // The next filter starts afresh, as the local step's next refresh would.
            safe = target;
        }
        assert!(within > 100, "the scene has pairs within reach: {within}");
        assert!(
            repaired_live > 0 && repaired_added > 0,
            "repaired pairs that may come within reach: {repaired_live} live, \
             {repaired_added} added by the extensions"
        );
        let (x0, x1) = (safe[strays[0] as usize].x, safe[strays[1] as usize].x);
        assert!(
            (0.0..0.01).contains(&x0) && (0.0..0.01).contains(&x1),
            "the strays came within reach of the other sheet, short of it: {x0}, {x1}"
        );
        assert!(
            renewals.iter().filter(|&&r| r == Renewal::Repaired).count() >= 2,
            "{renewals:?}"
        );
    }

    /// Two sheets 18 mm apart, jittered by up to 0.3 mm, while two vertices of one head for
    /// the other at 3 mm per local step, from the build on (so that the build stores their
    /// pairs with the other sheet): their deviations reach 14 mm and the others' stay near
    /// 3 mm, so the filter's horizon from all but the two (`reach + 2 D + max T`) is less than
    /// half of the one from the farthest (`D` = the largest deviation) and leaves out their
    /// pairs with the other sheet; found by the index by vertex, those that may come within
    /// reach are still live (every cached pair that may, and every pair within reach by brute
    /// force).
    #[test]
    fn a_few_fast_vertices_do_not_make_every_pair_near() {
        let mut rng = Rng::new(47);
        let side = 24u32;
        let n = side * side;
        let sheets = TestMesh::two_sheets(side, 0.018);
        let (mesh, rest) = (sheets.mesh(), sheets.positions.clone());
        let (_, every) = brute_force_pairs(&mesh, &rest);
        let strays = [n + 9 * side + 9, n + 14 * side + 12];
        assert_eq!((OUTLYING_SHARE * f64::from(2 * n)) as usize, strays.len());
        let (reach, allowance) = (0.008, vec![0.002; rest.len()]);
        let clamp = vec![1.0; rest.len()];
        let (mut cache, mut live, mut within) = (PairCache::default(), Vec::new(), 0);
        let (mut safe, mut beyond_live) = (rest.clone(), 0);
        for k in 0..4 {
            let target: Vec<_> = (0..rest.len())
                .map(|i| {
                    let towards = if strays.contains(&(i as u32)) {
                        -0.003 * (k + 1) as f64
                    } else {
                        0.0
                    };
                    rest[i] + Vector3::new(towards, 0.0, 0.0) + rng.vector() * 0.0003
                })
                .collect();
            let renewal = cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live);
            assert_eq!(renewal == Renewal::Built, k == 0, "step {k}: {renewal:?}");
            let (near, outlying) = cache.near(reach);
            assert_eq!(outlying, strays, "step {k}");
            let farthest = cache.deviation.iter().copied().fold(0.0, f64::max);
            let near_by_farthest = cache.order.within(reach + 2.0 * farthest + cache.apart);
            if k >= 2 {
                assert!(
                    2 * near < near_by_farthest,
                    "step {k}: {near} pairs near, {near_by_farthest} by the farthest deviation"
                );
            }
            let mut live_sorted = live.clone();
            live_sorted.sort_unstable();
            beyond_live += cache.pairs[near..cache.arranged]
                .iter()
                .filter(|(p, _)| live_sorted.binary_search(p).is_ok())
                .count();
            cache.assert_live_hold_every_cached_pair_that_may_come_within(
                &live, &allowance, reach, k,
            );
            let moves = Moves::new(&safe, &target, &clamp, &allowance);
            within +=
                moves.assert_live_hold_every_pair_within_reach(&every, &live, reach, &mut rng, k);
            safe = target;
        }
        assert!(within > 100, "the scene has pairs within reach: {within}");
        assert!(
            beyond_live > 0,
            "live pairs beyond the horizon: {beyond_live}"
        );
    }

    /// One edge of the rolled-up grid swinging fast (up to 0.05 m per local step, the rest
    /// jittered by up to 3 mm): the live pairs hold every pair within reach (brute force),
    /// the moving vertices and those within `SKIN_RINGS` rings of them (a ring is a column of
    /// the grid) get skins for the motion, and the vertices of regions away from it (more than
    /// a quarter of the sheet) keep the small skins of their own jitter.
    #[test]
    fn a_swinging_edge_leaves_the_rest_of_the_sheet_a_small_skin() {
        let mut rng = Rng::new(43);
        let n = 24;
        let rolled = TestMesh::rolled(n, 0.03, &mut rng);
        let mesh = rolled.mesh();
        let mut safe = rolled.positions.clone();
        let (_, every) = brute_force_pairs(&mesh, &safe);
        let (reach, allowance) = (0.02, vec![0.001; safe.len()]);
        let clamp = vec![1.0; safe.len()];
        // Column `i` of the grid: the edge i = 0 swings, columns 0..=3 are within 3 rings.
        let column = |v: usize| v % n as usize;
        let (mut cache, mut live, mut within) = (PairCache::default(), Vec::new(), 0);
        for k in 0..4 {
            let target: Vec<_> = (0..safe.len())
                .map(|v| {
                    let swing = if column(v) == 0 { 0.05 } else { 0.0 };
                    safe[v] + Vector3::new(0.0, 0.0, swing) + rng.vector() * 0.003
                })
                .collect();
            if cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live)
                == Renewal::Built
            {
                // A vertex at rest strays from the mean of a region at rest by at most twice
                // the jitter; one whose regions' halos hold a swinging vertex (within the
                // rings its skin spreads over) strays by their share of the swing.
                let jitter = SKIN_MOVES * 2.0 * 0.003 * 3f64.sqrt() + 0.001 + 0.25 * reach;
                let regions = &cache.regions;
                let swinging: Vec<u32> = (0..safe.len())
                    .filter(|&v| column(v) == 0)
                    .flat_map(|v| regions.holding(v).to_vec())
                    .collect();
                let mut near_swing: Vec<bool> = (0..safe.len())
                    .map(|v| regions.holding(v).iter().any(|p| swinging.contains(p)))
                    .collect();
                for _ in 0..SKIN_RINGS {
                    let before = near_swing.clone();
                    for t in mesh.triangles {
                        if t.iter().any(|&v| before[v as usize]) {
                            t.iter().for_each(|&v| near_swing[v as usize] = true);
                        }
                    }
                }
                let away = near_swing.iter().filter(|&&n| !n).count();
                assert!(away > safe.len() / 4, "{away} vertices away from the swing");
                for (v, &r) in cache.skin.iter().enumerate() {
                    if column(v) <= SKIN_RINGS {
                        let swung = SKIN_MOVES * 0.04;
                        assert!(
                            r > swung,
                            "step {k}: vertex {v} swings or is near, skin {r}"
                        );
                    } else if !near_swing[v] {
                        assert!(r < jitter, "step {k}: vertex {v} at rest, skin {r}");
                    }
                }
            }
            let moves = Moves::new(&safe, &target, &clamp, &allowance);
            within +=
                moves.assert_live_hold_every_pair_within_reach(&every, &live, reach, &mut rng, k);
            safe = target;
        }
        assert!(within > 100, "the scene has pairs within reach: {within}");
    }

    /// Growing the allowances of some vertices and extending the live list gives the list a
    /// full filter gives for the grown allowances, whether the build still covers them (a
    /// few vertices by a few millimetres), is repaired for them (one vertex by 0.3 m: the
    /// extension repairs, as the filter does) or is built afresh (a third of the vertices by
    /// 0.3 m, too many to repair: the extension declines and the filter builds).
    #[test]
    fn extending_the_live_pairs_equals_filtering_them_afresh() {
        let mut rng = Rng::new(41);
        let rolled = TestMesh::rolled(12, 0.03, &mut rng);
        let mesh = rolled.mesh();
        let safe = rolled.positions.clone();
        let (_, all_pairs) = brute_force_pairs(&mesh, &safe);
        let reach = 0.02;
        let target: Vec<_> = safe.iter().map(|p| p + rng.vector() * 0.004).collect();
        let mut allowance = vec![0.001; safe.len()];
        let (mut extended, mut afresh) = (PairCache::default(), PairCache::default());
        let (mut by_extension, mut by_filter) = (Vec::new(), Vec::new());
        extended.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut by_extension);
        afresh.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut by_filter);
        let first = by_extension.len();
        use Renewal::{Built, Kept, Repaired};
        for (round, (every, by, expected)) in [
            (7, 0.004, Kept),
            (5, 0.004, Kept),
            (1000, 0.3, Repaired),
            (3, 0.3, Built),
        ]
        .into_iter()
        .enumerate()
        {
            let grown: Vec<u32> = (0..safe.len() as u32).step_by(every).collect();
            for &v in &grown {
                allowance[v as usize] += by;
            }
            let renewal = extended
                .extend_live(&allowance, &grown, &mesh, reach, &mut by_extension)
                .unwrap_or_else(|| {
                    extended.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut by_extension)
                });
            let renewal_afresh =
                afresh.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut by_filter);
            assert_eq!([renewal, renewal_afresh], [expected; 2], "round {round}");
            if renewal == Repaired {
                extended
                    .assert_stores_exactly_the_pairs_within_their_limit(&all_pairs, reach, round);
            }
            let sorted = |pairs: &[Pair]| {
                let mut pairs = pairs.to_vec();
                pairs.sort_unstable();
                pairs
            };
            assert_eq!(sorted(&by_extension), sorted(&by_filter), "round {round}");
        }
        assert!(by_extension.len() > first, "the growth made pairs live");
    }

    /// Local steps as the solver makes them, on a rolled-up sheet falling as a whole while a
    /// strip of it swings (several local steps per time step, each starting where the last
    /// one's target was, the target moving a little between them, some allowances growing):
    /// the live pairs hold every pair that comes within reach (brute force), more than a
    /// third of the filters get away without a sweep, and they keep at most half again as
    /// many pairs live as a sweep afresh.
    #[test]
    fn refiltering_since_the_sweep_holds_every_pair_within_reach() {
        let mut rng = Rng::new(17);
        let rolled = TestMesh::rolled(11, 0.02, &mut rng);
        let mesh = rolled.mesh();
        let mut safe = rolled.positions.clone();
        let n = safe.len();
        let (_, every) = brute_force_pairs(&mesh, &safe);
        let reach = 0.012;
        let clamp = vec![1.0; n];
        let (mut cache, mut fresh) = (PairCache::default(), PairCache::default());
        let (mut live, mut afresh) = (Vec::new(), Vec::new());
        let (mut refilters, mut sweeps, mut calls, mut within) = (0, 0, 0, 0);
        for step in 0..8 {
            let fall = Vector3::new(0.0, 0.0, -0.004);
            let swing = |i: usize| if i % 11 < 2 { 0.006 * step as f64 } else { 0.0 };
            let mut target: Vec<_> = safe
                .iter()
                .enumerate()
                .map(|(i, p)| p + fall + Vector3::new(swing(i), 0.0, 0.0))
                .collect();
            let mut allowance = vec![0.0005; n];
            for local in 0..4 {
                if local > 0 {
                    safe = target.clone();
                }
                for y in target.iter_mut() {
                    *y += rng.vector() * 1e-3;
                }
                if local == 2 {
                    for a in allowance.iter_mut().step_by(9) {
                        *a += 0.0005;
                    }
                }
                let swept = cache.sweeps();
                let renewal = cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live);
                let swept = cache.sweeps() - swept;
                assert!(swept <= 1, "{swept} sweeps in one filter");
                // A build leaves no sweep to refilter from.
                assert!(
                    renewal != Renewal::Built || swept == 1,
                    "a build without a sweep"
                );
                let moves = Moves::new(&safe, &target, &clamp, &allowance);
                within += moves.assert_live_hold_every_pair_within_reach(
                    &every, &live, reach, &mut rng, calls,
                );
                fresh.sweep.valid = false;
                fresh.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut afresh);
                assert!(
                    live.len() <= afresh.len() * 3 / 2 + 10,
                    "step {step}, local step {local}: {} live, {} afresh",
                    live.len(),
                    afresh.len()
                );
                calls += 1;
                sweeps += swept;
                refilters += 1 - swept;
            }
            safe = target;
        }
        assert!(within > 1000, "pairs came within reach: {within}");
        assert!(refilters > calls / 3, "{refilters} refilters of {calls}");
        assert!(sweeps > 2, "{sweeps} sweeps");
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
            let moves = Moves::new(&safe, &target, &clamp, &allowance);
            within +=
                moves.assert_live_hold_every_pair_within_reach(&every, &live, reach, &mut rng, k);
            safe = target;
        }
        assert!(within > 100, "the scene has pairs within reach: {within}");
        use Renewal::{Built, Kept};
        assert_eq!(builds, [Built, Kept, Kept, Built, Kept]);
        // Another mesh (self-contact off) forces a build and finds nothing.
        let mesh = ContactMesh {
            self_contact: &[false],
            ..mesh
        };
        assert_eq!(
            cache.live_pairs(&safe, &safe, &allowance, &mesh, reach, &mut live),
            Renewal::Built
        );
        assert!(live.is_empty() && cache.candidates() == 0);
    }
}
