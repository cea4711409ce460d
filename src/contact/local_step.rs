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
//!    the halving a few of them go back and forth for good, and every local step ran to its
//!    cap (640 local iterations in a step of the three layers over the ball, 103 with it).
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

use std::time::Instant;

use nalgebra::Vector3;
use rayon::prelude::*;

use super::barrier::Barrier;
use super::barrier_push::{BarrierPush, VertexSums};
use super::broad_phase::ContactMesh;
use super::ccd::AdditiveCcd;
use super::distance::Closest;
use super::pair_cache::{PairCache, Renewal};
use super::parallel_fade::{default_parallel_angle, sin2_limit};
use super::primitive_pairs::Pair;
use crate::error::{check_param, invalid, Result};
use crate::symmetric::SymmetricMatrix3;

/// How far the descent of the local step moves each vertex along its direction `g_i` of eq. 49.
/// Both keep every move below `eps xi`, so the CCD and the guarantee pass see the same kind of
/// path; they differ in how fast the descent reaches the minimum of eq. 47.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DescentStep {
    /// Eq. 53 as in the paper: one `lambda` for all vertices, from the barrier's steepest
    /// possible slope `ceil|B'| = |B'(eps xi)|` and the largest distance to the target (in a
    /// metric `W`, `z_i += lambda W_i^-1 g_i` with the slope's bound times the largest
    /// `|W_i^-1|`, so that no move exceeds `eps xi` and none overshoots its target). Where
    /// some pair is close (its slope bound is thousands of times the proximal term's) every
    /// vertex creeps: a local step then ends at its iteration cap far from the minimum, and
    /// what it returns depends on the cap.
    Uniform,
    /// Per vertex, `z_i += (W_i + K_i)^-1 g_i`, cut to length `eps xi`, with
    /// `K_i = mu sum_c m_c B''(x_c) f'(d_c) |alpha_c^i| (sum_j |alpha_c^j|) n_c n_c^T`
    /// (dimensionless, 3 x 3): the barrier's curvature along each pair's normal `n_c` (`x_c`
    /// the rescaled gap, `f'` the rescale's slope, `m_c` the pair's fade, see
    /// [`ContactParams::parallel_angle`]), with the pair's weights summed by rows (a
    /// block Gershgorin bound: `(sum_j alpha_j n . u_j)^2 <= sum_j |alpha_j| sum_j |alpha_j|
    /// (n . u_j)^2` by Cauchy-Schwarz), so that the block-diagonal matrix of the `W_i + K_i`
    /// bounds from above the Hessian of eq. 47 with the barrier taken along the normals
    /// (their difference is positive semi-definite). A block-Jacobi-preconditioned descent:
    /// vertices away from contact go straight to their target (up to `eps xi` per iteration),
    /// vertices in contact take a step of about the distance to the barrier's balance point
    /// along the normals and move freely along the contact (a scalar `1 + trace K_i` would slow
    /// their sliding as much as their approach, and a sheet resting on another would hardly
    /// slide at all).
    Curvature,
}

/// The metric `W_i` of eq. 47's proximal term, `sum_i (z_i - y_i^k)^T W_i (z_i - y_i^k) / 2`,
/// which the local step minimises with the barrier.
///
/// The global step is a Jacobi sweep, `y^k = y + D^-1 r(y)` with `D` the block diagonal of
/// eq. 25 (`D_i = m_i I + h^2 sum (C_i + C_j)`, kg), a step on the implicit Euler energy `E` in
/// the metric `D` (`-r` is the gradient of `h^2 E`). At a fixed point of the two steps the local
/// step's move balances the global step's, `W_i^-1 mu grad_i B = D_i^-1 r_i`, so the contact
/// force on vertex `i` is `-r_i / h^2 = -D_i W_i^-1 mu grad_i B / h^2` (N).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProximalMetric {
    /// `W_i = I`, eq. 47 as in the paper: the contact force on each vertex is scaled by its own
    /// `D_i`. The forces of a pair then do not cancel where its vertices' `D_i` differ, and
    /// contact makes momentum: a light sheet meeting one eight times heavier pushes it eight
    /// times harder than it is pushed, and both nearly stop (`tests/test_contact.py`).
    Identity,
    /// `W_i = D_i / d` with `d` the mean of `trace(D_i) / 3` over the free vertices of every
    /// body (kg), taken afresh at each local step (not in the paper): the contact force is
    /// `-d mu grad_i B / h^2`, the negative gradient of the energy `d mu B / h^2`, so a pair's
    /// forces cancel and contact conserves momentum, and the fixed points are the stationary
    /// points of `E + d mu B / h^2`. The barrier's weight is then effectively `d mu`: along a
    /// contact normal `n` it is `d / (n^T D_i n)` times the paper's (with the default tangent
    /// preconditioner `D_i` is stiffer in the membrane's plane than along its normal, so faces
    /// pressed together feel a stronger barrier than in the paper). Exact for the plain SISSM
    /// step; with `inner_iters > 1` or `Method::Descent` the global step's metric is not `D`,
    /// and `W` only approximates it.
    Jacobi,
}

/// Contact parameters (SI units). Defaults follow Table 1 of the paper (cloths over a ball):
/// `xi = 1.5 mm`, `d_hat = 4 xi`, `eps = 0.1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactParams {
    /// Contact thickness `xi` (m): mid-surfaces of two primitives stay at least `xi` apart in
    /// the barrier's view, and never closer than `eps xi`.
    pub thickness: f64,
    /// Barrier range `d_hat` (m), measured on the gap `f(d) - xi`.
    pub d_hat: f64,
    /// Minimal separation multiplier `eps` (eq. 51): also caps every descent move at `eps xi`.
    pub eps: f64,
    /// Barrier weight `mu` of eq. 47 (dimensionless: the barrier is in m^2 like the proximal
    /// term). Not in Table 1; 1 balances the two terms of eq. 47 at gaps of about `d_hat / 2`.
    pub weight: f64,
    /// Cap on descent iterations per local step.
    pub max_iters: usize,
    /// The descent's step rule.
    pub step: DescentStep,
    /// Times of impact at or below this are not clamped inside the descent (avoids the
    /// sticking of clamping at tiny times; Algorithm 2, line 15). In `[0, 1)`.
    pub toi_threshold: f64,
    /// The additive CCD (`s = 0.1`, `t_c = 0.95` as in the paper).
    pub ccd: AdditiveCcd,
    /// Start the descent from `y_i^k + (z_i - y_i^k)_last` instead of the paper's `y_i^k`
    /// (Algorithm 2, line 2): the move the last local step (of the same vertex count) made at
    /// vertex `i`, where the barrier pushed it there and the final clamp did not move it
    /// (elsewhere no offset). Where the contacts persist the descent then starts near its
    /// minimum, and the local steps of a time step continue one another's descent instead of
    /// repeating it: at the global iteration's fixed point the local step is solved as well
    /// as the iteration is, not only to its stopping test. The offset is a move like a descent
    /// move (drift, deviation, CCD from the safe positions), so every guarantee holds.
    pub warm_start: bool,
    /// Fade angle `theta_0` (radians, in `[0, pi/2)`): an edge-edge pair whose edges are
    /// closer to parallel than this at the local step's safe positions enters the barrier
    /// with the weight `r (2 - r)`, `r = sin^2 theta / sin^2 theta_0`, 0 for parallel edges
    /// (IPC's edge-edge mollifier, not in the paper; see [`super::parallel_fade`]). Without it
    /// (0) the local step's measure stalls at about a micrometre on stacked layers, as the
    /// closest points of nearly parallel edges jump. The default, `asin(sqrt(1e-3))` (1.8
    /// degrees), is IPC's.
    pub parallel_angle: f64,
    /// The metric of eq. 47's proximal term. Read by the solver, which computes the weights
    /// and passes them to [`project`].
    pub proximal: ProximalMetric,
}

impl Default for ContactParams {
    fn default() -> Self {
        let thickness = 1.5e-3;
        Self {
            thickness,
            d_hat: 4.0 * thickness,
            eps: 0.1,
            weight: 1.0,
            max_iters: 32,
            step: DescentStep::Curvature,
            toi_threshold: 0.1,
            ccd: AdditiveCcd::default(),
            warm_start: true,
            parallel_angle: default_parallel_angle(),
            proximal: ProximalMetric::Jacobi,
        }
    }
}

impl ContactParams {
    /// Checks every parameter, naming the first bad one.
    pub fn validate(&self) -> Result<()> {
        check_param(
            "thickness",
            self.thickness,
            |v| v > 0.0,
            "a finite thickness > 0 m",
        )?;
        check_param("d_hat", self.d_hat, |v| v > 0.0, "a finite range > 0 m")?;
        check_param("eps", self.eps, |v| v > 0.0 && v < 1.0, "in (0, 1)")?;
        check_param("weight", self.weight, |v| v > 0.0, "a finite weight > 0")?;
        check_param(
            "toi_threshold",
            self.toi_threshold,
            |v| (0.0..1.0).contains(&v),
            "in [0, 1)",
        )?;
        check_param("ccd s", self.ccd.s, |v| v > 0.0 && v < 1.0, "in (0, 1)")?;
        check_param(
            "ccd t_c",
            self.ccd.t_c,
            |v| v > 0.0 && v <= 1.0,
            "in (0, 1]",
        )?;
        check_param(
            "parallel_angle",
            self.parallel_angle,
            |v| (0.0..std::f64::consts::FRAC_PI_2).contains(&v),
            "an angle in [0, pi/2) radians",
        )?;
        if self.max_iters < 1 {
            return Err(invalid!(
                "contact max_iters must be >= 1, got {}",
                self.max_iters
            ));
        }
        Ok(())
    }

    fn barrier(&self) -> Barrier {
        Barrier {
            thickness: self.thickness,
            d_hat: self.d_hat,
            eps: self.eps,
        }
    }

    /// The local step's stopping distance (m) for the solver's tolerance `tol` (m; 0: the
    /// solver runs a fixed number of iterations): the local step stops once its largest move
    /// is below [`STOP_FRACTION`] `eps xi`, or below [`TOL_SHARE`] `tol` where `tol > 0` and
    /// that is smaller.
    pub fn stop_distance(&self, tol: f64) -> f64 {
        let own = STOP_FRACTION * self.eps * self.thickness;
        if tol > 0.0 {
            own.min(TOL_SHARE * tol)
        } else {
            own
        }
    }
}

/// A local step stops once its largest move is below this fraction of `eps xi`, or below
/// [`TOL_SHARE`] of the solver's tolerance where that is smaller
/// ([`ContactParams::stop_distance`]).
pub const STOP_FRACTION: f64 = 1e-2;

/// The share of the solver's tolerance `tol` that bounds the local step's stopping distance.
/// The local step's result is only as exact as its stopping test, and an error of its size
/// enters every global iteration: with a stop above about `tol / 2` the global iteration can
/// go on at `tol` without converging. Three 16 x 16 layers of 0.5 m over the ball at `tol =
/// 1e-6 m` (`xi = 1.5 mm`, so `STOP_FRACTION eps xi = 1.5 um`), steps of 500 run to the cap
/// of 200 iterations: 36 with the stop at 1.5 um, 11 at `tol`, 2 at `0.5 tol`, none at
/// `0.3 tol` (at most 11 iterations) or `0.15 tol` (at most 6). At the paper scenes' `tol =
/// 1e-4 m` the fraction of `eps xi` is the smaller one, so they are not affected. The cost of
/// a tight `tol`: more local iterations (19 per step median against 11 above), fewer settled
/// vertices ([`SETTLED_SHARE`] follows the stop, which it must not exceed), and where the
/// local step's measure cannot fall below `tol / 5` (nearly parallel edges without the fade,
/// see [`ContactParams::parallel_angle`]) every local step runs to `max_iters`.
pub const TOL_SHARE: f64 = 0.2;

/// A descent move shorter than this share of the stopping distance is not taken: the vertex
/// stays, and
/// the pairs none of whose vertices moved keep their closest points and barrier terms, so an
/// iteration's distances and terms cost what its moving vertices' pairs cost (not in the
/// paper). The stopping test still counts such a move. A cost trade-off: late in a local step
/// most vertices of stacked layers move by less, though each by a few nanometres (six layers
/// of 200 x 200 landing on the floor, step 459 from a saved state: of the 122K vertices in
/// contact, 90-100K move by more than [`STOP_FRACTION`] `eps xi` in the first local step's
/// tenth iteration, 5-20K in the later local steps'; the step's descent took 147 s before,
/// 101 s with this and the kept sums of [`super::barrier_push`], one run each).
/// With the stopping distance itself the vertices that slide by small moves stop short (a
/// triangle pressed along a floor by a slanted roof keeps 1.5 times the imbalance its test
/// allows).
pub const SETTLED_SHARE: f64 = 0.25;

/// Passes of the final clamp before the remaining colliding vertices fall back to safety.
pub const CLAMP_PASSES: usize = 16;

/// The first allowance `A_i` of every vertex (see [`super::pair_cache`]), in descent moves of
/// `eps xi`: the live pairs cover iterates within it of the global step's result, and are
/// refreshed (the allowance raised by the deviation) when a vertex goes further. A cost
/// trade-off only: two primitives that keep their places relative to each other stay out of
/// the live list while their distance exceeds the reach by twice the allowance (a flat sheet
/// of the paper's cloth at 200 x 200 keeps its own diagonal pairs 0.87 mm beyond the reach,
/// about six moves of `eps xi`), and a vertex the descent moves `k` times brings about
/// `log2 k` refreshes.
const FIRST_ALLOWANCE: f64 = 1.0;

