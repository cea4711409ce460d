//! The global step's move `delta` from the residual `r` of eq. 12 (He et al. 2017, section 4.2,
//! Fig. 7), by one of the global solvers: the linear system `(M + h^2 L) delta = r` with the
//! local step's projections held (its fixed point, `r = 0`, is the implicit Euler solution
//! whatever the solver).
//!
//! - Jacobi: `delta_i = D_i^-1 (r_i + h^2 sum_j L_ij-weights delta_j)`, `D_i = m_i + h^2 L_ii`,
//!   from `delta = 0`: one sweep is `D^-1 r` (with Chebyshev acceleration on top, the
//!   paper's default);
//! - position-based averaging: every bond's two particles solve their own 2 x 2 block of the
//!   system, and each particle moves by the average of what its bonds ask (the constraint
//!   averaging of position-based dynamics, in residual form);
//! - direct: [`super::direct::DirectSolver`].
//!
//! Jacobi and Chebyshev's sweep is followed by the bodies' coarse translations
//! ([`super::coarse`]) and the two-level correction on aggregates ([`super::two_level`]).
//!
//! Each particle's move is computed alone from the previous sweep, so the results are the same
//! for any number of threads.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::collider::ColliderModel;
use crate::error::Result;
use crate::real::Real;

use super::system::ParticleSystem;
use super::two_level::TwoLevel;

/// `inner` Jacobi sweeps on `(M + h^2 L) delta = r` from `delta = 0`, into `sys.delta`.
pub(crate) fn jacobi<T: Real>(sys: &mut ParticleSystem<T>, h2: T, inner: usize) {
    let mut delta = std::mem::take(&mut sys.delta);
    let mut scratch = std::mem::take(&mut sys.scratch);
    {
        let (sys, residual, pinned) = (&*sys, &sys.current.residual, &sys.points.pinned);
        delta.par_iter_mut().enumerate().for_each(|(i, d)| {
            *d = if pinned[i] {
                Vector3::zeros()
            } else {
                residual[i] / sys.diagonal(i, h2)
            };
        });
        for _ in 1..inner {
            let previous = &delta;
            scratch.par_iter_mut().enumerate().for_each(|(i, d)| {
                if pinned[i] {
                    *d = Vector3::zeros();
                    return;
                }
                let mut coupled = Vector3::zeros();
                for b in sys.rest.row(i) {
                    coupled += previous[sys.rest.indices[b] as usize] * sys.rest.coupling[b];
                }
                *d = (residual[i] + coupled * h2) / sys.diagonal(i, h2);
            });
            std::mem::swap(&mut delta, &mut scratch);
        }
    }
    sys.delta = delta;
    sys.scratch = scratch;
}

/// Position-based averaging, into `sys.delta`: particle `i` with `n_i` bonds moves by
/// `(1 / n_i) sum_b d_i^b`, where bond `b` to `j` solves its two particles' block of the
/// global matrix, `[D_i, -s; -s, D_j] [d_i; d_j] = [r_i; r_j]`, `D = m + h^2 L_ii`,
/// `s = h^2 (k_ij + k_ji)` (a pinned `j` keeps `d_j = 0`): the average of the bonds' own
/// projections, as position-based dynamics averages its constraints' (Macklin et al. 2014).
/// Without coupling it is a Jacobi sweep; a bond whose particles are pulled alike lets them
/// move further together, one whose particles are pulled apart holds them back.
pub(crate) fn position_averaging<T: Real>(sys: &mut ParticleSystem<T>, h2: T) {
    let mut delta = std::mem::take(&mut sys.delta);
    {
        let sys = &*sys;
        let (rest, residual, pinned) = (&sys.rest, &sys.current.residual, &sys.points.pinned);
        delta.par_iter_mut().enumerate().for_each(|(i, d)| {
            *d = Vector3::zeros();
            if pinned[i] {
                return;
            }
            let d_i = sys.diagonal(i, h2);
            for b in rest.row(i) {
                let j = rest.indices[b] as usize;
                *d += if pinned[j] {
                    residual[i] / d_i
                } else {
                    let s = h2 * rest.coupling[b];
                    let d_j = sys.diagonal(j, h2);
                    (residual[i] * d_j + residual[j] * s) / (d_i * d_j - s * s)
                };
            }
            *d /= T::of(rest.row(i).len() as f64);
        });
    }
    sys.delta = delta;
}

/// Builds the two-level correction ([`super::two_level`]) on the first step that asks for it,
/// if some particle takes part (of a solid body that is not plastic), and readies it for the
/// step.
pub(crate) fn prepare_two_level<T: Real>(sys: &mut ParticleSystem<T>) -> Result<()> {
    if sys.two_level.is_none() {
        let plastic = sys.plastic.as_ref();
        let takes_part: Vec<bool> = (sys.coarse.solid.iter().enumerate())
            .map(|(b, &solid)| solid && !plastic.is_some_and(|p| p.is_plastic(b)))
            .collect();
        sys.two_level = TwoLevel::of_bodies(&sys.rest, &sys.points.ranges, &takes_part)?;
    }
    if let Some(two) = &mut sys.two_level {
        two.start_step();
    }
    Ok(())
}

/// Adds the two-level correction to the sweep's move `sys.delta` from the residual at the
/// current iterate, after the step's first iteration ([`super::two_level`], "When");
/// `coupled` holds another family's reaction per particle. A failed factorisation leaves the
/// move alone and is reported at the end of the step.
pub(crate) fn two_level_correction<T: Real>(
    sys: &mut ParticleSystem<T>,
    h: T,
    colliders: &[ColliderModel<T>],
    coupled: &[Vector3<T>],
) {
    let Some(two) = &mut sys.two_level else {
        return;
    };
    if !two.past_first_iteration() {
        return;
    }
    let (points, repulsion) = (&sys.points, sys.repulsion.as_ref());
    two.hold(
        &sys.rest,
        &sys.current.residual,
        h,
        points,
        &sys.touched,
        &sys.delta,
        colliders,
        coupled,
        repulsion,
    );
    if let Err(e) = two.correct(&sys.rest, &sys.current.residual, &mut sys.delta, h) {
        sys.failure.get_or_insert(e);
    }
}
