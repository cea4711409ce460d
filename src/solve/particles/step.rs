//! One global iteration of the particle family (He et al. 2017, eq. 12-13): the residual at
//! the current iterate, the global solver's move (for Jacobi and Chebyshev with the bodies'
//! coarse translation, [`super::coarse`]), Armijo backtracking on the merit, the
//! colliders in the Jacobi metric with friction, Chebyshev extrapolation, and the measures.
//!
//! **Merit (eq. 13).** The deviatoric force (eq. 10) is not the gradient of any energy, so the
//! line search cannot ask the energy to fall. It asks the residual of eq. 12 to:
//! `phi(y) = sum_i |r_i|^2 / m_i` with `r = m (y* - y) + h^2 f(y)` (kg m^2), zero exactly at
//! the implicit Euler solution.
//!
//! **One kernel pass per iteration.** The line search's trials are the next iterates
//! themselves, colliders, repulsion and extrapolation applied, so that the accepted trial's
//! evaluation is the next iteration's. The first trial is the whole move, extrapolated where
//! the family's Chebyshev sequence extrapolates ([`super::chebyshev`]): it passes unless its
//! merit exceeds [`GROWTH`] times the merit where the sequence started (Chebyshev is no
//! descent method: its merit may rise between iterates while its error bound falls). A plain
//! trial passes when `phi(y + alpha delta) <= (1 - 2 sigma alpha) phi(y)` (`sigma` =
//! [`ARMIJO_SIGMA`]; for `delta = J^-1 r` the directional derivative of `phi` is `-2 phi`).
//! A rejected extrapolation restarts the sequence and tries the plain move; a rejected plain
//! move halves `alpha`, at most [`MAX_HALVINGS`] times, and the last trial is taken if none
//! passes. The Armijo test compares the merits over the particles no collider moved in the
//! trial (a moved particle's residual carries the collider's reaction, which no move takes
//! away), and a plain trial that a collider touched is taken without halvings (the projected
//! move is no descent direction of the free particles' merit).
//!
//! **Projected extrapolation.** A particle against frictionless colliders only, and which the
//! repulsion did not move, is extrapolated like every other and then kept out of the colliders
//! again: `y^{k+1} = P(w (P(y + delta) - y^{k-1}) + y^{k-1})`, `P` the projection in the
//! Jacobi metric. Left plain (as particles against frictional colliders still are), a body's
//! contact layer slides along the collider at the plain Jacobi rate while Chebyshev accelerates
//! the body above it, and its sideways residual is what stalls an impact step.

use std::time::Instant;

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::collider::{push_out_with_friction, ColliderModel};
use crate::parallel::chunked_sum;
use crate::real::Real;
use crate::solve::collider_passes::clear_of_colliders;
use crate::solve::points::Points;
use crate::solve::update::{MoveOptions, Update};
use crate::solve::GlobalSolver;
use crate::symmetric::SymmetricMatrix3;

use super::chebyshev::GROWTH;
use super::coarse;
use super::contact_gap::contact_reach;
use super::direct::DirectSolver;
use super::directions::{jacobi, position_averaging, two_level_correction};
use super::exact_iterate::known;
use super::roundoff::{residual_floor, MeasureReport};
use super::system::ParticleSystem;
use crate::timing::millis;

/// The sufficient-decrease constant of the Armijo condition.
pub const ARMIJO_SIGMA: f64 = 1e-4;
/// Most halvings of the step length in one line search (`alpha >= 1/16`).
pub const MAX_HALVINGS: usize = 4;
/// The move of one global iteration, from the evaluation at the current iterate `y`, into
/// `y_next`, and its measures (the direct solver factored by [`prepare_direct`]). With a line
/// search the evaluation at `y_next` is left as the current one (see the module's doc); the
/// step's own collider pass leaves `y_next` alone ([`Family::keeps_out_of_colliders`]).
///
/// [`Family::keeps_out_of_colliders`]: crate::solve::family::Family::keeps_out_of_colliders
pub(crate) fn global_move<T: Real>(
    sys: &mut ParticleSystem<T>,
    h: T,
    options: &MoveOptions<'_, T>,
) -> Update {
    let h2 = h * h;
    sys.exact.advance();
    let started = Instant::now();
    let merit = sys
        .current
        .residual_merit(&sys.rest, &sys.points, h2, &mut sys.chunks);
    let noise = merit_floor(sys, h2);
    sys.timings.residual += millis(started);
    let started = Instant::now();
    match options.global_solver {
        GlobalSolver::Jacobi | GlobalSolver::Chebyshev => {
            jacobi(sys, h2, options.inner_iters);
            coarse_correction(sys, h2, options);
            let two_level_started = Instant::now();
            two_level_correction(sys, h, options.colliders, options.contact_reaction);
            sys.timings.two_level += millis(two_level_started);
        }
        GlobalSolver::Position => position_averaging(sys, h2),
        GlobalSolver::Direct => {
            direct_move(sys, h, options.colliders);
            coarse_correction(sys, h2, options);
        }
    }
    sys.timings.solve += millis(started);
    let omega = sys.chebyshev.next(merit);
    let update = if options.step_length {
        line_search(sys, h2, merit, noise, omega, options)
    } else {
        propose(sys, h2, T::one(), omega, options)
    };
    // The accepted trial is the last one proposed: its friction multipliers are the iterate's.
    if let Some(repulsion) = &mut sys.repulsion {
        repulsion.accept();
    }
    update
}