/// The allowance a vertex starts a local step with, in deviations it reached in the last one
/// (see [`LivePairs::start`]). A cost trade-off only: with 1, cloth folding on the floor at
/// 200 x 200 (steps 472-474 from a saved state, alternating runs) refreshed the live list 55-64
/// times per step, most of them growing the same hundred vertices again, each local step;
/// with 2, 27-30 times, and the steps took 7.3 s instead of 8.6-10.6 s. Draping over the ball
/// (steps 402-404) is unchanged.
const CARRIED_DEVIATION: f64 = 2.0;

/// The largest shift of a vertex's safe position or target since the last filter, as a share
/// of its allowance, with which a local step keeps the live pairs as they are (see
/// [`LivePairs::start`]): the rest of the allowance is room for its own moves.
const REUSE_SHIFT: f64 = 0.5;

/// The largest share of the vertices that may shift by more than [`REUSE_SHIFT`] of their
/// allowance for a local step to keep the live pairs, adding those vertices' pairs: on the three
/// layers over the ball, a few to a hundred of their 120K vertices stop the reuse of the late
/// global iterations' local steps otherwise.
const REUSE_STRAYS: f64 = 0.01;

/// What one local step did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ContactStats {
    /// Candidate triangle pairs of the broad phase's last build (see [`super::pair_cache`]).
    pub candidate_pairs: usize,
    /// Triangle pairs of that build whose inflated boxes overlap (before the distance test
    /// that leaves the candidates).
    pub box_pairs: usize,
    /// Primitive pairs of the broad phase's last build, with those repairs added since (the
    /// pairs each filter of the live list chooses from; largest).
    pub cached_pairs: usize,
    /// Primitive pairs that may come within the barrier's reach (the live pairs).
    pub primitive_pairs: usize,
    /// Primitive pair CCD queries (descent and guarantee pass).
    pub ccd_queries: usize,
    /// Broad phase builds (the others reused the last build's pairs).
    pub broad_phase_builds: usize,
    /// Repairs of the last build for a few vertices that strayed beyond their skins (see
    /// [`super::pair_cache`]), each instead of a build.
    pub cache_repairs: usize,
    /// Filterings of the cached pairs into the live list and additions to it (at the start of
    /// a local step unless the list is kept (`LivePairs::start`), and each time a vertex
    /// outgrows its allowance).
    pub live_refreshes: usize,
    /// Those of the filterings that were sweeps: each looked at every cached pair near
    /// enough afresh; the others looked again only at the pairs whose bound may have fallen
    /// below the reach since the last sweep (see [`super::sweep`]).
    pub sweeps: usize,
    /// Primitive pairs within the barrier's reach at the end (faded ones included).
    pub active_pairs: usize,
    /// Descent iterations.
    pub iterations: usize,
    /// Vertices clamped by the final guarantee pass.
    pub clamped: usize,
    /// Milliseconds in the broad phase (with the live pairs' distances at the safe positions,
    /// which prune the CCD and the distances), the CCD and the descent (distances and
    /// updates).
    pub broad_phase_ms: f64,
    pub ccd_ms: f64,
    pub descent_ms: f64,
}

impl ContactStats {
    /// Sums the counts and times of two local steps (active pairs: the later one's; box,
    /// candidate, cached and primitive pairs: the larger).
    pub fn accumulate(&mut self, other: &ContactStats) {
        self.candidate_pairs = self.candidate_pairs.max(other.candidate_pairs);
        self.box_pairs = self.box_pairs.max(other.box_pairs);
        self.cached_pairs = self.cached_pairs.max(other.cached_pairs);
        self.primitive_pairs = self.primitive_pairs.max(other.primitive_pairs);
        self.ccd_queries += other.ccd_queries;
        self.broad_phase_builds += other.broad_phase_builds;
        self.cache_repairs += other.cache_repairs;
        self.live_refreshes += other.live_refreshes;
        self.sweeps += other.sweeps;
        self.active_pairs = other.active_pairs;
        self.iterations += other.iterations;
        self.clamped += other.clamped;
        self.broad_phase_ms += other.broad_phase_ms;
        self.ccd_ms += other.ccd_ms;
        self.descent_ms += other.descent_ms;
    }
}

/// The local step's buffers, owned by the caller and kept between calls (one per body list):
/// once they have grown to the scene's size, a local step allocates nothing.
#[derive(Default)]
pub struct Workspace {
    live: LivePairs,
    /// `y^k`, the target of the proximal term.
    target: Vec<Vector3<f64>>,
    /// Per vertex: total distance moved by the descent (m).
    drift: Vec<f64>,
    /// Per vertex: `sum_c |alpha_c^i|` of eq. 53.
    alpha: Vec<f64>,
    /// Per vertex: the barrier curvature `K_i` of [`DescentStep::Curvature`].
    curvature: Vec<SymmetricMatrix3<f64>>,
    /// Per vertex: moved since the last CCD.
    changed: Vec<bool>,
    /// Per vertex: moved since its pairs' closest points were last evaluated.
    unmeasured: Vec<bool>,
    /// Per pair: its closest points were evaluated afresh at the last evaluation.
    fresh: Vec<bool>,
    /// Per vertex: smallest time of impact.
    vertex_toi: Vec<f64>,
    /// Per vertex: clamped by the final guarantee pass.
    clamped: Vec<bool>,
    /// Per pair: time of impact.
    toi: Vec<Option<f64>>,
    /// Per pair: within `(1 + 4 eps) xi` at the last distance evaluation.
    near: Vec<bool>,
    /// Per pair: closest points.
    closest: Vec<Closest>,
    /// Per pair: separation floor of the guarantee pass (m), 0 where it needs no CCD.
    floors: Vec<f64>,
    /// Per vertex: `|y_i^k - z_i^{k-1}|` (m), how far the global step took it from safety.
    motion: Vec<f64>,
    /// Per vertex: the barrier push of eq. 49 at the current iterate (m), at the returned
    /// positions once [`project`] returns (see [`Workspace::push`]).
    push: Vec<Vector3<f64>>,
    /// Per vertex: the warm start of the next local step ([`ContactParams::warm_start`]), m.
    warm: Vec<Vector3<f64>>,
    /// Per vertex: the last descent move of this local step that it took (m).
    last_move: Vec<Vector3<f64>>,
    /// Per vertex: the factor on its descent moves, halved at each reversal (see [`project`]).
    damping: Vec<f64>,
    /// The barrier's terms per pair and their sums per vertex, kept between iterations.
    barrier_push: BarrierPush,
    /// Per vertex: the metric `W_i` of the last [`project`] ([`ProximalWeights`]).
    weights: Vec<SymmetricMatrix3<f64>>,
}

impl Workspace {
    /// Per vertex, the barrier push `p_i = -mu sum_c m_c B'(f(d_c) - xi) alpha_c^i n_c` (m) of
    /// eq. 49 at the positions the last [`project`] returned: where the descent has converged,
    /// `W_i (z_i - y_i^k) = p_i`, so `W_i^-1 p_i` is the displacement by which contact holds
    /// each vertex back from the global step's target (zero away from contact; empty before
    /// any call).
    pub fn push(&self) -> &[Vector3<f64>] {
        &self.push
    }

    /// Per vertex, the metric `W_i` the last [`project`] used (`None`: the identity, or no pair
    /// was within reach and nothing moved).
    pub fn weights(&self) -> Option<&[SymmetricMatrix3<f64>]> {
        (!self.weights.is_empty()).then_some(&self.weights[..])
    }
}

