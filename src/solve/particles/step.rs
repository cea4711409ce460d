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

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::collider::push_out_with_friction;
use crate::real::Real;
use crate::solve::points::Points;
use crate::solve::update::{MoveOptions, Update};
use crate::solve::GlobalSolver;
use crate::symmetric::SymmetricMatrix3;

use super::direct::DirectSolver;
use super::directions::{jacobi, position_averaging};
use super::system::ParticleSystem;

/// The sufficient-decrease constant of the Armijo condition.
pub const ARMIJO_SIGMA: f64 = 1e-4;
/// Most halvings of the step length in one line search (`alpha >= 1/16`).
pub const MAX_HALVINGS: usize = 4;

/// The move of one global iteration, from the evaluation at the current iterate `y`, into
/// `y_next`, and its measures (the direct solver factored by [`prepare_direct`]).
pub(crate) fn global_move<T: Real>(
    sys: &mut ParticleSystem<T>,
    h: T,
    options: &MoveOptions<'_, T>,
) -> Update {
    let h2 = h * h;
    let merit = sys.current.residual_merit(&sys.points, h2, &mut sys.chunks);
    match options.global_solver {
        GlobalSolver::Jacobi | GlobalSolver::Chebyshev => jacobi(sys, h2, options.inner_iters),
        GlobalSolver::Position => position_averaging(sys, h2),
        GlobalSolver::Direct => {
            let (residual, points) = (&sys.current.residual, &sys.points);
            sys.scratch.par_iter_mut().enumerate().for_each(|(i, r)| {
                *r = supported(
                    &residual[i],
                    &points.y[i],
                    points.margin[i],
                    Points::colliders_of(&points.collides, i, options.colliders),
                );
            });
            let direct = sys.direct.as_mut().expect("factored by prepare_direct");
            direct.solve(&sys.scratch, &mut sys.delta);
        }
    }
    let alpha = if options.step_length {
        line_search(sys, h2, merit)
    } else {
        T::one()
    };
    if let Some(repulsion) = &mut sys.repulsion {
        repulsion.correct(&sys.points, &sys.delta, alpha);
    }
    finish(sys, h2, alpha, options)
}

/// Factors the direct solver's matrix for the time step `h` (s) and the current pins unless
/// the factor at hand is for them (before the iterations, which then allocate nothing).
pub(crate) fn prepare_direct<T: Real>(
    sys: &mut ParticleSystem<T>,
    h: f64,
) -> crate::error::Result<()> {
    let pinned = &sys.points.pinned;
    if !sys.direct.as_ref().is_some_and(|d| d.matches(h, pinned)) {
        sys.direct = Some(DirectSolver::factor(&sys.rest, h, pinned)?);
    }
    Ok(())
}

/// Armijo backtracking on the merit (see the module's doc); leaves the accepted trial's
/// evaluation as the current one, keyed by its positions.
fn line_search<T: Real>(sys: &mut ParticleSystem<T>, h2: T, merit: f64) -> T {
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
        let trial = sys.trial.residual_merit(&sys.points, h2, &mut sys.chunks);
        let bound = merit * (1.0 - 2.0 * ARMIJO_SIGMA * alpha.to_f64());
        if trial <= bound || halving == MAX_HALVINGS || !trial.is_finite() {
            break;
        }
        alpha *= T::of(0.5);
    }
    std::mem::swap(&mut sys.current, &mut sys.trial);
    // The residual at `y` (for the measures) is in what is now the trial evaluation.
    alpha
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
    options: &MoveOptions<'_, T>,
) -> Update {
    let mut y_next = std::mem::take(&mut sys.points.y_next);
    // After a line search the residual at `y` sits in `trial` (the evaluations swapped).
    let residual = if options.step_length {
        &sys.trial.residual
    } else {
        &sys.current.residual
    };
    let direct = options.global_solver == GlobalSolver::Direct;
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
            let free = if direct {
                sys_ref.scratch[i] / points.mass[i]
            } else {
                (residual[i] + reaction * d) / points.mass[i]
            };
            let mut update = Update::of(i, y, next);
            update.residual = free.norm_squared().to_f64().sqrt();
            update
        })
        .reduce(|| Update::NONE, Update::merge);
    sys.points.y_next = y_next;
    update
}

/// The residual `r` (kg m) of a particle at `y` (m) with the colliders' support taken out, for
/// the direct solver.
///
/// With a non-diagonal solve, projecting the moves out of the colliders does not converge to
/// the constrained solution: the solve spreads a supported particle's pull into the free
/// ones, and the projection only stops the supported particle. So a particle that rests on a
/// collider (within [`CONTACT_GAP`] of its margin `margin`, m, at `y`) has the part of its
/// residual that pushes into the collider (along the collider's normal `n`) removed before the
/// solve: the collider carries it. At a fixed point every free particle's residual is zero
/// and a resting one's pushes only into its collider, the constrained implicit Euler solution
/// (frictionless for the solve; the projection that follows applies friction to the move).
#[inline]
fn supported<T: Real>(
    residual: &Vector3<T>,
    y: &Vector3<T>,
    margin: T,
    colliders: &[crate::collider::ColliderModel<T>],
) -> Vector3<T> {
    let reach = margin * (T::one() + T::of(CONTACT_GAP));
    let mut r = *residual;
    for c in colliders {
        if c.signed_distance(y) <= reach {
            let n = c.normal(y);
            r -= n * r.dot(&n).min(T::zero());
        }
    }
    r
}

/// How close to its margin (a fraction of the margin) a particle counts as resting on a
/// collider for the direct solver ([`supported`]).
pub const CONTACT_GAP: f64 = 1e-3;
