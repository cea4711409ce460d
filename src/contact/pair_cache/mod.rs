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
//!   triangles only. A build is often forced by a handful of vertices straying by a fraction
//!   of a millimetre; a repair defers it until some region pair outgrows its skin, which only
//!   a build puts right. The pairs a repair adds (few) go after the build's (millions), which
//!   keep their order, index and sweep, and every filter looks at each of them: arranging
//!   and indexing all the pairs afresh would make a repair cost a good part of a build.
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
//!   (ski rental): as a sweep's positions fall behind, its filters cost more and more (the
//!   first global iterations of a step can move a body's parts millimetres apart, so that
//!   every later filter of the step looks again at a large share of the near pairs).

mod build;
mod filter;
mod packed_shift;
mod patch_groups;
mod repair;
#[cfg(test)]
mod tests;

use nalgebra::Vector3;
use rayon::prelude::*;

use super::broad_phase::{BroadPhase, ContactMesh};
use super::distance_order::DistanceOrder;
use super::patches::Patches;
use super::primitive_pairs::{Owners, Pair};
use super::regions::Regions;
use super::sweep::{displacements, Sweep, NO_BODY};
use packed_shift::PackedShift;
use patch_groups::PatchGroups;

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
    /// others (few: only the pairs of the at most [`repair::MOST_RAISED`] of the vertices
    /// whose skins repairs raised).
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
    /// `shift`, the allowances and the patches as the last sweep read them.
    packed_shift: PackedShift,
    /// The build's arranged pairs by the patches of their sides, with the last sweep's
    /// slacks (grouped at the first sweep of a build).
    patch_groups: PatchGroups,
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

    /// Writes `[s_i - r_i, y_i - r_i]` into `shift` and measures the regions' common
    /// motions, the means of `shift` over their halos (any choice is correct; the means keep
    /// the vertices' deviations small).
    fn measure_motion(&mut self, safe: &[Vector3<f64>], target: &[Vector3<f64>]) {
        displacements(safe, target, &self.reference, &mut self.shift);
        self.regions.measure(&self.shift);
    }
}

/// Whether `x < limit`, NaN counting as below (a NaN bound keeps its pair).
fn below(x: f64, limit: f64) -> bool {
    x < limit || x.is_nan() || limit.is_nan()
}