/// The live pairs of a local step and the motion they cover (see [`super::pair_cache`]).
#[derive(Default)]
struct LivePairs {
    cache: PairCache,
    /// The pairs that may come within the barrier's reach.
    pairs: Vec<Pair>,
    /// Per pair: distance at the safe positions `z^{k-1}` (m).
    start: Vec<f64>,
    /// Per pair: its fade at the safe positions, held through the local step (1, or a nearly
    /// parallel edge-edge pair's, see [`super::parallel_fade`]).
    fade: Vec<f64>,
    /// `sin^2` of the fade angle the fades are for.
    sin2_limit: f64,
    /// Per vertex: the allowance `A_i` (m) the pairs were filtered for, around the path
    /// between `filtered_safe` and `filtered_target`.
    allowance: Vec<f64>,
    /// The safe positions and the global step's result (m) the pairs were filtered for.
    filtered_safe: Vec<Vector3<f64>>,
    filtered_target: Vec<Vector3<f64>>,
    /// Per vertex: `max(|s_i - s_i^f|, |y_i - y_i^f|)` (m), how far this local step's safe
    /// position and target are from those the pairs were filtered for (0 after a filter).
    shift: Vec<f64>,
    /// Per vertex: `E_i >= |z_i - y_i^k|` (m) at the current iterate `z`: 0 at `z = y^k`, a
    /// clamp to `z^{k-1} + t (z - z^{k-1})` makes it `(1 - t) |y_i^k - z_i^{k-1}| + t E_i`, a
    /// descent move adds its length.
    deviation: Vec<f64>,
    /// The vertices whose allowance the last [`LivePairs::cover`] raised.
    grown: Vec<u32>,
    /// Counts the changes to `pairs`: a list with the same version is the same list.
    version: u64,
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
    /// of `eps xi`: their local steps then skip the filter (about 0.3 s of each local step on
    /// three layers of 200 x 200 on the ball).
    #[allow(clippy::too_many_arguments)]
    fn start(
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
    fn filter(
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
    fn cover(
        &mut self,
        safe: &[Vector3<f64>],
        target: &[Vector3<f64>],
        mesh: &ContactMesh,
        reach: f64,
        stats: &mut ContactStats,
    ) -> Option<usize> {
        debug_assert_eq!(self.shift.len(), self.allowance.len());
        self.grown.clear();
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

/// Sets `v` to `n` copies of `value`, reusing its allocation.
fn refill<T: Clone>(v: &mut Vec<T>, n: usize, value: T) {
    v.clear();
    v.resize(n, value);
}

fn millis(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

/// Forgets every pair's time of impact and nearness, and marks every vertex moved, so that the
/// next CCD queries all `pairs` (a count) afresh.
fn restart_ccd(
    pairs: usize,
    toi: &mut Vec<Option<f64>>,
    near: &mut Vec<bool>,
    changed: &mut [bool],
) {
    refill(toi, pairs, None);
    refill(near, pairs, true);
    changed.iter_mut().for_each(|c| *c = true);
}

/// Writes into `t` the smallest time of impact per vertex over the pairs that collide (1 where
/// none).
fn vertex_toi(pairs: &[Pair], toi: &[Option<f64>], t: &mut Vec<f64>, n: usize) {
    refill(t, n, 1.0);
    for (pair, hit) in pairs.iter().zip(toi) {
        if let Some(time) = hit {
            for &v in &pair.v {
                t[v as usize] = t[v as usize].min(*time);
            }
        }
    }
}

/// Keeps vertex `i` out of the colliders after a move from `from` (outside them) to `z_i`:
/// `keep_out(i, from, z_i, metric)` keeps `z_i` on the side of each collider the move came
/// from, moves it back to their surfaces by the shortest move in the metric whose inverse is
/// `metric` (symmetric positive definite; `None`: the identity, a normal projection), and then
/// onto them wherever the surface's curvature left it inside.
pub type KeepOut<'a> =
    dyn Fn(usize, &Vector3<f64>, &mut Vector3<f64>, Option<&SymmetricMatrix3<f64>>) + Sync + 'a;

/// Writes the metric `W_i` of eq. 47's proximal term into its argument, one per vertex
/// (dimensionless, symmetric positive definite; a vertex whose `W_i` cannot be inverted stays).
/// Called by [`project`] only when some pair is within the barrier's reach (a scene with
/// nothing near pays nothing for it).
pub type ProximalWeights<'a> = dyn Fn(&mut Vec<SymmetricMatrix3<f64>>) + Sync + 'a;

/// Runs the local step: `positions` holds `y^k` on entry and `z` on return; `safe` is
/// `z^{k-1}`, free of intersections; `fixed` vertices are never moved; `weights` gives the
/// metric of eq. 47's proximal term ([`ProximalWeights`]; `None`: the identity, see
/// [`ProximalMetric`]), kept in `work` ([`Workspace::weights`]). `tol` is the solver's
/// tolerance (m; 0: none), which bounds the stopping distance
/// ([`ContactParams::stop_distance`]). `keep_out`
/// ([`KeepOut`]) takes a vertex out of the colliders after every descent move, in the move's
/// metric, so the barrier cannot push a membrane into a collider. (The final clamp moves a
/// vertex back towards its safe position along a straight line, which can cut into a curved
/// collider by the sagitta of that chord, `L^2 / 8R` for a chord of length `L` on a ball of
/// radius `R`.) `work` holds the buffers between calls.
#[allow(clippy::too_many_arguments)]
pub fn project(
    safe: &[Vector3<f64>],
    positions: &mut [Vector3<f64>],
    fixed: &[bool],
    weights: Option<&ProximalWeights>,
    mesh: &ContactMesh,
    params: &ContactParams,
    tol: f64,
    keep_out: &KeepOut,
    work: &mut Workspace,
) -> ContactStats {
    let mut stats = ContactStats::default();
    let barrier = params.barrier();
    let (xi, eps, mu) = (params.thickness, params.eps, params.weight);
    let reach = barrier.reach();
    let n = positions.len();

    let t = Instant::now();
    work.target.clear();
    work.target.extend_from_slice(positions);
    let first = FIRST_ALLOWANCE * eps * xi;
    work.live.start(
        safe,
        &work.target,
        first,
        mesh,
        reach,
        sin2_limit(params.parallel_angle),
        &mut stats,
    );
    stats.broad_phase_ms += millis(t);
    refill(&mut work.push, n, Vector3::zeros());
    work.weights.clear();
    if work.live.pairs.is_empty() {
        work.warm.clear();
        return stats;
    }
    if let Some(fill) = weights {
        fill(&mut work.weights);
    }
    // Moved out for the descent, which borrows the rest of `work`; put back below.
    let metric = std::mem::take(&mut work.weights);
    let weights = weights.map(|_| &metric[..]);

    let z = positions;
    safe.par_iter()
        .zip(&*z)
        .map(|(s, y)| (y - s).norm())
        .collect_into_vec(&mut work.motion);
    let bound = barrier.derivative_bound();
    refill(&mut work.drift, n, 0.0);
    refill(&mut work.alpha, n, 0.0);
    refill(&mut work.curvature, n, SymmetricMatrix3::zeros());
    refill(&mut work.last_move, n, Vector3::zeros());
    refill(&mut work.damping, n, 1.0);
    // Vertices moved since the last CCD: a pair none of whose vertices moved keeps its time.
    // After the first iteration a vertex moves at most `2 eps xi` per iteration (a step of at
    // most `eps xi` under either rule, and a projection out of a collider no longer than the
    // step's depth into it), so only pairs that were within `(1 + 4 eps) xi` can reach `xi`:
    // the others skip the CCD. (`changed` is only sized here: `restart_ccd` marks every vertex.)
    work.changed.resize(n, true);
    if params.warm_start && work.warm.len() == n {
        // Line 2 with the warm start: a move like a descent move, so it counts as drift and
        // deviation (and may refresh the live pairs) before the first CCD sees the path.
        work.drift
            .par_iter_mut()
            .zip(&mut work.live.deviation[..])
            .zip(&mut z[..])
            .zip(&work.warm)
            .enumerate()
            .for_each(|(i, (((di, ei), zi), offset))| {
                if fixed[i] || *offset == Vector3::zeros() {
                    return;
                }
                let before = *zi;
                *zi += offset;
                keep_out(i, &before, zi, None);
                *di = (*zi - before).norm();
                *ei = *di;
            });
        let t = Instant::now();
        work.live.cover(safe, &work.target, mesh, reach, &mut stats);
        stats.broad_phase_ms += millis(t);
    }
    restart_ccd(
        work.live.pairs.len(),
        &mut work.toi,
        &mut work.near,
        &mut work.changed,
    );
    let near_distance = (1.0 + 4.0 * eps) * xi;
    let stop = params.stop_distance(tol);
    let settled = SETTLED_SHARE * stop;
    // Eq. 53's step in the metric `W` bounds the push's slope times the largest `|W_i^-1|`
    // over the free vertices: `W` is fixed through the local step, so once.
    let compliance = match (params.step, weights) {
        (DescentStep::Uniform, Some(w)) => (0..n)
            .into_par_iter()
            .filter(|&i| !fixed[i])
            .map(|i| compliance_bound(&w[i]))
            .reduce(|| 0.0, f64::max),
        _ => 1.0,
    };
    refill(&mut work.unmeasured, n, true);
    // The live pairs before this one have their closest points at the current iterate, as
    // far as the list goes (vertices in `unmeasured` moved since).
    let mut measured = 0;
    let Workspace {
        live,
        motion,
        target,
        drift,
        push,
        alpha,
        curvature,
        changed,
        unmeasured,
        fresh,
        vertex_toi: per_vertex,
        toi,
        near,
        closest,
        last_move,
        damping,
        barrier_push: sums,
        ..
    } = work;
    for _ in 0..params.max_iters {
        // Lines 4-18: CCD between the safe positions and z^m, clamp above the threshold.
        let t = Instant::now();
        let changed_now = &*changed;
        // Every vertex of the path from `z^{k-1}` to `z^m` is within `motion_i + drift_i` of
        // `z^{k-1}` (see `pair_cache`): a pair whose distance bound over such moves exceeds
        // `xi` cannot reach `xi` on it, so its CCD is skipped.
        let drift_now = &*drift;
        stats.ccd_queries += toi
            .par_iter_mut()
            .zip(&live.pairs)
            .zip(&*near)
            .zip(&live.start)
            .map(|(((hit, p), &near), &d0)| {
                if !near || p.distance_bound(d0, motion, drift_now) > xi {
                    *hit = None;
                } else if p.v.iter().any(|&v| changed_now[v as usize]) {
                    *hit = p.ccd(safe, z, xi, &params.ccd);
                    return 1;
                }
                0
            })
            .sum::<usize>();
        vertex_toi(&live.pairs, toi, per_vertex, n);
        z.par_iter_mut()
            .zip(changed.par_iter_mut())
            .zip(unmeasured.par_iter_mut())
            .zip(live.deviation.par_iter_mut())
            .enumerate()
            .for_each(|(i, (((zi, moved), unmeasured), ei))| {
                let ti = per_vertex[i];
                *moved = !fixed[i] && ti < 1.0 && ti > params.toi_threshold;
                if *moved {
                    *zi = safe[i] + (*zi - safe[i]) * ti;
                    *ei = (1.0 - ti) * motion[i] + ti * *ei;
                    *unmeasured = true;
                }
            });
        stats.ccd_ms += millis(t);
        // The clamps may have taken a vertex beyond its allowance.
        let t = Instant::now();
        if let Some(kept) = live.cover(safe, target, mesh, reach, &mut stats) {
            restart_ccd(live.pairs.len(), toi, near, changed);
            measured = measured.min(kept);
        }
        stats.broad_phase_ms += millis(t);

        // Lines 19-27: distances, weights and the descent direction of eq. 49, evaluated
        // afresh for the pairs with a vertex that moved since (and the pairs new in the list).
        let t = Instant::now();
        closest_within(
            &live.pairs,
            &live.start,
            motion,
            drift,
            reach,
            z,
            (measured, &*unmeasured),
            closest,
            fresh,
        );
        // A pair left out by `closest_within` is not near: it is at least `reach` apart,
        // which is beyond `(1 + 4 eps) xi` whenever `d_hat >= 4 eps xi` (the defaults), so the
        // full evaluation would not call it near either.
        near.par_iter_mut()
            .zip(&*closest)
            .for_each(|(near, c)| *near = c.separation.norm() < near_distance);
        sums.update(
            &live.pairs,
            (live.version, measured),
            closest,
            &live.fade,
            fresh,
            &barrier,
            mu,
            VertexSums {
                push,
                alpha,
                curvature,
            },
        );
        #[cfg(test)]
        tests::assert_as_if_evaluated_afresh(
            live,
            (motion, drift, reach),
            z,
            closest,
            (&barrier, mu),
            (push, alpha, curvature),
        );
        measured = live.pairs.len();
        unmeasured.par_iter_mut().for_each(|u| *u = false);
        let lambda = match params.step {
            DescentStep::Uniform => {
                let (alpha_0, farthest) = (0..n)
                    .into_par_iter()
                    .filter(|&i| !fixed[i])
                    .map(|i| (alpha[i], (target[i] - z[i]).norm()))
                    .reduce(|| (0.0, 0.0), |a, b| (a.0.max(b.0), a.1.max(b.1)));
                // Eq. 53, in the metric `W` (the push's bound times the largest `|W_i^-1|`).
                Some((eps * xi / (mu * alpha_0 * bound * compliance + farthest)).min(1.0))
            }
            DescentStep::Curvature => None,
        };
        let longest = eps * xi;
        let moved = z
            .par_iter_mut()
            .zip(drift.par_iter_mut())
            .zip(changed.par_iter_mut())
            .zip(unmeasured.par_iter_mut())
            .zip(live.deviation.par_iter_mut())
            .zip(last_move.par_iter_mut())
            .zip(damping.par_iter_mut())
            .enumerate()
            .map(|(i, ((((((zi, di), ci), ui), ei), last), damp))| {
                if fixed[i] {
                    return 0.0;
                }
                let before = *zi;
                let direction = push[i] + proximal_pull(weights, i, &(target[i] - *zi));
                // The move is `M_i^-1` times the direction, taken in the metric `M_i^-1`:
                // `M_i = W_i / lambda` for eq. 53's step, `W_i + K_i` for the curvature rule
                // (None: the identity). `M_i` is positive definite unless `K_i` is not finite;
                // then the vertex stays (a NaN position is caught by the global step). With
                // `W_i = I` away from contact `K_i = 0`: no inverse needed.
                let k = &curvature[i];
                let system = match (lambda, weights) {
                    (Some(_), None) => None,
                    (Some(_), Some(w)) => Some(w[i]),
                    (None, Some(w)) => Some(*k + w[i]),
                    (None, None) => (*k != SymmetricMatrix3::zeros()).then(|| k.plus_identity(1.0)),
                };
                let (step, metric) = match system.map(|s| s.try_inverse()) {
                    None => (direction, None),
                    Some(Some(inverse)) => (inverse.mul_vector(&direction), Some(inverse)),
                    Some(None) => (Vector3::zeros(), None),
                };
                // The longest move: the curvature rule's bound (eq. 53's step is within it).
                let (proposed, cap) = match lambda {
                    Some(lambda) => (step * lambda, None),
                    None => (step, Some(longest)),
                };
                let take = |damp: f64| {
                    damped_move(i, &before, &proposed, metric.as_ref(), cap, damp, keep_out)
                };
                let step = match settle_or_move(&before, take, settled, last, damp) {
                    Move::Settled(length) => return length,
                    Move::Taken { end, length } => {
                        *zi = end;
                        length
                    }
                };
                *ci = true;
                *ui = true;
                *di += step;
                *ei += step;
                step
            })
            .reduce(|| 0.0, f64::max);
        stats.iterations += 1;
        stats.descent_ms += millis(t);

        // A vertex moved beyond its allowance: the live pairs may miss a pair now (NaN counts
        // as beyond). Refresh them and start the CCD afresh on the new list.
        let t = Instant::now();
        if let Some(kept) = live.cover(safe, target, mesh, reach, &mut stats) {
            restart_ccd(live.pairs.len(), toi, near, changed);
            measured = measured.min(kept);
        }
        stats.broad_phase_ms += millis(t);
        if moved < stop {
            break;
        }
    }

    if let Some(kept) = guarantee(safe, z, fixed, mesh, params, work, &mut stats) {
        measured = measured.min(kept);
    }
    work.weights = metric;

    // The sums at the final positions: as in the loop, only the pairs with a vertex that
    // moved since the last evaluation (the last descent move, the guarantee's clamps) or new
    // in the list are evaluated afresh.
    let t = Instant::now();
    closest_within(
        &work.live.pairs,
        &work.live.start,
        &work.motion,
        &work.drift,
        reach,
        z,
        (measured, &work.unmeasured),
        &mut work.closest,
        &mut work.fresh,
    );
    stats.active_pairs = work
        .closest
        .par_iter()
        .filter(|c| c.separation.norm() < reach)
        .count();
    work.barrier_push.update(
        &work.live.pairs,
        (work.live.version, measured),
        &work.closest,
        &work.live.fade,
        &work.fresh,
        &barrier,
        mu,
        VertexSums {
            push: &mut work.push,
            alpha: &mut work.alpha,
            curvature: &mut work.curvature,
        },
    );
    #[cfg(test)]
    tests::assert_as_if_evaluated_afresh(
        &work.live,
        (&work.motion, &work.drift, reach),
        z,
        &work.closest,
        (&barrier, mu),
        (&work.push, &work.alpha, &work.curvature),
    );
    // The next warm start: this step's own move where the barrier pushes and no clamp of
    // the guarantee pass moved the vertex.
    work.warm.clear();
    if params.warm_start {
        work.warm.par_extend(
            work.push
                .par_iter()
                .zip(&work.clamped)
                .zip(&*z)
                .zip(&work.target)
                .map(|(((p, &clamped), zi), yi)| {
                    if clamped || *p == Vector3::zeros() {
                        Vector3::zeros()
                    } else {
                        zi - yi
                    }
                }),
        );
    }
    stats.descent_ms += millis(t);
    stats
}

/// The proximal term's pull on vertex `i`, `W_i (y_i^k - z_i)` (m) for `to_target =
/// y_i^k - z_i` (`weights`: see [`project`]).
#[inline]
fn proximal_pull(
    weights: Option<&[SymmetricMatrix3<f64>]>,
    i: usize,
    to_target: &Vector3<f64>,
) -> Vector3<f64> {
    weights.map_or(*to_target, |w| w[i].mul_vector(to_target))
}

/// A bound of `|W^-1|` (the largest absolute row sum of the inverse, dimensionless; 0 where
/// `W` is not invertible, as the vertex then stays).
fn compliance_bound(w: &SymmetricMatrix3<f64>) -> f64 {
    w.try_inverse().map_or(0.0, |c| {
        let [c00, c11, c22] = c.diagonal.map(f64::abs);
        let [c01, c02, c12] = c.upper.map(f64::abs);
        (c00 + c01 + c02).max(c01 + c11 + c12).max(c02 + c12 + c22)
    })
}

/// A vertex's descent move, as [`settle_or_move`] decides it.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Move {
    /// Shorter than the settled length: not taken (the vertex stays); the move's length (m),
    /// which the stopping test still counts.
    Settled(f64),
    /// Taken: where the vertex goes (m), and the move's length (m).
    Taken { end: Vector3<f64>, length: f64 },
}

/// Decides a vertex's descent move from `before` (m), where `take(damp)` is where a move at
/// damping `damp` ends ([`damped_move`]). A move at least `settled` (m) long that points
/// against `last`, the vertex's last move taken, overshot: its damping `damp` is halved for the
/// rest of the local step and the move taken again at it (see the module doc; the moves as
/// taken are compared, so a proposal into a collider that holds the vertex points against a
/// slide along it). A move shorter than `settled` is not taken and changes neither `damp` nor
/// `last` (it reverses nothing); a move taken becomes `last`.
fn settle_or_move(
    before: &Vector3<f64>,
    take: impl Fn(f64) -> Vector3<f64>,
    settled: f64,
    last: &mut Vector3<f64>,
    damp: &mut f64,
) -> Move {
    let mut end = take(*damp);
    if (end - before).norm() >= settled && (end - before).dot(last) < 0.0 {
        *damp *= 0.5;
        end = take(*damp);
    }
    let length = (end - before).norm();
    if length < settled {
        return Move::Settled(length);
    }
    *last = end - before;
    Move::Taken { end, length }
}

/// Where vertex `i` goes from `before` on a descent move of `damp` times `proposed` (m):
/// out of the colliders in the proposal's metric (`metric`, the inverse of `W_i + K_i`; `None`:
/// the identity), then cut to `damp` times `longest` (m; `None`: no cut) and taken out of the
/// colliders again, by a normal projection, where the cut point is inside.
///
/// A normal projection after a move in `(W_i + K_i)^-1` would stop where that move points
/// straight into the collider, with the part `(W_i + K_i) n` of the descent direction along the
/// surface unbalanced. The cut comes after the projection: a proposal mostly into the collider
/// would otherwise be cut to a crawl along it (and the metric's slide along a surface can be
/// long where the barrier is stiff and nearly normal to it). The cut point lies on the chord
/// from `before` to the projected end, which cuts into a curved collider (by about `f (1 - f)
/// L^2 / 2R` at the fraction `f` of a chord of length `L` on a ball of radius `R`): hence the
/// second projection.
fn damped_move(
    i: usize,
    before: &Vector3<f64>,
    proposed: &Vector3<f64>,
    metric: Option<&SymmetricMatrix3<f64>>,
    longest: Option<f64>,
    damp: f64,
    keep_out: &KeepOut,
) -> Vector3<f64> {
    let mut at = before + proposed * damp;
    keep_out(i, before, &mut at, metric);
    if let Some(longest) = longest {
        let (slide, limit) = (at - before, longest * damp);
        let length = slide.norm();
        if length > limit {
            at = before + slide * (limit / length);
            keep_out(i, before, &mut at, None);
        }
    }
    at
}

/// Writes into `closest` the closest points at `z` of the pairs from `measured` on and of those
/// with a vertex marked in `unmeasured` (`(measured, unmeasured)`), and marks them in `fresh`;
/// the others keep theirs, as none of their vertices moved. `closest[..measured]` must hold the
/// last evaluation of the same pairs in the same places, with `start` and `drift` unchanged
/// for them since (`drift` changes only for a vertex that moves, which is then marked). A
/// pair whose distance bound (from its distance `start` at the safe positions, the vertices'
/// `motion` and their total descent moves `drift`, all m) is at least `reach` feels no
/// barrier, so its closest points are not needed, and it gets [`FAR`].
#[allow(clippy::too_many_arguments)]
fn closest_within(
    pairs: &[Pair],
    start: &[f64],
    motion: &[f64],
    drift: &[f64],
    reach: f64,
    z: &[Vector3<f64>],
    (measured, unmeasured): (usize, &[bool]),
    closest: &mut Vec<Closest>,
    fresh: &mut Vec<bool>,
) {
    closest.resize(pairs.len(), FAR);
    fresh.resize(pairs.len(), false);
    closest
        .par_iter_mut()
        .zip(fresh.par_iter_mut())
        .zip(pairs.par_iter().zip(start))
        .enumerate()
        .for_each(|(k, ((c, fresh), (p, &d0)))| {
            *fresh = k >= measured || p.v.iter().any(|&v| unmeasured[v as usize]);
            if !*fresh {
                return;
            }
            *c = if p.distance_bound(d0, motion, drift) >= reach {
                FAR
            } else {
                p.closest(z)
            };
        });
}

/// Stands for the closest points of a pair beyond the barrier's reach: no weights, an infinite
/// separation (so no barrier, not active, and NaN as its direction is never taken).
const FAR: Closest = Closest {
    weights: [0.0; 4],
    separation: Vector3::new(f64::INFINITY, 0.0, 0.0),
};

/// The final clamp (see the module doc) over the live pairs in `work`: marks the vertices it
/// moves in `work.unmeasured`, adds to `stats` their number, the CCD queries it made and its
/// time (a refresh of the live pairs after a clamp counting as broad phase). Returns, where
/// it refreshed the live pairs, how many of those before are still in their places at the
/// head of the list (the least over its refreshes).
fn guarantee(
    safe: &[Vector3<f64>],
    z: &mut [Vector3<f64>],
    fixed: &[bool],
    mesh: &ContactMesh,
    params: &ContactParams,
    work: &mut Workspace,
    stats: &mut ContactStats,
) -> Option<usize> {
    let t = Instant::now();
    let (floor, reach) = (params.eps * params.thickness, params.barrier().reach());
    let Workspace {
        live,
        target,
        motion,
        drift,
        floors,
        toi,
        vertex_toi: per_vertex,
        clamped,
        unmeasured,
        ..
    } = work;
    refill(clamped, z.len(), false);
    let mut stale = true;
    let mut kept: Option<usize> = None;
    let mut refreshing = 0.0;
    for pass in 0..=CLAMP_PASSES {
        if stale {
            // Each pair's separation floor, from its distance at the safe positions; pairs
            // already touching there cannot be helped and are skipped, and so are pairs whose
            // distance bound stays above the floor (the clamps below only bring vertices
            // closer to safety, so the bound holds on every path `z^{k-1} -> z` the passes
            // test).
            live.pairs
                .par_iter()
                .zip(&live.start)
                .map(|(p, &d0)| {
                    let min = floor.min(0.9 * d0);
                    if p.distance_bound(d0, motion, drift) > min {
                        0.0
                    } else {
                        min
                    }
                })
                .collect_into_vec(floors);
        }
        stats.ccd_queries += floors.iter().filter(|&&min| min > 0.0).count();
        live.pairs
            .par_iter()
            .zip(&*floors)
            .map(|(p, &min)| {
                if min > 0.0 {
                    p.ccd(safe, z, min, &params.ccd)
                } else {
                    None
                }
            })
            .collect_into_vec(toi);
        if toi.iter().all(Option::is_none) {
            break;
        }
        vertex_toi(&live.pairs, toi, per_vertex, z.len());
        for (i, zi) in z.iter_mut().enumerate() {
            let ti = per_vertex[i];
            if fixed[i] || ti >= 1.0 {
                continue;
            }
            let keep = if pass < CLAMP_PASSES { ti } else { 0.0 };
            *zi = safe[i] + (*zi - safe[i]) * keep;
            live.deviation[i] = (1.0 - keep) * motion[i] + keep * live.deviation[i];
            clamped[i] = true;
            unmeasured[i] = true;
        }
        // The clamps may have taken a vertex beyond its allowance: the next pass and the
        // final evaluation look at the clamped positions.
        let r = Instant::now();
        let refreshed = live.cover(safe, target, mesh, reach, stats);
        stale = refreshed.is_some();
        kept = match (kept, refreshed) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        refreshing += millis(r);
    }
    stats.clamped = clamped.iter().filter(|&&m| m).count();
    stats.broad_phase_ms += refreshing;
    stats.ccd_ms += millis(t) - refreshing;
    kept
}

#[cfg(test)]
mod tests {
    use super::super::barrier_push::tests::{assert_same_sums, sums_from_scratch, Sums};
    use super::*;

    /// No colliders to keep out of.
    const FREE: &KeepOut = &|_, _, _, _| {};

    /// No solver tolerance: the local step stops at [`STOP_FRACTION`] `eps xi`.
    const NO_TOL: f64 = 0.0;

    /// A [`KeepOut`] for `colliders`: every move from where the vertex is, to their surfaces.
    fn keeping_out_of(
        colliders: &[super::super::ColliderModel<f64>],
    ) -> impl Fn(usize, &Vector3<f64>, &mut Vector3<f64>, Option<&SymmetricMatrix3<f64>>) + Sync + '_
    {
        move |_, from, zi, metric| {
            *zi = super::super::out_of_colliders(
                colliders,
                super::super::MoveStart::Now(*from),
                *zi,
                0.0,
                metric,
            );
        }
    }

    type Scene = (Vec<Vector3<f64>>, Vec<Vector3<f64>>, Vec<[u32; 3]>);

    /// Two parallel triangles, the upper pushed through the lower by the "global step".
    fn crossing() -> Scene {
        let v = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
        let lower = [v(0., 0., 0.), v(1., 0., 0.), v(0., 1., 0.)];
        let safe: Vec<_> = lower
            .iter()
            .copied()
            .chain(lower.iter().map(|p| p + v(0.1, 0.1, 0.01)))
            .collect();
        let target: Vec<_> = lower
            .iter()
            .copied()
            .chain(lower.iter().map(|p| p + v(0.1, 0.1, -0.01)))
            .collect();
        (safe, target, vec![[0, 1, 2], [3, 4, 5]])
    }

    #[test]
    fn a_crossing_move_is_stopped_and_the_pair_kept_apart() {
        let (safe, target, triangles) = crossing();
        let params = ContactParams {
            thickness: 2e-3,
            d_hat: 4e-3,
            ..ContactParams::default()
        };
        let body = [0, 0];
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &body,
            self_contact: &[true],
        };
        let mut z = target.clone();
        let fixed = vec![false; 6];
        let mut work = Workspace::default();
        let stats = project(
            &safe, &mut z, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
        );
        assert_eq!(stats.candidate_pairs, 1);
        assert!(stats.active_pairs > 0 && stats.iterations > 0);
        let lowest_upper = z[3..].iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
        let highest_lower = z[..3].iter().map(|p| p.z).fold(f64::NEG_INFINITY, f64::max);
        assert!(
            lowest_upper - highest_lower > params.eps * params.thickness,
            "gap {}",
            lowest_upper - highest_lower
        );
        // Without self-contact nothing happens.
        let mesh = ContactMesh {
            self_contact: &[false],
            ..mesh
        };
        let mut z = target.clone();
        let stats = project(
            &safe, &mut z, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
        );
        assert_eq!(stats.candidate_pairs, 0);
        assert_eq!(z, target);
    }

    /// A workspace that served a bigger scene before gives the same result as a fresh one
    /// (without the warm start, which carries the last local step's moves on by design).
    #[test]
    fn a_reused_workspace_gives_the_fresh_result() {
        let (safe, target, triangles) = crossing();
        let params = ContactParams {
            thickness: 2e-3,
            d_hat: 4e-3,
            warm_start: false,
            ..ContactParams::default()
        };
        let solve = |work: &mut Workspace, scale: f64| {
            let safe: Vec<_> = safe.iter().map(|p| p * scale).collect();
            let mut z: Vec<_> = target.iter().map(|p| p * scale).collect();
            let mesh = ContactMesh {
                triangles: &triangles,
                body: &[0, 1],
                self_contact: &[true, true],
            };
            let stats = project(
                &safe,
                &mut z,
                &[false; 6],
                None,
                &mesh,
                &params,
                NO_TOL,
                FREE,
                work,
            );
            let counts = (
                stats.candidate_pairs,
                stats.active_pairs,
                stats.iterations,
                stats.clamped,
            );
            (z, counts, work.push().to_vec())
        };
        let mut used = Workspace::default();
        solve(&mut used, 0.5);
        let fresh = solve(&mut Workspace::default(), 1.0);
        let (_, (_, active, _, _), _) = &fresh;
        assert!(*active > 0);
        assert_eq!(solve(&mut used, 1.0), fresh);
    }

    /// A small triangle held by its target `y` inside the barrier over a large fixed one, with
    /// no pair but its three vertices' point-triangle pairs in reach: eq. 47 then separates
    /// per vertex, and its minimum solves `z - y = -mu B'(z - xi)` (heights above the lower
    /// triangle, m). The target is `xi + depth d_hat` high and `slide` (m) along `x` from the
    /// safe positions; the barrier pushes along `z` only, so the minimum keeps the target's `x`
    /// and `y`. Returns the root, found by bisection, and the local step's result, target and
    /// iterations for `params` (from [`pressing`]), run with `work`.
    fn pressed_triangle(
        params: &ContactParams,
        depth: f64,
        slide: f64,
        work: &mut Workspace,
    ) -> (f64, [Vector3<f64>; 3], [Vector3<f64>; 3], usize) {
        pressed_triangle_in(None, params, NO_TOL, depth, slide, work)
    }

    /// [`pressed_triangle`] with the proximal term in the metric `W` at every vertex (`None`:
    /// the identity): the minimum solves `W (z - y) = -mu B'(h - xi) e_z`, so `z - y` is
    /// `W^-1 e_z` times `-mu B'`, and its height `h` solves `h - y_z = -(W^-1)_zz mu B'(h - xi)`
    /// (the root returned). `tol` is the solver's tolerance passed to [`project`].
    fn pressed_triangle_in(
        metric: Option<SymmetricMatrix3<f64>>,
        params: &ContactParams,
        tol: f64,
        depth: f64,
        slide: f64,
        work: &mut Workspace,
    ) -> (f64, [Vector3<f64>; 3], [Vector3<f64>; 3], usize) {
        let (xi, d_hat) = (params.thickness, params.d_hat);
        let v = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
        let lower = [v(-1., -1., 0.), v(2., -1., 0.), v(-1., 2., 0.)];
        let upper = |h: f64| [v(0.1, 0.1, h), v(0.12, 0.1, h), v(0.1, 0.12, h)];
        let (start, pressed) = (xi + 0.95 * d_hat, xi + depth * d_hat);
        let safe: Vec<_> = lower.iter().chain(&upper(start)).copied().collect();
        let target = upper(pressed).map(|p| p + v(slide, 0.0, 0.0));
        let mut z: Vec<_> = lower.iter().chain(&target).copied().collect();
        let fixed = [true, true, true, false, false, false];
        let mesh = ContactMesh {
            triangles: &[[0, 1, 2], [3, 4, 5]],
            body: &[0, 1],
            self_contact: &[false, false],
        };
        let fill =
            |w: &mut Vec<SymmetricMatrix3<f64>>| w.extend(metric.into_iter().cycle().take(6));
        let weights = metric.is_some().then_some(&fill as &ProximalWeights);
        let stats = project(
            &safe, &mut z, &fixed, weights, &mesh, params, tol, FREE, work,
        );
        assert_eq!(stats.active_pairs, 3);
        let barrier = params.barrier();
        let compliance = metric.map_or(1.0, |w| w.try_inverse().unwrap().diagonal[2]);
        let (mut below, mut above) = (pressed, xi + d_hat);
        for _ in 0..200 {
            let mid = 0.5 * (below + above);
            let excess = mid - pressed + compliance * params.weight * barrier.derivative(mid - xi);
            if excess > 0.0 {
                above = mid;
            } else {
                below = mid;
            }
        }
        (below, [z[3], z[4], z[5]], target, stats.iterations)
    }

    /// The vertices of a flat `side x side` grid of `spacing` (m) in the plane `z = height`,
    /// moved by `shift` spacings along x, row by row.
    fn flat_grid(
        side: u32,
        spacing: f64,
        shift: f64,
        height: f64,
    ) -> impl Iterator<Item = Vector3<f64>> {
        (0..side * side).map(move |v| {
            let (i, j) = (f64::from(v % side), f64::from(v / side));
            Vector3::new(spacing * (i + shift), spacing * j, height)
        })
    }

    /// Two 6 x 6 grids of 1 cm spacing, the lower one fixed at height 0, the upper one moved by
    /// `offset` (in spacings, along `x`) and pressed from `xi + 0.95 d_hat` to
    /// `xi + 0.3 d_hat` with every vertex jittered by up to 0.3 mm: their edges are parallel,
    /// so the closest points of edge-edge pairs jump along the edges as they move, and the
    /// barrier's push on a vertex with them. Returns the local step's iterations and, over the
    /// upper grid's vertices, the longest step of the curvature rule at the result,
    /// `|(I + K_i)^-1 (p_i + y_i - z_i)|` (m): zero at the minimum of eq. 47.
    fn pressed_grids(offset: f64, params: &ContactParams) -> (usize, f64) {
        let mut rng = crate::test_rng::Rng::new(7);
        let (side, spacing) = (6_u32, 0.01);
        let (xi, d_hat) = (params.thickness, params.d_hat);
        let grid = |shift: f64, height: f64| flat_grid(side, spacing, shift, height);
        let lower: Vec<_> = grid(0.0, 0.0).collect();
        let safe: Vec<_> = lower
            .iter()
            .copied()
            .chain(grid(offset, xi + 0.95 * d_hat))
            .collect();
        let target: Vec<_> = lower
            .iter()
            .copied()
            .chain(grid(offset, xi + 0.3 * d_hat).map(|p| p + rng.vector() * 3e-4))
            .collect();
        use super::super::pair_cache::tests::{grid_triangles, two_copies};
        let (triangles, body) = two_copies(&grid_triangles(side), side * side);
        let n = lower.len();
        let fixed: Vec<bool> = (0..2 * n).map(|v| v < n).collect();
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &body,
            self_contact: &[false, false],
        };
        let mut z = target.clone();
        let mut work = Workspace::default();
        let stats = project(
            &safe, &mut z, &fixed, None, &mesh, params, NO_TOL, FREE, &mut work,
        );
        let longest = (n..2 * n)
            .map(|i| {
                let direction = work.push()[i] + target[i] - z[i];
                let inverse = work.curvature[i].plus_identity(1.0).try_inverse().unwrap();
                inverse.mul_vector(&direction).norm()
            })
            .fold(0.0, f64::max);
        (stats.iterations, longest)
    }

    /// The local step of a later global iteration on two `side x side` grids pressed together:
    /// from the last one's result as the safe positions (which had moved little since the
    /// one before), towards a target moved by up to 2 micrometres (a hundredth of the allowance
    /// `eps xi`), except for the last `strays` vertices, moved 0.7 times their allowance. It ends
    /// where a fresh workspace's local step ends (no warm start in either), with the push
    /// summed over every pair. Returns its figures and whether it filtered the pairs afresh.
    fn shifted_local_step(side: u32, strays: usize) -> (ContactStats, bool) {
        let params = ContactParams {
            warm_start: false,
            ..pressing(DescentStep::Curvature, 400)
        };
        let mut rng = crate::test_rng::Rng::new(3);
        let spacing = 0.01;
        let (xi, d_hat) = (params.thickness, params.d_hat);
        let grid = |height: f64| flat_grid(side, spacing, 0.3, height);
        let safe: Vec<_> = grid(0.0).chain(grid(xi + 0.95 * d_hat)).collect();
        let target: Vec<_> = grid(0.0)
            .chain(grid(xi + 0.3 * d_hat).map(|p| p + rng.vector() * 3e-4))
            .collect();
        use super::super::pair_cache::tests::{grid_triangles, two_copies};
        let (triangles, body) = two_copies(&grid_triangles(side), side * side);
        let n = safe.len() / 2;
        let fixed: Vec<bool> = (0..2 * n).map(|v| v < n).collect();
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &body,
            self_contact: &[false, false],
        };
        // The first local step moves the upper grid millimetres (its second filters afresh).
        let mut work = Workspace::default();
        let mut first = safe.clone();
        for _ in 0..2 {
            let mut next = target.clone();
            project(
                &first, &mut next, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
            );
            first = next;
        }
        let allowance = &work.live.allowance;
        let moved: Vec<_> = target
            .iter()
            .enumerate()
            .map(|(i, p)| match i {
                _ if fixed[i] => *p,
                _ if i >= 2 * n - strays => p + Vector3::x() * (0.7 * allowance[i]),
                _ => p + rng.vector() * 2e-6,
            })
            .collect();
        let mut kept = moved.clone();
        let stats = project(
            &first, &mut kept, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
        );
        assert!(stats.active_pairs > 0);
        // The CCD's distances at the safe positions are this local step's, kept list or not.
        for (p, &d) in work.live.pairs.iter().zip(&work.live.start) {
            assert_eq!(d, p.closest(&first).separation.norm());
        }
        assert_push_from_every_pair(&mesh, &first, &kept, &params, &work);
        let mut fresh = moved.clone();
        project(
            &first,
            &mut fresh,
            &fixed,
            None,
            &mesh,
            &params,
            NO_TOL,
            FREE,
            &mut Workspace::default(),
        );
        for (a, b) in kept.iter().zip(&fresh) {
            assert!((a - b).norm() < 1e-12, "{a} vs {b}");
        }
        (stats, work.live.filtered_target == moved)
    }

    /// After a shift of every vertex by a hundredth of its allowance, the local step keeps the
    /// live pairs: no filter, no refresh. With two vertices of 288 shifted by 0.7 of their
    /// allowance it raises their allowances and refreshes once (here the raised allowances,
    /// millimetres from the first local step's approach, outgrow the build's skins, so the
    /// extension falls back to a build); with four (more than 1 %) it filters afresh at once.
    /// Every time it ends where a fresh workspace does.
    #[test]
    fn a_local_step_after_a_small_shift_keeps_the_live_pairs() {
        let (stats, filtered) = shifted_local_step(6, 0);
        assert!(!filtered && stats.live_refreshes == 0, "{stats:?}");
        let (stats, _) = shifted_local_step(12, 2);
        assert_eq!(stats.live_refreshes, 1, "{stats:?}");
        let (stats, filtered) = shifted_local_step(12, 4);
        assert!(filtered && stats.live_refreshes >= 1, "{stats:?}");
    }

    /// Two parallel grids `reach + 1.02 A` apart, the upper one's vertices with the allowance
    /// `A` = 2 mm and the lower one's a thousandth of it: no pair can come within reach, and
    /// none is live. The upper grid then shifts down by `0.45 A` (the list is kept), and its
    /// vertices deviate by
    /// `0.6 A <= A`: together `1.05 A`, so the local step may look at pairs within reach, and
    /// [`LivePairs::cover`] must refresh the list (the deviation alone is within the
    /// allowance). Afterwards every pair a brute-force search finds within reach at the
    /// nearest positions the step may look at is live.
    #[test]
    fn a_kept_list_counts_the_shift_since_its_filter_against_the_allowance() {
        use super::super::pair_cache::tests::{brute_force_pairs, grid_triangles, two_copies};
        let (side, spacing, reach, a) = (6_u32, 0.01, 0.005, 0.002);
        let grid = |height: f64| flat_grid(side, spacing, 0.3, height);
        let gap = reach + 1.02 * a;
        let safe: Vec<_> = grid(0.0).chain(grid(gap)).collect();
        let n = safe.len() / 2;
        let (triangles, body) = two_copies(&grid_triangles(side), side * side);
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &body,
            self_contact: &[false, false],
        };
        let mut stats = ContactStats::default();
        let mut live = LivePairs {
            allowance: (0..2 * n)
                .map(|i| if i < n { a / 1000.0 } else { a })
                .collect(),
            deviation: vec![0.0; 2 * n],
            ..LivePairs::default()
        };
        live.filter(&safe, &safe, &mesh, reach, &mut stats);
        assert!(live.pairs.is_empty(), "{} pairs live", live.pairs.len());

        let shift = 0.45 * a;
        let shifted: Vec<_> = grid(0.0).chain(grid(gap - shift)).collect();
        let sin2 = sin2_limit(default_parallel_angle());
        live.start(
            &shifted,
            &shifted,
            a / 1000.0,
            &mesh,
            reach,
            sin2,
            &mut stats,
        );
        assert_eq!(stats.live_refreshes, 1, "the list is kept: {stats:?}");
        assert_eq!(live.filtered_safe, safe);

        let deviation = 0.6 * a;
        for e in &mut live.deviation[n..] {
            *e = deviation;
        }
        assert!(live
            .cover(&shifted, &shifted, &mesh, reach, &mut stats)
            .is_some());
        let nearest: Vec<_> = grid(0.0).chain(grid(gap - shift - deviation)).collect();
        let (_, every) = brute_force_pairs(&mesh, &nearest);
        let within: Vec<_> = every
            .iter()
            .filter(|p| p.closest(&nearest).separation.norm() < reach)
            .collect();
        assert!(within.len() > 50, "{} pairs within reach", within.len());
        let missed = within.iter().filter(|p| !live.pairs.contains(p)).count();
        assert_eq!(
            missed,
            0,
            "{missed} of {} pairs within reach not live",
            within.len()
        );
    }

