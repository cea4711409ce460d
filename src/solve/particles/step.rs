//! One global iteration of the particle family (He et al. 2017, eq. 12-13): the residual at
//! the current iterate, the global solver's move, Armijo backtracking on the merit, the
//! colliders in the Jacobi metric with friction, Chebyshev extrapolation, and the measures.
//!
//! **Merit (eq. 13).** The deviatoric force (eq. 10) is not the gradient of any energy, so the
//! line search cannot ask the energy to fall. It asks the residual of eq. 12 to:
//! `phi(y) = sum_i |r_i|^2 / m_i` with `r = m (y* - y) + h^2 f(y)` (kg m^2), zero exactly at
//! the implicit Euler solution. The step length `alpha` starts at 1 and halves until
//! `phi(y + alpha delta) <= (1 - 2 sigma alpha) phi(y)` (`sigma` = [`ARMIJO_SIGMA`]; for
//! `delta = J^-1 r` the directional derivative of `phi` is `-2 phi`), at most
//! [`MAX_HALVINGS`] times; the last trial is taken if none passes. Each trial is a whole next
//! iterate (colliders, repulsion and extrapolation applied) and costs one kernel evaluation,
//! which the next iteration reuses.

use std::time::Instant;

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::collider::{push_out_with_friction, ColliderModel};
use crate::parallel::chunked_sum;
use crate::real::Real;
use crate::solve::points::Points;
use crate::solve::update::{MoveOptions, Update};
use crate::solve::GlobalSolver;
use crate::symmetric::SymmetricMatrix3;

use super::direct::DirectSolver;
use super::directions::{jacobi, position_averaging};
use super::system::ParticleSystem;
use crate::timing::millis;

/// The sufficient-decrease constant of the Armijo condition.
pub const ARMIJO_SIGMA: f64 = 1e-4;
/// How far the merit may grow at an extrapolated trial before the plain move is tried: a
/// Chebyshev iterate is no descent step (it raises the merit for some iterations while it
/// damps the slow modes), and asking it to pass the Armijo bound took the acceleration away;
/// a growth beyond this factor is a sign of divergence.
pub const EXTRAPOLATION_GROWTH: f64 = 4.0;
/// Most halvings of the step length in one line search (`alpha >= 1/16`).
pub const MAX_HALVINGS: usize = 4;

/// The move of one global iteration, from the evaluation at the current iterate `y`, into
/// `y_next`, and its measures (the direct solver factored by [`prepare_direct`]).
///
/// The line search's trials are the next iterates themselves, with the colliders, the
/// repulsion and the extrapolation applied: the first is the whole extrapolated move, then
/// the whole plain move, then halvings of it. The accepted trial's evaluation is the next
/// iteration's (an iteration costs one kernel pass when its first trial passes), and the
/// step's own collider pass leaves `y_next` alone ([`Family::keeps_out_of_colliders`]).
///
/// [`Family::keeps_out_of_colliders`]: crate::solve::family::Family::keeps_out_of_colliders
pub(crate) fn global_move<T: Real>(
    sys: &mut ParticleSystem<T>,
    h: T,
    options: &MoveOptions<'_, T>,
) -> Update {
    let h2 = h * h;
    let started = Instant::now();
    let merit = sys.current.residual_merit(&sys.points, h2, &mut sys.chunks);
    sys.timings.residual += millis(started);
    let started = Instant::now();
    match options.global_solver {
        GlobalSolver::Jacobi | GlobalSolver::Chebyshev => jacobi(sys, h2, options.inner_iters),
        GlobalSolver::Position => position_averaging(sys, h2),
        GlobalSolver::Direct => direct_move(sys, h, options.colliders),
    }
    sys.timings.solve += millis(started);
    let noise = if options.step_length {
        merit_floor(sys, h2)
    } else {
        f64::INFINITY
    };
    line_search(sys, h2, merit, noise, options)
}

/// The merit's round-off floor (kg m^2): `sum_i f_i^2 m_i` with `f_i` the floor of particle
/// `i`'s residual per unit mass ([`ROUNDOFF_FACTOR`]), summed in fixed chunks.
fn merit_floor<T: Real>(sys: &mut ParticleSystem<T>, h2: T) -> f64 {
    let eps = T::default_epsilon().to_f64();
    let mut chunks = std::mem::take(&mut sys.chunks);
    let sys_ref = &*sys;
    let floor = chunked_sum(sys_ref.points.y.len(), &mut chunks, |i| {
        let size = ROUNDOFF_FACTOR * eps * sys_ref.points.y[i].norm().to_f64();
        let d = sys_ref.diagonal(i, h2).to_f64();
        (size * d).powi(2) / sys_ref.points.mass[i].to_f64()
    });
    sys.chunks = chunks;
    floor
}

