//! The contact local step: Algorithm 2 of Lu et al. 2023 (section 6).
//!
//! Given the last intersection-free positions `z^{k-1}` ("safe") and the positions `y^k` after
//! a global step, it looks for `z` near `y^k` that keeps every pair of primitives apart,
//! minimising eq. 47, `sum_i |z_i - y_i^k|^2 / 2 + mu sum_c B(f(d_c) - xi)`, by gradient descent
//! (with the proximal term in a metric `W_i` per vertex, `(z_i - y_i^k)^T W_i (z_i - y_i^k) / 2`,
//! by default the global step's: see [`ProximalMetric`]; the paper's is the identity):
//!
//! 1. broad phase: candidate triangle pairs, expanded into 6 point-triangle and 9 edge-edge
//!    primitive pairs per triangle pair (deduplicated), kept from one local step to the next
//!    while they provably contain every pair that can come within the barrier's reach, and
//!    filtered down to those (see [`super::pair_cache`]);
//! 2. per iteration `m`: additive CCD of every primitive pair between `z^{k-1}` and `z^m`
//!    (lines 4-12), except the pairs whose distance at `z^{k-1}` minus the largest moves of
//!    their two primitives stays above the CCD's separation (they cannot reach it); a vertex
//!    whose smallest time of impact `t_i` is in `(threshold, 1)` is clamped to
//!    `z^{k-1} + t_i (z^m - z^{k-1})` (lines 13-18);
//! 3. distances and closest-point weights of the pairs (lines 19-23), and the descent
//!    direction of eq. 49, `g_i = -mu sum_c m_c alpha_c^i B'(f(d_c) - xi) n_c + W_i (y_i^k - z_i)`,
//!    where `alpha_c^i` is vertex `i`'s barycentric weight in pair `c` and `n_c` the unit
//!    separation; following the paper, the barrier slope is taken at the rescaled gap of
//!    eq. 51 so that it stays bounded, `|B'| <= |B'(eps xi)|`. `m_c` (not in the paper) is 1
//!    except for edge-edge pairs within [`ContactParams::parallel_angle`] of parallel at the
//!    safe positions, which fade out ([`super::parallel_fade`], IPC's mollifier, held
//!    through the local step);
//! 4. a step that keeps every move below `eps xi` ([`DescentStep`]): either eq. 53's
//!    `lambda = min(1, eps xi / (mu alpha_0 ceil|B'| + D))` for every vertex, with `alpha_0` the
//!    largest `sum_c alpha_c^i` and `D` the largest `|y_i^k - z_i|` of this iteration, or (the
//!    default) a step per vertex scaled by the barrier's curvature along the contact normals
//!    there; stop when the largest move is below the stopping distance
//!    ([`ContactParams::stop_distance`]: [`STOP_FRACTION`] `eps xi`, less where the solver's
//!    tolerance asks it) or after `max_iters` iterations. A move shorter than
//!    [`SETTLED_SHARE`] of the stopping distance is not taken
//!    (not in the paper): the closest points and barrier terms of the pairs none of whose
//!    vertices moved are kept, and the sums of the vertices none of whose pairs changed
//!    ([`super::barrier_push`]): an iteration's distances and barrier terms cost what its
//!    moving vertices' pairs cost (its cheap scans over every pair and vertex remain). With
//!    [`DescentStep::Uniform`] a vertex whose `lambda |g_i|` is that short stays put instead
//!    of creeping.
//!    A vertex whose move points against its last one has overshot, and its moves are halved
//!    from then on for the rest of the local step (not in the paper). The step rules bound
//!    the barrier's curvature along the contact normals, but the closest points of nearly
//!    parallel edges jump along them as the edges move (stacked cloth layers are full of such
//!    pairs), and so does the push on their vertices: without
//!    the halving a few of them go back and forth for good, and every local step runs to its
//!    iteration cap.
//!    The halving damps such a jump but cannot remove it: the measure then stalls at about
//!    the jump (a micrometre), which the fade of nearly parallel pairs (`m_c` above) removes.
//!    By default the descent starts from the global step's result plus the last local step's
//!    move ([`ContactParams::warm_start`]), not from the result alone. After every move a
//!    vertex is taken out of the colliders (not in the paper), on the side its move came from
//!    and in the metric of its move, so
//!    that a membrane pressed onto a collider slides along it to the minimum of eq. 47 on
//!    its surface (exactly on a plane; on a curved surface up to its curvature over the last
//!    move, as the surface is linearised where the move ends); the curvature rule's bound then
//!    cuts the move taken, and the halving compares moves taken.
//!
//! A final guarantee pass (not in the paper, which leaves vertices with a small time of impact
//! unclamped): additive CCD from `z^{k-1}` to `z` once more, with the pair's separation floor
//! `min(eps xi, 0.9 d(z^{k-1}))`, clamping every vertex of a colliding pair to its time of
//! impact (repeated until no pair collides; after [`CLAMP_PASSES`] passes the remaining
//! vertices fall back to `z^{k-1}`). So if `z^{k-1}` is free of intersections, so is `z`, and
//! pairs that were `eps xi` apart stay so.

mod descent;
mod friction;
mod guarantee;
mod live_pairs;
mod moves;
mod params;
mod rest_gaps;
mod stats;
#[cfg(test)]
mod tests;
mod workspace;

pub use descent::resolve_contacts;
pub use moves::PushOut;
pub use params::{
    ContactParams, DescentStep, ProximalMetric, ProximalWeights, CLAMP_PASSES, D_HAT_PER_THICKNESS,
    SETTLED_SHARE, STOP_FRACTION, TOL_SHARE,
};
pub use rest_gaps::{SavedRestGap, SavedRestGaps};
pub use stats::ContactStats;
#[cfg(test)]
pub use workspace::Piece;
pub use workspace::Workspace;

use rayon::prelude::*;

/// Sets `v` to `n` copies of `value`, reusing its allocation; the entries it keeps are
/// overwritten in parallel (a local step refills about ten per-vertex buffers, each a pass
/// over memory that one thread alone is slow to write).
fn refill<T: Clone + Send + Sync>(v: &mut Vec<T>, n: usize, value: T) {
    v.truncate(n);
    v.par_iter_mut()
        .with_min_len(REFILL_GRAIN)
        .for_each(|x| x.clone_from(&value));
    v.resize(n, value);
}

/// Least entries per task of [`refill`].
const REFILL_GRAIN: usize = 4096;