    /// Pressed onto a grid of parallel edges (aligned with it, or half a spacing off), a grid
    /// comes to rest at the balance of eq. 47 within 40 iterations (21 and 30 here), the
    /// curvature rule's step there below 4 % of `eps xi` (1.7 % and 0.7 %). Without the
    /// halving of reversed moves, vertices whose edge-edge closest points jump as they move
    /// go back and forth for good: 400 iterations do not stop the descent, and it ends up to
    /// 11 % of `eps xi` from the balance.
    #[test]
    fn a_grid_pressed_onto_parallel_edges_comes_to_rest_instead_of_cycling() {
        let params = pressing(DescentStep::Curvature, 400);
        let eps_xi = params.eps * params.thickness;
        for offset in [0.0, 0.5] {
            let (iterations, longest) = pressed_grids(offset, &params);
            assert!(iterations < 40, "offset {offset}: {iterations} iterations");
            assert!(
                longest < 0.04 * eps_xi,
                "offset {offset}: step {} eps xi",
                longest / eps_xi
            );
        }
    }

    /// The parameters of [`pressed_triangle`]: `xi = 2 mm`, `d_hat = 4 mm`.
    fn pressing(step: DescentStep, max_iters: usize) -> ContactParams {
        ContactParams {
            thickness: 2e-3,
            d_hat: 4e-3,
            max_iters,
            step,
            ..ContactParams::default()
        }
    }

