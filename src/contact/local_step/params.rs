//! The contact parameters of the local step (Lu et al. 2023, Table 1 and eqs. 47-53), its step
//! rule and proximal metric, and the constants of its stopping test and final clamp.

use super::super::barrier::Barrier;
use super::super::ccd::AdditiveCcd;
use super::super::parallel_fade::default_parallel_angle;
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

/// The Python API's default barrier range per contact thickness, `d_hat = xi / 2` (the paper's
/// Table 1 has `4 xi`, which [`ContactParams::default`] keeps).
///
/// Layers rest where the barrier's push carries their weight, and that push is
/// `d mu |B'(x)| / h^2` (N; `d` the Jacobi mass scale, kg, `h` the time step, s): it balances a
/// vertex's weight `m g` at `|B'(x)| ~ g h^2` (m; 40 um at `h = 2 ms`), and near the range
/// `|B'(x)| ~ 3 (d_hat - x)^2 / d_hat`, so the gap `x` stays within about
/// `sqrt(g h^2 d_hat / 3)` (0.1 mm for `d_hat = 0.5 mm`) of `d_hat`: stacked layers rest with
/// their mid-surfaces `xi + d_hat` apart, whatever they weigh. With the paper's `4 xi` a cloth
/// of 1 mm floats 4 mm above the one below it (issue 41, item 3); with `xi / 2`, 0.5 mm.
pub const D_HAT_PER_THICKNESS: f64 = 0.5;

/// Contact parameters (SI units). Defaults follow Table 1 of the paper (cloths over a ball):
/// `xi = 1.5 mm`, `d_hat = 4 xi`, `eps = 0.1` (the Python API's `d_hat` default is
/// [`D_HAT_PER_THICKNESS`] `xi`).
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
    /// Fade angle `theta_0` (radians, in `[0, pi/2)`): an edge-edge pair whose edges are closer to
    /// parallel than this at the local step's safe positions enters the barrier with the weight `r
    /// (2 - r)`, `r = sin^2 theta / sin^2 theta_0`, 0 for parallel edges (IPC's edge-edge
    /// mollifier, not in the paper; see [`super::super::parallel_fade`]). Without it (0) the local
    /// step's measure stalls at about a micrometre on stacked layers, as the closest points of
    /// nearly parallel edges jump. The default, `asin(sqrt(1e-3))` (1.8 degrees), is IPC's.
    pub parallel_angle: f64,
    /// The metric of eq. 47's proximal term. Read by the solver, which computes the weights
    /// and passes them to [`super::resolve_contacts`].
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

    pub(super) fn barrier(&self) -> Barrier {
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
/// go on at `tol` without converging; `tol / 5` leaves a margin below that. At the paper
/// scenes' `tol = 1e-4 m` the fraction of `eps xi` is the smaller one. The cost of a tight
/// `tol`: more local iterations, fewer settled vertices ([`SETTLED_SHARE`] follows the stop,
/// which it must not exceed), and where the
/// local step's measure cannot fall below `tol / 5` (nearly parallel edges without the fade,
/// see [`ContactParams::parallel_angle`]) every local step runs to `max_iters`.
pub const TOL_SHARE: f64 = 0.2;

/// A descent move shorter than this share of the stopping distance is not taken: the vertex
/// stays, and the pairs none of whose vertices moved keep their closest points and barrier
/// terms, so an iteration's distances and terms cost what its moving vertices' pairs cost
/// (not in the paper). The stopping test still counts such a move. A cost trade-off: late in
/// a local step most vertices of stacked layers still move, each by a few nanometres. A
/// share rather than the stopping distance itself: at the full distance the vertices that
/// slide by small moves stop short of the balance their test allows.
pub const SETTLED_SHARE: f64 = 0.25;

/// Passes of the final clamp before the remaining colliding vertices fall back to safety.
pub const CLAMP_PASSES: usize = 16;

/// Writes the metric `W_i` of eq. 47's proximal term into its argument, one per vertex
/// (dimensionless, symmetric positive definite; a vertex whose `W_i` cannot be inverted stays).
/// Called by [`super::resolve_contacts`] only when some pair is within the barrier's reach (a scene
/// with nothing near pays nothing for it).
pub type ProximalWeights<'a> = dyn Fn(&mut Vec<SymmetricMatrix3<f64>>) + Sync + 'a;