/// Armijo backtracking on the merit (see the module's doc) over the trials of
/// [`global_move`]: a plain trial passes when the merit of the particles no collider touched
/// falls from its value at `y` over the same particles by the Armijo bound, an extrapolated
/// one when it grows less than [`EXTRAPOLATION_GROWTH`] times (the touched ones carry
/// the colliders' reactions in their residuals, which no move can take away). The accepted
/// trial's evaluation becomes the current one; the last trial is taken if none passes.
///
/// Below `noise` (the merit's round-off floor, [`merit_floor`]) the merit cannot tell a
/// decrease from round-off: a merit there takes the first trial without evaluating it (the
/// move is itself of round-off size: a body in free fall or at rest converges so in one
/// iteration and one kernel pass per step), and a trial within that floor of the Armijo
/// bound passes. Where a collider touched the plain trial, the merit cannot judge the
/// projection (the projected Jacobi move is no descent direction of the free particles'
/// merit: their neighbours at a contact take up its reaction over many iterations), and that
/// trial is taken without halvings.
fn line_search<T: Real>(
    sys: &mut ParticleSystem<T>,
    h2: T,
    merit: f64,
    noise: f64,
    options: &MoveOptions<'_, T>,
) -> Update {
    let (mut alpha, mut omega) = (T::one(), options.omega);
    let mut halvings = 0;
    loop {
        if let Some(repulsion) = &mut sys.repulsion {
            repulsion.correct(&sys.points, &sys.delta, alpha);
        }
        let started = Instant::now();
        let update = propose(sys, h2, alpha, omega, options);
        sys.timings.project += millis(started);
        if merit <= noise {
            return update;
        }
        let started = Instant::now();
        sys.trial.at.copy_from_slice(&sys.points.y_next);
        sys.trial.run(&sys.rest);
        sys.timings.evaluations += 1;
        sys.trial.residual_merit(&sys.points, h2, &mut sys.chunks);
        let before = free_merit(
            &sys.current.residual,
            &sys.points,
            &sys.touched,
            &mut sys.chunks,
        );
        let after = free_merit(
            &sys.trial.residual,
            &sys.points,
            &sys.touched,
            &mut sys.chunks,
        );
        sys.timings.line_search += millis(started);
        let bound = if omega.is_some() {
            before * EXTRAPOLATION_GROWTH
        } else {
            before * (1.0 - 2.0 * ARMIJO_SIGMA * alpha.to_f64())
        };
        let contact = omega.is_none() && sys.touched.iter().any(|&t| t);
        if after <= bound + noise || halvings == MAX_HALVINGS || contact || !after.is_finite() {
            std::mem::swap(&mut sys.current, &mut sys.trial);
            return update;
        }
        if omega.is_some() {
            omega = None;
        } else {
            alpha *= T::of(0.5);
            halvings += 1;
        }
    }
}

/// `sum_i |r_i|^2 / m_i` (kg m^2) over the particles not `touched` by a collider, summed in
/// fixed chunks (the same for any thread count).
fn free_merit<T: Real>(
    residual: &[Vector3<T>],
    points: &Points<T>,
    touched: &[bool],
    chunks: &mut Vec<f64>,
) -> f64 {
    chunked_sum(residual.len(), chunks, |i| {
        if touched[i] {
            0.0
        } else {
            residual[i].norm_squared().to_f64() / points.mass[i].to_f64()
        }
    })
}

/// Readies the direct solver for a step: the matrix's pattern and symbolic factor on the
/// first step (before the iterations, which then allocate nothing), and an empty set of
/// collider contacts (the held set starts again from the pins and the particles that touch a
/// collider at the first iterate).
pub(crate) fn prepare_direct<T: Real>(sys: &mut ParticleSystem<T>) -> crate::error::Result<()> {
    if sys.direct.is_none() {
        sys.direct = Some(DirectSolver::new(&sys.rest)?);
    }
    sys.held.fill(false);
    Ok(())
}