    /// Eq. 53's step in a metric `W` with `|W^-1| = 4` (a vertex lighter than the mean): one
    /// iteration from a target whose gap is `eps xi`, where the push reaches the slope bound,
    /// moves each vertex by at most `eps xi` (the bound times the largest `|W_i^-1|`); with
    /// the bound in the identity it would move about four times that.
    #[test]
    fn eq_53_in_a_light_metric_moves_no_vertex_beyond_eps_xi() {
        let metric = SymmetricMatrix3 {
            diagonal: [0.25; 3],
            upper: [0.0; 3],
        };
        let params = pressing(DescentStep::Uniform, 1);
        let eps_xi = params.eps * params.thickness;
        let depth = eps_xi / params.d_hat;
        let (_, z, target, iterations) = pressed_triangle_in(
            Some(metric),
            &params,
            NO_TOL,
            depth,
            0.0,
            &mut Workspace::default(),
        );
        assert_eq!(iterations, 1);
        let longest = z
            .iter()
            .zip(&target)
            .map(|(p, t)| (p - t).norm())
            .fold(0.0, f64::max);
        assert!(
            longest <= eps_xi * (1.0 + 1e-9),
            "{longest} against {eps_xi}"
        );
        assert!(
            longest > 0.5 * eps_xi,
            "the push must be near its bound: {longest}"
        );
    }