/// The bodies' coarse correction ([`coarse::correct`]) after the move of a Jacobi sweep or of
/// the direct solver, timed: it carries each body's net residual as a rigid translation and
/// rotation, and each frictional contact's tangential reaction within its Coulomb cone, which
/// neither the sweep's local moves nor the direct solver's held contacts (their own Jacobi
/// moves, see [`DirectSolver`]) carry to the whole body (time step squared `h2`, s^2).
fn coarse_correction<T: Real>(sys: &mut ParticleSystem<T>, h2: T, options: &MoveOptions<'_, T>) {
    let started = Instant::now();
    coarse::correct(sys, options.colliders, options.contact_reaction, h2);
    sys.timings.coarse += millis(started);
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
/// a collider at the current iterate ([`contact_reach`]) and keeps the
/// ones that touched earlier in the step, so that it changes, and the matrix is refactored,
/// only as contacts form (see [`DirectSolver`]). Should a factorisation fail, the move is one
/// Jacobi sweep and the failure is reported at the end of the step.
fn direct_move<T: Real>(sys: &mut ParticleSystem<T>, h: T, colliders: &[ColliderModel<T>]) {
    {
        let points = &sys.points;
        sys.held.par_iter_mut().enumerate().for_each(|(i, held)| {
            let reach = contact_reach(points.margin[i]);
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

/// The line search of the module's doc over the trials `y_next` ([`propose`]), from the merit
/// `merit` (kg m^2) at `y`, its round-off floor `noise` ([`merit_floor`]) and the sequence's
/// weight `omega`; returns the accepted trial's
/// measures and leaves its evaluation as the current one.
///
/// Below the merit's round-off floor ([`merit_floor`]) the merit cannot tell a decrease from
/// round-off: a merit there takes the first trial without evaluating it (the move is itself
/// of round-off size: a body in free fall or at rest converges so in one iteration and one
/// kernel pass per step), and a trial within that floor of its bound passes.
fn line_search<T: Real>(
    sys: &mut ParticleSystem<T>,
    h2: T,
    merit: f64,
    noise: f64,
    mut omega: Option<T>,
    options: &MoveOptions<'_, T>,
) -> Update {
    let (mut alpha, mut halvings) = (T::one(), 0);
    loop {
        let update = propose(sys, h2, alpha, omega, options);
        if merit <= noise {
            return update;
        }
        let started = Instant::now();
        sys.trial.at.copy_from_slice(&sys.points.y_next);
        sys.trial.run(&sys.rest);
        sys.timings.trial_kernel += millis(started);
        sys.timings.evaluations += 1;
        let whole = sys
            .trial
            .residual_merit(&sys.rest, &sys.points, h2, &mut sys.chunks);
        let passes = if omega.is_some() {
            whole <= GROWTH * sys.chebyshev.start_merit + noise
        } else {
            let (points, touched) = (&sys.points, &sys.touched);
            let before = free_merit(&sys.current.residual, points, touched, &mut sys.chunks);
            let after = free_merit(&sys.trial.residual, points, touched, &mut sys.chunks);
            after <= before * (1.0 - 2.0 * ARMIJO_SIGMA * alpha.to_f64()) + noise
        };
        sys.timings.line_search += millis(started);
        let contact = omega.is_none() && sys.touched.iter().any(|&t| t);
        if passes || halvings == MAX_HALVINGS || contact || !whole.is_finite() {
            std::mem::swap(&mut sys.current, &mut sys.trial);
            return update;
        }
        if omega.is_some() {
            omega = None;
            sys.chebyshev.restart();
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

/// The merit's round-off floor (kg m^2): `sum_i m_i nu_i^2` with `nu_i` the floor of particle
/// `i`'s residual per unit mass ([`residual_floor`]), summed in fixed chunks.
fn merit_floor<T: Real>(sys: &mut ParticleSystem<T>, h2: T) -> f64 {
    let mut chunks = std::mem::take(&mut sys.chunks);
    let sys_ref = &*sys;
    let (y, mass) = (&sys_ref.points.y, &sys_ref.points.mass);
    let floor = chunked_sum(y.len(), &mut chunks, |i| {
        let nu = residual_floor(&y[i], sys_ref.diagonal(i, h2), mass[i]);
        mass[i].to_f64() * nu * nu
    });
    sys.chunks = chunks;
    floor
}

/// The trial `y_next = y + alpha delta` (with the repulsion's move), kept out of the colliders
/// in the metric of the Jacobi diagonal (with friction), and extrapolated by `omega`
/// (Chebyshev): against frictionless colliders and without a repulsion move, then kept out
/// again (the module's doc); otherwise only where no collider touched it and the extrapolation
/// cannot reach into a collider ([`extrapolated`]). `sys.touched` marks the particles a
/// collider or the repulsion moved. The measures: the
/// largest move, and the convergence measure: the largest residual per unit mass at `y` with
/// the colliders' reaction to the whole move added (as for membranes,
/// [`crate::solve::membranes::jacobi::free_residual`]), less its round-off floor
/// ([`residual_floor`]).
fn propose<T: Real>(
    sys: &mut ParticleSystem<T>,
    h2: T,
    alpha: T,
    omega: Option<T>,
    options: &MoveOptions<'_, T>,
) -> Update {
    let started = Instant::now();
    if let Some(repulsion) = &mut sys.repulsion {
        let rest = &sys.rest;
        let diagonal = |i: usize| rest.diagonal(i, h2);
        repulsion.correct(&sys.points, &sys.delta, alpha, diagonal);
    }
    let mut y_next = std::mem::take(&mut sys.points.y_next);
    let mut touched = std::mem::take(&mut sys.touched);
    let mut exact_next = std::mem::take(&mut sys.exact.next);
    let sys_ref = &*sys;
    let (points, residual) = (&sys_ref.points, &sys_ref.current.residual);
    // Whether every collider is frictionless (the projected extrapolation's condition), once
    // per trial rather than per particle: a particle's colliders are all of them or none.
    let frictionless = options.colliders.iter().all(|c| c.friction == T::zero());
    let update = y_next
        .par_iter_mut()
        .zip(touched.par_iter_mut())
        .zip(exact_next.par_iter_mut())
        .enumerate()
        .map(|(i, ((next, touched), exact_next))| {
            let y = &points.y[i];
            *touched = false;
            if points.pinned[i] {
                *next = *y;
                *exact_next = wide(y);
                return (Update::NONE, MeasureReport::NONE);
            }
            let d = sys_ref.diagonal(i, h2);
            let inverse = SymmetricMatrix3::from_diagonal(&Vector3::repeat(T::one() / d));
            let margin = points.margin[i];
            let colliders = Points::colliders_of(&points.collides, i, options.colliders);
            let push = |to: Vector3<T>| {
                push_out_with_friction(y, to, &points.y_start[i], &inverse, margin, colliders)
            };
            let repelled = sys_ref
                .repulsion
                .as_ref()
                .map_or(Vector3::zeros(), |r| r.of_particle(i));
            let whole = y + sys_ref.delta[i];
            let free_move = y + sys_ref.delta[i] * alpha;
            *next = push(free_move + repelled);
            // The colliders' and the repulsion's reaction to the whole move.
            let reaction = if alpha == T::one() {
                *next - free_move
            } else {
                push(whole + repelled) - whole
            };
            *touched = *next != free_move;
            // The trial unrounded ([`super::exact_iterate`]): the move `y + alpha delta`
            // formed in f64, extrapolated from the unrounded `y^{k-1}` and rounded once; in
            // the coordinates a collider or the repulsion moved, the stored trial's.
            let mut exact = known(&(wide(y) + wide(&sys_ref.delta[i]) * alpha.to_f64()), next);
            if let Some(w) = omega {
                let previous = sys_ref.exact.previous(i, &points.y_prev[i]);
                let moved = (exact - previous) * w.to_f64() + previous;
                let rounded = moved.map(T::of);
                if repelled == Vector3::zeros() && (frictionless || colliders.is_empty()) {
                    // Projected extrapolation: the contact layer is accelerated with the rest.
                    *next = push(rounded);
                    *touched |= *next != rounded;
                    exact = moved;
                } else if !*touched && clear_of_colliders(next, &rounded, margin, colliders) {
                    *next = rounded;
                    exact = moved;
                }
            }
            *exact_next = known(&exact, next);
            // With another family's reaction on the particle (a membrane's, `crate::solve::coupling`).
            let coupled = options.contact_reaction.get(i).copied().unwrap_or_default();
            let free = (residual[i] + (reaction + coupled) * d) / points.mass[i];
            let mut update = Update::of(i, y, next);
            let floor = residual_floor(y, d, points.mass[i]);
            update.residual = (free.norm_squared().to_f64().sqrt() - floor).max(0.0);
            (update, MeasureReport::of(i, update.residual, floor))
        })
        .reduce(
            || (Update::NONE, MeasureReport::NONE),
            |a, b| (Update::merge(a.0, b.0), MeasureReport::merge(a.1, b.1)),
        );
    sys.points.y_next = y_next;
    sys.touched = touched;
    sys.exact.next = exact_next;
    let (update, report) = update;
    sys.timings.roundoff_floor = report.floor;
    sys.timings.worst_particle = report.particle.map(|i| sys.points.locate(i));
    sys.timings.project += millis(started);
    update
}

/// `v` in f64 (m).
#[inline(always)]
fn wide<T: Real>(v: &Vector3<T>) -> Vector3<f64> {
    v.map(|c| c.to_f64())
}