/// The direct solver's move into `sys.delta`: the held set grows by the particles that touch
/// a collider at the current iterate (within [`CONTACT_GAP`] of their margin) and keeps the
/// ones that touched earlier in the step, so that it changes, and the matrix is refactored,
/// only as contacts form (see [`DirectSolver`]). Should a factorisation fail, the move is one
/// Jacobi sweep and the failure is reported at the end of the step.
fn direct_move<T: Real>(sys: &mut ParticleSystem<T>, h: T, colliders: &[ColliderModel<T>]) {
    {
        let points = &sys.points;
        sys.held.par_iter_mut().enumerate().for_each(|(i, held)| {
            let reach = points.margin[i] * (T::one() + T::of(CONTACT_GAP));
            *held |= points.pinned[i]
                || Points::colliders_of(&points.collides, i, colliders)
                    .iter()
                    .any(|c| c.signed_distance(&points.y[i]) <= reach);
        });
    }
    let direct = sys.direct.as_mut().expect("built by prepare_direct");
    match direct.factor(&sys.rest, h.to_f64(), &sys.held) {
        Ok(()) => direct.solve(&sys.current.residual, &mut sys.delta),
        Err(e) => {
            sys.failure.get_or_insert(e);
            jacobi(sys, h * h, 1);
        }
    }
}

/// The round-off floor of a particle's residual per unit mass, in units of
/// `eps |y_i| D_i / m_i` (m): each bond vector `y_j - y_i` is known to about `eps |y_i|` (`eps`
/// the precision's machine epsilon), and the residual changes by `D_i` (the Jacobi diagonal,
/// kg) per metre a particle moves (the round-off of some 30 bond terms adds up to about
/// this: a body in free fall, its residual all round-off, stays below it). In f32, a stiff
/// body at a large step (25K particles of E 2e5 Pa in a 0.1 m cube at h = 1/30 s:
/// `D_i / m_i` about 5e4) cannot resolve its residual below some 5e-4 m, above the default
/// tolerance (docs/model.md).
pub const ROUNDOFF_FACTOR: f64 = 1.0;

/// The trial `y_next = y + alpha delta` (with the repulsion's move), kept out of the colliders
/// in the metric of the Jacobi diagonal (with friction) and, where no collider touched it,
/// extrapolated by `omega` (Chebyshev) and kept out again; `sys.touched` marks the particles
/// a collider moved. The measures: the largest move, and the largest residual per unit mass
/// at `y` with the colliders' reaction to the whole move added (as for membranes,
/// [`crate::solve::membranes::jacobi::free_residual`]).
fn propose<T: Real>(
    sys: &mut ParticleSystem<T>,
    h2: T,
    alpha: T,
    omega: Option<T>,
    options: &MoveOptions<'_, T>,
) -> Update {
    let mut y_next = std::mem::take(&mut sys.points.y_next);
    let mut touched = std::mem::take(&mut sys.touched);
    let sys_ref = &*sys;
    let (points, residual) = (&sys_ref.points, &sys_ref.current.residual);
    let update = y_next
        .par_iter_mut()
        .zip(touched.par_iter_mut())
        .enumerate()
        .map(|(i, (next, touched))| {
            let y = &points.y[i];
            *touched = false;
            if points.pinned[i] {
                *next = *y;
                return Update::NONE;
            }
            let d = sys_ref.diagonal(i, h2);
            let inverse = SymmetricMatrix3::from_diagonal(&Vector3::repeat(T::one() / d));
            let margin = points.margin[i];
            let push = |to: Vector3<T>| {
                push_out_with_friction(
                    y,
                    to,
                    &points.y_start[i],
                    &inverse,
                    margin,
                    Points::colliders_of(&points.collides, i, options.colliders),
                )
            };
            let repelled = sys_ref
                .repulsion
                .as_ref()
                .map_or(Vector3::zeros(), |r| r.of_particle(i));
            let whole = y + sys_ref.delta[i];
            let free_move = y + sys_ref.delta[i] * alpha;
            *next = push(free_move + repelled);
            let reaction = if alpha == T::one() {
                *next - free_move
            } else {
                push(whole + repelled) - whole
            };
            *touched = *next != free_move;
            if let Some(w) = omega.filter(|_| !*touched) {
                let extrapolated = (*next - points.y_prev[i]) * w + points.y_prev[i];
                *next = push(extrapolated);
                *touched = *next != extrapolated;
            }
            let free = (residual[i] + reaction * d) / points.mass[i];
            let mut update = Update::of(i, y, next);
            update.residual = free.norm().to_f64();
            update
        })
        .reduce(|| Update::NONE, Update::merge);
    sys.points.y_next = y_next;
    sys.touched = touched;
    update
}

/// How close to its margin (a fraction of the margin) a particle counts as touching a
/// collider for the direct solver ([`direct_move`]).
pub const CONTACT_GAP: f64 = 1e-3;