    /// The solver's tolerance bounds how far from the minimum of eq. 47 the local step may
    /// stop: on its own stopping test (`1 % eps xi`, 2 um here) the pressed triangle ends
    /// within `eps xi / 100` of it (1.3 um, 13 iterations), at `tol = 10 nm` within `tol`
    /// (1.4 nm, 21 iterations; its stop at `tol / 5`). Above the own stopping distance, `tol`
    /// changes nothing.
    #[test]
    fn a_tighter_solver_tolerance_takes_the_local_step_closer_to_its_minimum() {
        let params = pressing(DescentStep::Curvature, 100);
        let eps_xi = params.eps * params.thickness;
        let solve = |tol: f64| {
            let (root, z, _, iterations) =
                pressed_triangle_in(None, &params, tol, 0.3, 0.0, &mut Workspace::default());
            let error = z.iter().map(|p| (p.z - root).abs()).fold(0.0, f64::max);
            (error, iterations)
        };
        let (own, own_iterations) = solve(NO_TOL);
        let (tight, tight_iterations) = solve(1e-8);
        assert!(own < 0.01 * eps_xi, "{own}");
        assert!(
            own > 1e-8,
            "the own stop must be the looser one here: {own}"
        );
        assert!(tight < 1e-8, "{tight} m from the minimum at tol = 1e-8 m");
        assert!(tight_iterations > own_iterations);
        assert_eq!(solve(1e-4), (own, own_iterations));
    }

    /// The curvature step reaches the minimum of eq. 47 within its stopping test: 13
    /// iterations, about 10 of them the approach at `eps xi` per iteration, and 0.7 % of
    /// `eps xi` from the minimum. Eq. 53's uniform step creeps, its steepest slope bound being
    /// about 180 times the proximal term's here: at the default cap it is still nearly 5 `eps xi`
    /// short, and without a cap its moves fall below the stopping test's `1 % eps xi` while it
    /// is still more than `eps xi` short (1.1 here).
    #[test]
    fn the_curvature_step_reaches_the_minimum_that_the_uniform_step_creeps_towards() {
        let eps_xi = 0.1 * 2e-3;
        let (root, z, _, iterations) = pressed_triangle(
            &pressing(DescentStep::Curvature, 32),
            0.3,
            0.0,
            &mut Workspace::default(),
        );
        for p in z {
            assert!((p.z - root).abs() < 0.02 * eps_xi, "{} vs {root}", p.z);
        }
        assert!(iterations < 20, "{iterations} iterations");
        let (root, z, _, iterations) = pressed_triangle(
            &pressing(DescentStep::Uniform, 32),
            0.3,
            0.0,
            &mut Workspace::default(),
        );
        assert_eq!(iterations, 32);
        for p in z {
            assert!(root - p.z > 4.0 * eps_xi, "{} vs {root}", p.z);
        }
        let cap = 100_000;
        let (root, z, _, iterations) = pressed_triangle(
            &pressing(DescentStep::Uniform, cap),
            0.3,
            0.0,
            &mut Workspace::default(),
        );
        assert!(iterations < cap, "{iterations} iterations");
        for p in z {
            assert!(root - p.z > eps_xi, "{} vs {root}", p.z);
        }
    }

    /// In a metric `W` that couples `x` to `z` ([`ProximalMetric::Jacobi`] gives each vertex
    /// its own), the pressed triangle's minimum moves along `W^-1 e_z`: up to the height where
    /// `(W^-1)_zz mu B'` balances the press (2.13 mm above the target, against 1.54 mm with the
    /// identity) and sideways by `(W^-1)_xz / (W^-1)_zz` (-0.4) times that rise. The curvature
    /// step in `W + K` reaches it within its stopping test (18 iterations, 13 with the
    /// identity).
    #[test]
    fn a_weighted_proximal_term_moves_the_minimum_along_its_metric() {
        let eps_xi = 0.1 * 2e-3;
        let metric = SymmetricMatrix3 {
            diagonal: [2.0, 1.0, 0.5],
            upper: [0.0, 0.8, 0.0],
        };
        let params = pressing(DescentStep::Curvature, 64);
        let (root, z, target, iterations) = pressed_triangle_in(
            Some(metric),
            &params,
            NO_TOL,
            0.3,
            0.0,
            &mut Workspace::default(),
        );
        let rise = root - target[0].z;
        let inverse = metric.try_inverse().unwrap();
        let sideways = inverse.upper[1] / inverse.diagonal[2] * rise;
        assert!(sideways < -2.0 * eps_xi, "{sideways}");
        for (p, t) in z.iter().zip(&target) {
            assert!((p.z - root).abs() < 0.02 * eps_xi, "{} vs {root}", p.z);
            assert!(
                (p.x - t.x - sideways).abs() < 0.02 * eps_xi,
                "{} vs {}",
                p.x - t.x,
                sideways
            );
            assert!((p.y - t.y).abs() < 0.02 * eps_xi, "{} vs {}", p.y, t.y);
        }
        assert!(iterations < 24, "{iterations} iterations");
        // Eq. 53's step in `W` creeps, but along the same line: `z - y` stays along `W^-1 e_z`.
        let params = pressing(DescentStep::Uniform, 200);
        let (_, z, target, _) = pressed_triangle_in(
            Some(metric),
            &params,
            NO_TOL,
            0.3,
            0.0,
            &mut Workspace::default(),
        );
        for (p, t) in z.iter().zip(&target) {
            let moved = p - t;
            assert!(moved.z > eps_xi, "{moved}");
            let along = inverse.upper[1] / inverse.diagonal[2];
            assert!(
                (moved.x - along * moved.z).abs() < 1e-9 * moved.z,
                "{moved}"
            );
        }
    }

    /// Pulled `10 eps xi` sideways to a target below `xi`, the triangle is clamped by the CCD
    /// about a quarter of the way short, in the barrier, and the descent has to slide it the
    /// rest along the contact while pushing it up: it reaches the target's place and the
    /// barrier's balance height within 20 iterations. The barrier is stiff only along its
    /// normal: a step scaled by the curvature's trace, the same in every direction, slides by
    /// a small fraction of the lag per iteration and ends the local step more than `eps xi`
    /// short.
    #[test]
    fn the_curvature_step_slides_freely_along_the_contact() {
        let eps_xi = 0.1 * 2e-3;
        let slide = 10.0 * eps_xi;
        let (root, z, target, iterations) = pressed_triangle(
            &pressing(DescentStep::Curvature, 32),
            -0.25,
            slide,
            &mut Workspace::default(),
        );
        for (p, t) in z.iter().zip(&target) {
            assert!((p.z - root).abs() < 0.02 * eps_xi, "{} vs {root}", p.z);
            assert!((p.xy() - t.xy()).norm() < 0.02 * eps_xi, "{p} vs {t}");
        }
        assert!(iterations < 20, "{iterations} iterations");
    }

    /// Every local step of these tests checks, at every iteration, that the closest points it
    /// kept for the pairs none of whose vertices moved, and the sums it kept for the vertices
    /// none of whose pairs changed, are those of a fresh evaluation of every pair, to the bit:
    /// the kept ones are exact, not an approximation.
    pub(super) fn assert_as_if_evaluated_afresh(
        live: &LivePairs,
        (motion, drift, reach): (&[f64], &[f64], f64),
        z: &[Vector3<f64>],
        closest: &[Closest],
        (barrier, mu): (&Barrier, f64),
        (push, alpha, curvature): (&[Vector3<f64>], &[f64], &[SymmetricMatrix3<f64>]),
    ) {
        let (mut fresh, mut every) = (Vec::new(), Vec::new());
        let none_moved = vec![false; z.len()];
        closest_within(
            &live.pairs,
            &live.start,
            motion,
            drift,
            reach,
            z,
            (0, &none_moved),
            &mut every,
            &mut fresh,
        );
        for (k, (kept, afresh)) in closest.iter().zip(&every).enumerate() {
            assert!(
                kept.weights == afresh.weights && kept.separation == afresh.separation,
                "pair {k}: kept {kept:?}, afresh {afresh:?}"
            );
        }
        let sums = sums_from_scratch(&live.pairs, &every, &live.fade, z.len(), (barrier, mu));
        let kept = (push.to_vec(), alpha.to_vec(), curvature.to_vec());
        assert_same_sums(&kept, &sums);
    }

