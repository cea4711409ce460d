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
//! [`MAX_HALVINGS`] times; the last trial is taken if none passes. Each trial costs one kernel
//! evaluation, which the next iteration reuses when the move is not changed afterwards.

use std::time::Instant;

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::collider::{push_out_with_friction, ColliderModel};
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
/// Most halvings of the step length in one line search (`alpha >= 1/16`).
pub const MAX_HALVINGS: usize = 4;
/// The merit's round-off floor in the line search, in units of [`super::evaluation::Evaluation::merit_noise`]
/// (whose force term does not bound the round-off of a sum of some 30 bond forces).
pub const NOISE_FACTOR: f64 = 100.0;

/// The move of one global iteration, from the evaluation at the current iterate `y`, into
/// `y_next`, and its measures (the direct solver factored by [`prepare_direct`]).
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
    let started = Instant::now();
    let (alpha, tried) = if options.step_length {
        line_search(sys, h2, merit)
    } else {
        (T::one(), false)
    };
    sys.timings.line_search += millis(started);
    if let Some(repulsion) = &mut sys.repulsion {
        repulsion.correct(&sys.points, &sys.delta, alpha);
    }
    let started = Instant::now();
    let update = finish(sys, h2, alpha, tried, options);
    sys.timings.project += millis(started);
    update
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

/// Armijo backtracking on the merit (see the module's doc); leaves the accepted trial's
/// evaluation as the current one, keyed by its positions. Returns the step length and whether
/// a trial was evaluated (then the residual at `y` sits in `sys.trial`).
///
/// Below [`NOISE_FACTOR`] times the merit's round-off floor ([`super::evaluation::Evaluation::merit_noise`])
/// the merit cannot tell a decrease from round-off: a merit there takes the whole move, which
/// is itself of round-off size (`delta` is linear in the residual), without a trial (a body
/// in free fall or at rest converges so in one iteration and one kernel pass per step), and a
/// trial within that floor of the Armijo bound passes.
fn line_search<T: Real>(sys: &mut ParticleSystem<T>, h2: T, merit: f64) -> (T, bool) {
    let noise = NOISE_FACTOR * sys.current.merit_noise(&sys.points, h2, &mut sys.chunks);
    if merit <= noise {
        return (T::one(), false);
    }
    let mut alpha = T::one();
    for halving in 0..=MAX_HALVINGS {
        {
            let (y, delta) = (&sys.points.y, &sys.delta);
            sys.trial
                .at
                .par_iter_mut()
                .enumerate()
                .for_each(|(i, t)| *t = y[i] + delta[i] * alpha);
        }
        sys.trial.run(&sys.rest);
        sys.timings.evaluations += 1;
        let trial = sys.trial.residual_merit(&sys.points, h2, &mut sys.chunks);
        let bound = merit * (1.0 - 2.0 * ARMIJO_SIGMA * alpha.to_f64());
        if trial <= bound + noise || halving == MAX_HALVINGS || !trial.is_finite() {
            break;
        }
        alpha *= T::of(0.5);
    }
    std::mem::swap(&mut sys.current, &mut sys.trial);
    (alpha, true)
}

/// `y_next = y + alpha delta`, kept out of the colliders in the metric of the Jacobi diagonal
/// (with friction) and extrapolated (Chebyshev) where no collider touched it; the measures:
/// the largest move, and the largest residual per unit mass at `y` with the colliders'
/// reaction to the whole move added (as for membranes,
/// [`crate::solve::membranes::jacobi::free_residual`]).
fn finish<T: Real>(
    sys: &mut ParticleSystem<T>,
    h2: T,
    alpha: T,
    tried: bool,
    options: &MoveOptions<'_, T>,
) -> Update {
    let mut y_next = std::mem::take(&mut sys.points.y_next);
    // After a line search's trial the residual at `y` sits in `trial` (the evaluations
    // swapped).
    let residual = if tried {
        &sys.trial.residual
    } else {
        &sys.current.residual
    };
    let sys_ref = &*sys;
    let points = &sys_ref.points;
    let update = y_next
        .par_iter_mut()
        .enumerate()
        .map(|(i, next)| {
            let y = &points.y[i];
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
            if let Some(w) = options.omega.filter(|_| *next == free_move) {
                *next = (*next - points.y_prev[i]) * w + points.y_prev[i];
            }
            // With another family's reaction on the particle (a membrane's, `crate::solve::coupling`).
            let coupled = options.contact_reaction.get(i).copied().unwrap_or_default();
            let free = (residual[i] + (reaction + coupled) * d) / points.mass[i];
            let mut update = Update::of(i, y, next);
            update.residual = free.norm_squared().to_f64().sqrt();
            update
        })
        .reduce(|| Update::NONE, Update::merge);
    sys.points.y_next = y_next;
    update
}

/// How close to its margin (a fraction of the margin) a particle counts as touching a
/// collider for the direct solver ([`direct_move`]).
pub const CONTACT_GAP: f64 = 1e-3;
