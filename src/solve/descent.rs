//! The baseline of the paper's Fig. 13: Jacobi-preconditioned gradient descent with a
//! backtracking line search on the total variational energy (Wang and Yang 2016, "Descent
//! methods for elastic body simulation on the GPU"), optionally Chebyshev-accelerated.
//!
//! It minimises the same energy as SISSM with the same per-vertex preconditioner `D`; the
//! difference is the step: one global step length `alpha`, accepted only when the energy does
//! not rise (halved otherwise, kept across iterations), instead of SISSM's per-vertex step
//! length. Every trial costs a kernel evaluation and an energy reduction.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::membrane::Preconditioner;
use crate::real::Real;

use super::evaluate::{evaluate, total_energy};
use super::jacobi::{free_residual, keep_out, LocalSystem, MoveOptions, Update};
use super::system::System;

/// Halvings of the step length tried before a (tiny) step is taken regardless.
const MAX_HALVINGS: usize = 12;

/// Relative energy change treated as round-off: near the minimum the energy cannot resolve
/// smaller decreases, and insisting on them would halve the step to nothing.
const ENERGY_ROUND_OFF: f64 = 1e-12;

/// State of the line search within a time step.
#[derive(Debug, Clone, Copy)]
pub(super) struct LineSearch {
    /// Current global step length (starts at 1 each time step).
    pub alpha: f64,
    /// Variational energy of the current iterate (J).
    pub energy: f64,
}

/// One descent iteration from the responses evaluated at `y`: direction `d_k = D_k^-1 r_k`,
/// trial `y + alpha d` (kept out of colliders, Chebyshev-extrapolated on the first try),
/// accepted when `E` does not increase (beyond round-off), else `alpha` halves; a step
/// accepted at once doubles `alpha` again (up to 1). Leaves the accepted trial in
/// `y_next`, the responses evaluated there, and its energy in `search`.
pub(super) fn descent_iteration<T: Real>(
    sys: &mut System<T>,
    h: T,
    mode: Preconditioner,
    options: &MoveOptions<'_, T>,
    search: &mut LineSearch,
) -> Update {
    let h2 = h * h;
    let n = sys.y.len();
    if sys.locals.len() != n {
        let zero = LocalSystem::new(
            T::one(),
            Matrix3::zeros(),
            Vector3::zeros(),
            Vector3::zeros(),
            T::zero(),
        );
        sys.locals = vec![zero; n];
        sys.delta = vec![Vector3::zeros(); n];
    }
    let mut locals = std::mem::take(&mut sys.locals);
    let mut direction = std::mem::take(&mut sys.delta);
    let sys_ref = &*sys;
    let residual = locals
        .par_iter_mut()
        .zip(direction.par_iter_mut())
        .enumerate()
        .map(|(k, (local, d))| {
            if sys_ref.pinned[k] {
                *d = Vector3::zeros();
                return 0.0;
            }
            *local = LocalSystem::of(sys_ref, k, h2);
            *d = local.solve();
            free_residual(sys_ref, k, local, options)
        })
        .reduce(|| 0.0, f64::max);

    let mut omega = options.omega;
    let mut update = Update::NONE;
    for halving in 0..=MAX_HALVINGS {
        let alpha = T::of(search.alpha);
        let (y, y_prev, y_start, pinned, rest) =
            (&sys.y, &sys.y_prev, &sys.y_start, &sys.pinned, &sys.rest);
        update = sys
            .y_next
            .par_iter_mut()
            .enumerate()
            .map(|(k, next)| {
                if pinned[k] {
                    *next = y[k];
                    return Update::NONE;
                }
                let margin = rest.vertices[k].half_thickness;
                *next = keep_out(
                    y[k] + direction[k] * alpha,
                    &y_start[k],
                    &locals[k].inverse,
                    margin,
                    options.colliders,
                );
                if let Some(w) = omega {
                    *next = (*next - y_prev[k]) * w + y_prev[k];
                }
                for c in options.colliders {
                    *next = c.project(*next, margin);
                }
                Update::of(k, &y[k], next)
            })
            .reduce(|| Update::NONE, Update::merge);
        if update.first_bad.is_some() {
            break;
        }
        std::mem::swap(&mut sys.y, &mut sys.y_next);
        evaluate(sys, mode);
        let energy = total_energy(sys, h);
        std::mem::swap(&mut sys.y, &mut sys.y_next);
        if energy <= search.energy + ENERGY_ROUND_OFF * search.energy.abs()
            || halving == MAX_HALVINGS
        {
            search.energy = energy;
            if halving == 0 {
                search.alpha = (search.alpha * 2.0).min(1.0);
            }
            break;
        }
        search.alpha *= 0.5;
        omega = None;
    }
    sys.locals = locals;
    sys.delta = direction;
    Update { residual, ..update }
}