    /// A grid falling through another, fixed one (its target 2 mm under it, from 5.1 mm over
    /// it, with jitter), the same grid pressed onto it from within the barrier's reach, and the
    /// two grids free and crossing: the descent extends its live pairs, filters them afresh
    /// mid-descent, and settles some vertices while others go on (each iteration checks that
    /// what it kept is exact, see [`assert_as_if_evaluated_afresh`]). The grids stay `eps xi`
    /// apart, and the push is the one summed over every pair. (No CCD clamp happens after the
    /// first iteration here: the clamps' marking of their vertices is tested by
    /// [`a_settled_vertex_clamped_mid_descent_has_its_pairs_measured_again`] and, for the
    /// guarantee pass, by
    /// [`the_guarantee_pass_keeps_out_a_move_from_within_the_threshold_and_measures_its_push`].)
    #[test]
    fn local_steps_that_refresh_their_pairs_keep_exact_closest_points() {
        use super::super::pair_cache::tests::{grid_triangles, two_copies};
        let params = ContactParams::default();
        let (xi, d_hat) = (params.thickness, params.d_hat);
        let side = 8_u32;
        let (triangles, body) = two_copies(&grid_triangles(side), side * side);
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &body,
            self_contact: &[false, false],
        };
        let n = (side * side) as usize;
        let mut rng = crate::test_rng::Rng::new(11);
        for (from, to, lower_to, fixed_lower) in [
            (xi + 0.6 * d_hat, -2e-3, 0.0, true),
            (xi + 0.95 * d_hat, xi + 0.3 * d_hat, 0.0, true),
            (xi + 0.6 * d_hat, -4e-3, 4e-3, false),
        ] {
            let fixed: Vec<bool> = (0..2 * n).map(|v| fixed_lower && v < n).collect();
            let safe: Vec<_> = flat_grid(side, 0.01, 0.0, 0.0)
                .chain(flat_grid(side, 0.01, 0.3, from))
                .collect();
            let jitter = if fixed_lower { 0.0 } else { 1e-3 };
            let mut z: Vec<_> = flat_grid(side, 0.01, 0.0, lower_to)
                .map(|p| (p, jitter))
                .chain(flat_grid(side, 0.01, 0.3, to).map(|p| (p, 1e-3)))
                .map(|(p, jitter)| p + rng.vector() * jitter)
                .collect();
            let mut work = Workspace::default();
            let stats = project(
                &safe, &mut z, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
            );
            assert!(
                stats.iterations > 3 && stats.live_refreshes > 1,
                "{stats:?}"
            );
            assert_push_from_every_pair(&mesh, &safe, &z, &params, &work);
        }
    }

    /// A vertex that has settled and is clamped by the CCD mid-descent gets its pairs measured
    /// again. The triangle `(q, c, d)` slides 0.3 mm to its target and rests there, 7.6 mm over
    /// a fixed triangle: beyond the barrier's reach of 7.5 mm, so no force, but within reach
    /// of the distance bound, so its pairs with it are evaluated. A test hook in the collider
    /// pass lowers the free vertex `p` of a third triangle `(p, a, b)`, far above, by 0.1 mm
    /// per iteration (the descent goes on), then throws it under `(q, c, d)`, twice. The CCD
    /// then clamps `q`, `c` and `d` back along their slides, though the descent did not move
    /// them since: after the second throw (the first rebuilds the live pairs, which makes
    /// every pair fresh anyway) only the clamp marks their pairs with the fixed triangle, whose
    /// closest points [`assert_as_if_evaluated_afresh`] checks at every iteration (without the
    /// mark, they are those from before the clamp).
    #[test]
    fn a_settled_vertex_clamped_mid_descent_has_its_pairs_measured_again() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        let params = ContactParams {
            max_iters: 20,
            ..ContactParams::default()
        };
        let v = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
        let height = 0.004;
        let below = height - 0.0076;
        // q, c, d; p, a, b; the fixed triangle below.
        let safe = vec![
            v(0.005, 0.005, height),
            v(0.010, 0.005, height),
            v(0.005, 0.010, height),
            v(0.0075, 0.002, 0.018),
            v(0.0075, 0.002, 0.014),
            v(0.0075, -0.003, 0.014),
            v(0.0, 0.0, below),
            v(0.02, 0.0, below),
            v(0.0, 0.02, below),
        ];
        let slide = v(3e-4, 0.0, 0.0);
        let mut z = safe.clone();
        z[..3].iter_mut().for_each(|x| *x += slide);
        let fixed = [false, false, false, false, true, true, true, true, true];
        let mesh = ContactMesh {
            triangles: &[[0, 1, 2], [3, 4, 5], [6, 7, 8]],
            body: &[0, 1, 2],
            self_contact: &[false; 3],
        };
        const P: usize = 3;
        const THROW: usize = 5;
        const THROWS: [usize; 2] = [THROW, 4 * THROW];
        let calls = AtomicUsize::new(0);
        let lower_then_throw: &KeepOut = &|i, before, zi, _| {
            if i != P {
                return;
            }
            let call = calls.fetch_add(1, Ordering::Relaxed);
            if call < THROW {
                *zi = before - v(0.0, 0.0, 1e-4);
            } else if THROWS.iter().any(|&t| (t..t + 4).contains(&call)) {
                // The throw, again where the move is cut to `eps xi` after it, and where the
                // move is halved and taken again as it reverses the last one.
                *zi = v(0.0075, 0.008, 0.0);
            }
        };
        let mut work = Workspace::default();
        let stats = project(
            &safe,
            &mut z,
            &fixed,
            None,
            &mesh,
            &params,
            NO_TOL,
            lower_then_throw,
            &mut work,
        );
        assert!(calls.load(Ordering::Relaxed) >= THROWS[1] + 4, "{stats:?}");
        assert_push_from_every_pair(&mesh, &safe, &z, &params, &work);
    }

    /// A small triangle resting on a floor (a collider), under a large one tilted by 20
    /// degrees and fixed within the barrier's reach: the barrier pushes the small one down into
    /// the floor and along it, towards where the roof rises. The floor takes the push's normal
    /// part; the rest slides the triangle along the floor, to the minimum of eq. 47 there
    /// (Karush-Kuhn-Tucker): the descent direction `g_i = p_i + y_i - z_i` has no part along
    /// the floor and points into it. The curvature step moves in `(I + K_i)^-1` with `K_i`
    /// stiff along the roof's normal: a normal projection out of the floor after such a
    /// move stops the slide where the move points straight into the floor, with `g_i`'s
    /// part along the floor left unbalanced (6 `eps xi` here). Two more ways to fail it: cutting
    /// the move to `eps xi` before the projection (the proposal is mostly into the floor, so
    /// what is left along it crawls), and halving the moves whenever the proposal, not the
    /// move taken, points against the last move (every iteration here).
    #[test]
    fn a_triangle_pressed_onto_a_collider_by_a_slanted_roof_slides_to_the_balance() {
        use super::super::{Collider, MovingCollider, Shape};
        let params = pressing(DescentStep::Curvature, 32);
        let eps_xi = params.eps * params.thickness;
        let floor = MovingCollider::new(Collider::fixed(
            Shape::plane([0.0; 3], [0.0, 0.0, 1.0]).unwrap(),
        ))
        .during_step::<f64>(0.0, 1.0);
        let floors = [floor];
        let v = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
        let small = [v(0.1, 0.1, 0.), v(0.102, 0.1, 0.), v(0.1, 0.102, 0.)];
        let tilt = 20f64.to_radians();
        let (up, along) = (
            v(tilt.sin(), 0.0, tilt.cos()),
            v(tilt.cos(), 0.0, -tilt.sin()),
        );
        let centre = v(0.1007, 0.1007, 0.0) + up * (params.thickness + 0.4 * params.d_hat);
        let roof = [
            centre - along - Vector3::y(),
            centre + along * 2.0 - Vector3::y(),
            centre - along + Vector3::y() * 2.0,
        ];
        let safe: Vec<_> = small.iter().chain(&roof).copied().collect();
        let mut z = safe.clone();
        let fixed = [false, false, false, true, true, true];
        let mesh = ContactMesh {
            triangles: &[[0, 1, 2], [3, 4, 5]],
            body: &[0, 1],
            self_contact: &[false, false],
        };
        let keep_out = keeping_out_of(&floors);
        let mut work = Workspace::default();
        let stats = project(
            &safe, &mut z, &fixed, None, &mesh, &params, NO_TOL, &keep_out, &mut work,
        );
        assert_eq!(stats.active_pairs, 3);
        // About 7 moves of `eps xi` along the floor, then the approach (14 here).
        assert!(stats.iterations < 20, "{} iterations", stats.iterations);
        for i in 0..3 {
            let g = work.push()[i] + safe[i] - z[i];
            assert!(z[i].z.abs() < 1e-12, "vertex {i} off the floor: {}", z[i]);
            assert!(
                safe[i].x - z[i].x > eps_xi,
                "vertex {i} has not slid: {}",
                z[i]
            );
            assert!(g.xy().norm() < 0.02 * eps_xi, "vertex {i}: g = {g}");
            assert!(g.z < 0.0, "vertex {i}: g = {g}");
        }
    }

    /// A descent move along a 1 cm ball, from a point on it: the proposal (5 mm along, 2 mm
    /// in) is taken out of the ball, 5.5 mm from the start, and then cut to the longest move,
    /// 0.2 mm (and 0.1 mm at half damping). The cut point is on the chord to the projected
    /// end, 53 micrometres inside the ball (13 at half damping); it is projected out again, so
    /// the move ends on the surface, up to 5 % short of the longest move (the projection
    /// shortens it by 3.4 %, 0.8 % at half damping). Without the second projection the vertex
    /// would end inside.
    #[test]
    fn a_move_cut_along_a_ball_ends_on_its_surface() {
        use super::super::{Collider, MovingCollider, Shape};
        let radius = 0.01;
        let ball = Shape::sphere([0.0; 3], radius).unwrap();
        let balls =
            [MovingCollider::new(Collider::fixed(ball.clone())).during_step::<f64>(0.0, 1.0)];
        let keep_out = keeping_out_of(&balls);
        let before = Vector3::new(0.0, 0.0, radius);
        let proposed = Vector3::new(0.005, 0.0, -0.002);
        let longest = 2e-4;
        for damp in [1.0, 0.5] {
            let end = damped_move(0, &before, &proposed, None, Some(longest), damp, &keep_out);
            let depth = ball.signed_distance(&end);
            assert!(
                depth.abs() < 1e-12,
                "damp {damp}: {depth:e} m from the surface"
            );
            let moved = (end - before).norm();
            assert!(
                (0.95 * longest * damp..=longest * damp).contains(&moved) && end.x > 0.0,
                "damp {damp}: moved {moved} to {end}"
            );
        }
    }

    /// The halving of an overshooting vertex's moves and the settled rule: a move too short to
    /// be taken reverses nothing (its damping and last move stay), a long one against the last
    /// move is halved and taken, and one that halving makes too short is not taken (but the
    /// halving stays).
    #[test]
    fn a_move_too_short_to_take_leaves_the_damping_and_the_last_move_alone() {
        let before = Vector3::new(0.3, -0.2, 1.0);
        let settled = 1e-6;
        let decide = |proposed: Vector3<f64>, last: &mut Vector3<f64>, damp: &mut f64| {
            settle_or_move(&before, |d| before + proposed * d, settled, last, damp)
        };
        let first = Vector3::new(1e-4, 0.0, 0.0);
        let (mut last, mut damp) = (first, 1.0);

        let back = Vector3::new(-0.5e-6, 0.0, 0.0);
        match decide(back, &mut last, &mut damp) {
            Move::Settled(length) => assert!((length - 0.5e-6).abs() < 1e-12, "{length}"),
            taken => panic!("{taken:?}"),
        }
        assert_eq!(
            (last, damp),
            (first, 1.0),
            "a short move changed the descent"
        );

        let far_back = Vector3::new(-1e-4, 0.0, 0.0);
        let end = before + far_back * 0.5;
        let length = (end - before).norm();
        assert_eq!(
            decide(far_back, &mut last, &mut damp),
            Move::Taken { end, length }
        );
        assert_eq!((last, damp), (end - before, 0.5));

        let onwards = Vector3::new(-2e-4, 1e-4, 0.0);
        let end = before + onwards * 0.5;
        let length = (end - before).norm();
        assert_eq!(
            decide(onwards, &mut last, &mut damp),
            Move::Taken { end, length }
        );
        assert_eq!(
            (last, damp),
            (end - before, 0.5),
            "a move along the last one halved"
        );

        let (mut last, mut damp) = (first, 1.0);
        let barely = Vector3::new(-1.5e-6, 0.0, 0.0);
        match decide(barely, &mut last, &mut damp) {
            Move::Settled(length) => assert!((length - 0.75e-6).abs() < 1e-12, "{length}"),
            taken => panic!("{taken:?}"),
        }
        assert_eq!((last, damp), (first, 0.5));
    }

    /// A local step repeated on the same positions starts from where the last one ended: it
    /// stops after one move below the stopping test and returns the same positions (within
    /// it). Cold, it repeats the whole approach.
    #[test]
    fn a_warm_start_continues_the_last_local_step() {
        let eps_xi = 0.1 * 2e-3;
        for warm_start in [true, false] {
            let params = ContactParams {
                warm_start,
                ..pressing(DescentStep::Curvature, 32)
            };
            let mut work = Workspace::default();
            let (_, first, _, cold) = pressed_triangle(&params, 0.3, 0.0, &mut work);
            let (_, again, _, iterations) = pressed_triangle(&params, 0.3, 0.0, &mut work);
            for (a, b) in first.iter().zip(&again) {
                assert!((a - b).norm() < 0.02 * eps_xi, "{a} vs {b}");
            }
            assert!(cold > 5, "{cold} iterations");
            if warm_start {
                assert_eq!(iterations, 1);
            } else {
                assert_eq!(iterations, cold);
            }
        }
    }

    /// A pair's fade scales everything it adds to a vertex: its push, its share of eq. 53's
    /// `alpha` and its curvature `K_i`. An edge-edge pair of two edges 2 mm apart and turned
    /// by half the fade angle (within the barrier's reach of 7.5 mm) adds `m` (about 7/16)
    /// times what it adds unfaded; turned to parallel, nothing.
    #[test]
    fn a_pairs_fade_scales_its_push_share_and_curvature() {
        use super::super::parallel_fade::edge_edge_fade;
        let params = ContactParams::default();
        let sin2 = sin2_limit(params.parallel_angle);
        let pair = [Pair {
            edge_edge: true,
            v: [0, 1, 2, 3],
        }];
        let crossing = |theta: f64| {
            let (c, s) = (theta.cos(), theta.sin());
            [
                Vector3::new(-0.01, 0.0, 0.0),
                Vector3::new(0.01, 0.0, 0.0),
                Vector3::new(-0.01 * c, -0.01 * s, 0.002),
                Vector3::new(0.01 * c, 0.01 * s, 0.002),
            ]
        };
        let terms = |x: &[Vector3<f64>], fade: f64| {
            barrier_terms(&pair, &[pair[0].closest(x)], &[fade], 4, &params)
        };
        let turned = crossing(0.5 * params.parallel_angle);
        let m = pair[0].distance_and_fade(&turned, sin2).1;
        assert_eq!(
            m,
            edge_edge_fade(&(turned[1] - turned[0]), &(turned[3] - turned[2]), sin2)
        );
        assert!((m - 7.0 / 16.0).abs() < 1e-3, "{m}");
        let (full, faded) = (terms(&turned, 1.0), terms(&turned, m));
        for v in 0..4 {
            assert!(full.0[v].norm() > 0.0 && full.1[v] > 0.0);
            assert!((faded.0[v] - full.0[v] * m).norm() < 1e-15 * full.0[v].norm().max(1.0));
            assert!((faded.1[v] - full.1[v] * m).abs() < 1e-15);
            let (k, k_full) = (faded.2[v].to_matrix(), full.2[v].to_matrix() * m);
            assert!((k - k_full).norm() <= 1e-12 * k_full.norm(), "vertex {v}");
        }
        let parallel = crossing(0.0);
        let m = pair[0].distance_and_fade(&parallel, sin2).1;
        assert_eq!(m, 0.0);
        let (push, alpha, curvature) = terms(&parallel, m);
        assert!(push.iter().all(|p| *p == Vector3::zeros()) && alpha.iter().all(|&a| a == 0.0));
        assert!(curvature.iter().all(|k| *k == SymmetricMatrix3::zeros()));
    }

    /// At the result `z` of a local step from `safe`, no two primitives are closer than
    /// `eps xi`, and the barrier push the local step left in `work` equals the one summed over
    /// every primitive pair (brute force, each pair faded as at `safe`): the live pairs held
    /// every pair within the barrier's reach, and the descent saw them.
    fn assert_push_from_every_pair(
        mesh: &ContactMesh,
        safe: &[Vector3<f64>],
        z: &[Vector3<f64>],
        params: &ContactParams,
        work: &Workspace,
    ) {
        let (_, every) = super::super::pair_cache::tests::brute_force_pairs(mesh, safe);
        let nearest = every
            .iter()
            .map(|p| p.closest(z).separation.norm())
            .fold(f64::INFINITY, f64::min);
        assert!(nearest >= params.eps * params.thickness, "{nearest}");
        let push = brute_force_push(&every, z, safe, params);
        for (i, (a, b)) in work.push().iter().zip(&push).enumerate() {
            assert!(
                (a - b).norm() <= 1e-12 * (1.0 + b.norm()),
                "vertex {i}: {a} vs {b}"
            );
        }
    }

    /// The barrier push at `z` summed over `pairs`, each pair faded as at `fade_at` (m).
    fn brute_force_push(
        pairs: &[Pair],
        z: &[Vector3<f64>],
        fade_at: &[Vector3<f64>],
        params: &ContactParams,
    ) -> Vec<Vector3<f64>> {
        let closest: Vec<_> = pairs.iter().map(|p| p.closest(z)).collect();
        let sin2 = sin2_limit(params.parallel_angle);
        let fades: Vec<_> = pairs
            .iter()
            .map(|p| p.distance_and_fade(fade_at, sin2).1)
            .collect();
        barrier_terms(pairs, &closest, &fades, z.len(), params).0
    }

    /// [`BarrierPush::update`]'s push, `alpha` and `K_i` over the `n` vertices, from scratch.
    fn barrier_terms(
        pairs: &[Pair],
        closest: &[Closest],
        fades: &[f64],
        n: usize,
        params: &ContactParams,
    ) -> Sums {
        sums_from_scratch(pairs, closest, fades, n, (&params.barrier(), params.weight))
    }

    /// A triangle lying parallel over another of the same shape (1 cm legs) and pressed into
    /// its barrier while it turns by twice the fade angle: its edges are parallel to those
    /// below at the safe positions, 3.6 degrees off at the target. The local step holds every
    /// pair's fade as it was at the safe positions, so its push is the brute-force push with
    /// the fades there (the edge-edge pairs along the legs faded out), not with the fades at
    /// the result, which differs by more than a tenth of it.
    #[test]
    fn a_local_step_holds_the_fades_of_its_safe_positions() {
        let params = pressing(DescentStep::Curvature, 32);
        let (xi, d_hat) = (params.thickness, params.d_hat);
        let leg = 0.01;
        let triangle = |height: f64, turn: f64| {
            let (c, s) = (turn.cos(), turn.sin());
            [(0.0, 0.0), (leg, 0.0), (0.0, leg)]
                .map(|(x, y)| Vector3::new(c * x - s * y, s * x + c * y, height))
        };
        let lower = triangle(0.0, 0.0);
        let safe: Vec<_> = lower
            .iter()
            .chain(&triangle(xi + 0.95 * d_hat, 0.0))
            .copied()
            .collect();
        let turn = 2.0 * params.parallel_angle;
        let mut z: Vec<_> = lower
            .iter()
            .chain(&triangle(xi + 0.3 * d_hat, turn))
            .copied()
            .collect();
        let fixed = [true, true, true, false, false, false];
        let mesh = ContactMesh {
            triangles: &[[0, 1, 2], [3, 4, 5]],
            body: &[0, 1],
            self_contact: &[false, false],
        };
        let mut work = Workspace::default();
        project(
            &safe, &mut z, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
        );
        let (_, every) = super::super::pair_cache::tests::brute_force_pairs(&mesh, &safe);
        let (held, at_result) = (
            brute_force_push(&every, &z, &safe, &params),
            brute_force_push(&every, &z, &z, &params),
        );
        for v in 3..6 {
            let (a, held, other) = (work.push()[v], held[v], at_result[v]);
            assert!(
                (a - held).norm() <= 1e-12 * held.norm(),
                "vertex {v}: {a} vs {held}"
            );
            assert!(
                (other - held).norm() > 0.1 * held.norm(),
                "vertex {v}: {other} vs {held}"
            );
        }
    }

    /// Three parallel triangles, `xi = d_hat = 1 mm`: the lowest fixed at height 0, the middle
    /// one at rest just beyond the barrier's reach above it (0.2 mm beyond), the top one
    /// pressed from beyond the reach above the middle one to `0.1 d_hat` into its barrier. The
    /// middle triangle has no motion of its own: only the descent's moves (its drift), pushed
    /// by the top one, bring it within the lowest one's reach, which then holds it up. The
    /// push at the result is the brute-force one, the lowest triangle's barrier included.
    #[test]
    fn a_sheet_pushed_by_the_descent_alone_feels_the_sheet_below() {
        let params = ContactParams {
            thickness: 1e-3,
            d_hat: 1e-3,
            ..ContactParams::default()
        };
        let reach = params.barrier().reach();
        let v = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
        let lowest = [v(-1., -1., 0.), v(2., -1., 0.), v(-1., 2., 0.)];
        let small = |h: f64| [v(0.1, 0.1, h), v(0.12, 0.1, h), v(0.1, 0.12, h)];
        let middle = reach + 2e-4;
        let top = small(middle + reach + 5e-4);
        let pressed = small(middle + params.thickness + 0.1 * params.d_hat);
        let stack = |upper: [Vector3<f64>; 3]| -> Vec<_> {
            lowest
                .iter()
                .chain(&small(middle))
                .chain(&upper)
                .copied()
                .collect()
        };
        let (safe, target) = (stack(top), stack(pressed));
        let mesh = ContactMesh {
            triangles: &[[0, 1, 2], [3, 4, 5], [6, 7, 8]],
            body: &[0, 1, 2],
            self_contact: &[false; 3],
        };
        let fixed = [true, true, true, false, false, false, false, false, false];
        let mut z = target.clone();
        let mut work = Workspace::default();
        project(
            &safe, &mut z, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
        );
        assert_push_from_every_pair(&mesh, &safe, &z, &params, &work);
        let lowered = z[3..6].iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
        assert!(
            lowered < reach - 1e-4,
            "middle triangle at {lowered}, reach {reach}"
        );
    }

    /// Three slightly wavy 9 x 9 grids (1 cm spacing) falling about 5 cm in one local step,
    /// with `xi = 1 mm` and a reach of 3 mm: the lowest sheet 50 mm, the other two 53 mm,
    /// through the lowest (1.5 mm below them at the start), which half of their width
    /// overlaps; the top one 5 mm above the middle one (beyond the reach). The CCD clamps the
    /// overlap's vertices each by its own factor, holding the middle sheet back by centimetres
    /// through the top one that fell on: its pairs with the middle sheet become live only
    /// after the clamps. At the result no two primitives are closer than `eps xi`, and the
    /// barrier push equals the one summed over every primitive pair (brute force): the live
    /// pairs held every pair within the barrier's reach.
    #[test]
    fn sheets_falling_through_each_other_keep_every_pair_within_reach_live() {
        let n = 9u32;
        let mut safe = Vec::new();
        let mut target = Vec::new();
        let sheets = [
            (0.0, 0.0, 0.05),
            (0.045, 0.0015, 0.053),
            (0.045, 0.0065, 0.053),
        ];
        for (shift, height, fall) in sheets {
            for j in 0..n {
                for i in 0..n {
                    let (u, v) = (f64::from(i) * 0.01, f64::from(j) * 0.01);
                    let wave = 0.0002 * (40.0 * u).sin() * (30.0 * v).cos();
                    let p = Vector3::new(u + shift, v, height + wave);
                    safe.push(p);
                    target.push(p - Vector3::new(0.0, 0.0, fall));
                }
            }
        }
        let mut triangles = Vec::new();
        let mut body = Vec::new();
        for sheet in 0..3 {
            for j in 0..n - 1 {
                for i in 0..n - 1 {
                    let v = sheet * n * n + j * n + i;
                    triangles.push([v, v + 1, v + n + 1]);
                    triangles.push([v, v + n + 1, v + n]);
                    body.extend([sheet, sheet]);
                }
            }
        }
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &body,
            self_contact: &[true, true, true],
        };
        let params = ContactParams {
            thickness: 1e-3,
            d_hat: 2e-3,
            // Few descent moves: their drift alone would not bring the pairs in.
            max_iters: 2,
            ..ContactParams::default()
        };
        let mut z = target.clone();
        let mut work = Workspace::default();
        let fixed = vec![false; safe.len()];
        let stats = project(
            &safe, &mut z, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
        );
        assert!(stats.active_pairs > 0, "{stats:?}");
        // Held back by clamps: some vertices by far more than the descent's moves of at most
        // `eps xi` each could take them, others hardly at all.
        let held: Vec<f64> = z.iter().zip(&target).map(|(a, b)| (a - b).norm()).collect();
        let most = held.iter().copied().fold(0.0, f64::max);
        let least = held.iter().copied().fold(f64::INFINITY, f64::min);
        let descent = params.max_iters as f64 * params.eps * params.thickness;
        assert!(
            most > 2.0 * descent && least < 0.1 * descent,
            "{most} {least}"
        );
        assert_push_from_every_pair(&mesh, &safe, &z, &params, &work);
        // The same local step again starts from the allowances the first one needed: it
        // refreshes the live list less often, and keeps every pair `eps xi` apart. (Its
        // positions differ a little: a refresh restarts the CCD, whose additive steps can
        // report a time for pairs it would otherwise have skipped.)
        let mut again = target.clone();
        let second = project(
            &safe, &mut again, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
        );
        assert!(
            second.live_refreshes < stats.live_refreshes,
            "{} then {} refreshes",
            stats.live_refreshes,
            second.live_refreshes
        );
        assert_push_from_every_pair(&mesh, &safe, &again, &params, &work);
    }

    /// A triangle within `xi` of a fixed one that the global step takes 10 mm through it: the
    /// CCD inside the descent finds the time of impact below its threshold and leaves the
    /// move, the descent sees no barrier at the far side (beyond reach) and stops at once,
    /// so only the guarantee pass keeps the triangle out. It clamps all three vertices, which
    /// end at least the floor `eps xi` above, and the barrier push left for the next global
    /// iteration is measured where the clamps left them (not where the descent last saw
    /// them, beyond reach with no push). The first time the clamps take the vertices beyond
    /// their allowances and the live pairs are filtered afresh; the same local step again
    /// starts with room for them, keeps its list, and measures only the clamped vertices'
    /// pairs afresh.
    #[test]
    fn the_guarantee_pass_keeps_out_a_move_from_within_the_threshold_and_measures_its_push() {
        let v = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
        let lower = [v(-1.0, -1.0, 0.0), v(2.0, -1.0, 0.0), v(-1.0, 2.0, 0.0)];
        let upper = [v(0.1, 0.1, 0.0), v(0.2, 0.1, 0.0), v(0.1, 0.2, 0.0)];
        let params = pressing(DescentStep::Curvature, 32);
        let (xi, floor) = (params.thickness, params.eps * params.thickness);
        let height = 1.5 * floor;
        let safe: Vec<_> = lower
            .iter()
            .copied()
            .chain(upper.iter().map(|p| p + v(0.0, 0.0, height)))
            .collect();
        let target: Vec<_> = lower
            .iter()
            .copied()
            .chain(upper.iter().map(|p| p - v(0.0, 0.0, 0.01)))
            .collect();
        // The time of impact at `xi` is 0 and at the floor far below the threshold.
        assert!(height < xi && (height - floor) / (height + 0.01) < params.toi_threshold);
        let triangles = [[0, 1, 2], [3, 4, 5]];
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &[0, 1],
            self_contact: &[true, true],
        };
        let fixed = [true, true, true, false, false, false];
        let mut work = Workspace::default();
        for refreshes in [2, 0] {
            let mut z = target.clone();
            let stats = project(
                &safe, &mut z, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
            );
            assert_eq!(stats.iterations, 1, "{stats:?}");
            assert_eq!(stats.clamped, 3, "{stats:?}");
            assert_eq!(stats.live_refreshes, refreshes, "{stats:?}");
            for p in &z[3..] {
                assert!(floor <= p.z && p.z < height, "{p}");
            }
            assert!(work.push()[3..].iter().all(|p| p.z > 0.0));
            assert_push_from_every_pair(&mesh, &safe, &z, &params, &work);
        }
    }

    #[test]
    fn far_apart_bodies_are_left_alone() {
        let (safe, _, triangles) = crossing();
        let body = [0, 1];
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &body,
            self_contact: &[true, true],
        };
        let mut z = safe.clone();
        let params = ContactParams {
            thickness: 1e-3,
            d_hat: 2e-3,
            ..ContactParams::default()
        };
        project(
            &safe,
            &mut z,
            &[false; 6],
            None,
            &mesh,
            &params,
            NO_TOL,
            FREE,
            &mut Workspace::default(),
        );
        assert_eq!(z, safe);
    }
}
