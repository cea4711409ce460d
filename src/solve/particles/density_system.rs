//! The fluids' density constraints linearised at the working positions, and the
//! preconditioned conjugate gradients that solve them ([`super::fluid`]'s `cg` solver).
//!
//! **The system.** With `J` the constraints' Jacobian (row `i`: `grad_k C_i = d rho~_i / d y_k
//! / rho0_i`, 1/m), `W` the members' mobilities (`w_k`, the inverse-mass shares of
//! [`super::fluid`], 0 for a pinned member: it does not move) and `eps_i` (1/m^2) a
//! regulariser, the multipliers of one linearisation solve the Schur complement
//! `(J W J^T + eps) lambda = b` on the active constraints (`lambda` in m^2, `b_i = -ask_i
//! C_i`, dimensionless, `ask_i` the fraction of its violation row `i` asks), and the members
//! move by `dy = W J^T lambda` (m). This is Macklin and Mueller's (2013) eq. 9-12 with all
//! constraints coupled: their Jacobi iteration takes
//! `lambda_i = b_i / A_ii` (eq. 11, the diagonal of this matrix) and relinearises; here the
//! coupled system is solved first, so that a correction travels across the whole liquid in
//! one linearisation and not one kernel support per pass. Inactive constraints (a surface
//! particle below rest, a partner) are rows of the identity with `b_i = 0` and `lambda_i =
//! 0`: `A` is symmetric positive definite on the active set (`eps > 0`).
//!
//! **The solver.** Conjugate gradients preconditioned by `diag(A)` (the Jacobi denominators),
//! from `lambda = 0`, until every constraint's remainder `|b_i - (A lambda)_i| / ask_i` (the
//! part of `C_i` its linearised moves still owe, relative density; `ask_i` the fraction of the
//! violation its `b_i` asks) is within the asked bound or after the iterations allowed. Each
//! iteration applies `J^T` and `J` once (the work of one Jacobi pass without its gradients).
//! Inner products sum fixed chunks of [`DOT_CHUNK`] entries in `f64` in parallel and then the
//! chunks in order: the same bits for any number of threads.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::geometry::bounds::nan_max;
use crate::parallel::GRAIN;
use crate::real::Real;

use super::density_walls::{slide, Walls};

/// Entries per partial sum of an inner product (fixed, so that the sum's order does not depend
/// on the threads).
const DOT_CHUNK: usize = 1024;

/// The density constraints linearised at the working positions (see the module's doc). The
/// gradient arrays are in kg/m^4 (`d rho~_i / d y_k`, not yet divided by `rho0_i`).
pub(super) struct DensitySystem<'a, T: Real> {
    /// Neighbour lists (CSR over the members; a member is not its own neighbour).
    pub offsets: &'a [u32],
    pub indices: &'a [u32],
    /// Per member, `d rho~_i / d y_i`; per CSR entry `(i, j)`, `d rho~_i / d y_j`.
    pub own: &'a [Vector3<T>],
    pub grads: &'a [Vector3<T>],
    /// Per CSR entry `(i, j)`, the index of the entry `(j, i)`.
    pub mirror: &'a [u32],
    /// Per member: rest density `rho0_i` (kg/m^3) and regulariser `eps_i` (1/m^2).
    pub rest: &'a [T],
    pub eps: &'a [T],
    /// Per member, its mobility `w_k` (dimensionless; 0 for a member that does not move).
    pub mobility: &'a [T],
    /// Per member, the walls it slides on ([`Walls`]: its moves lose their normal parts,
    /// `W_k = w_k (I - sum_n n n^T)`; [`super::density_walls`]).
    pub walls: &'a [Walls<T>],
    /// Per member, whether its constraint is in the system.
    pub active: &'a [bool],
}

impl<T: Real> DensitySystem<'_, T> {
    /// The move of member `k` before its walls' slide, `w_k (J^T p)_k` (m for `p` in m^2):
    /// `w_k (grad_k C_k p_k + sum_j grad_k C_j p_j)`, where `grad_k C_j` is the entry of `k` in
    /// `j`'s row.
    pub fn unslid(&self, k: usize, p: &[T]) -> Vector3<T> {
        let (offsets, indices, mirror, grads, rest) = (
            self.offsets,
            self.indices,
            self.mirror,
            self.grads,
            self.rest,
        );
        let mut sum = self.own[k] * (p[k] / rest[k]);
        for b in offsets[k] as usize..offsets[k + 1] as usize {
            let j = indices[b] as usize;
            sum += grads[mirror[b] as usize] * (p[j] / rest[j]);
        }
        sum * self.mobility[k]
    }

    /// The moves `u = W J^T p` (m for `p` in m^2) of every member: [`Self::unslid`] less its
    /// parts along the member's walls.
    pub fn spread(&self, p: &[T], u: &mut [Vector3<T>]) {
        let walls = self.walls;
        u.par_iter_mut()
            .with_min_len(GRAIN)
            .enumerate()
            .for_each(|(k, u)| *u = slide(&walls[k], self.unslid(k, p)));
    }

    /// `q = A p` (see the module's doc), with `u` the scratch of the moves `W J^T p`; `p` must
    /// be 0 on the inactive constraints.
    pub fn apply(&self, p: &[T], u: &mut [Vector3<T>], q: &mut [T]) {
        self.spread(p, u);
        let u = &*u;
        let (offsets, indices, own, grads) = (self.offsets, self.indices, self.own, self.grads);
        let (rest, eps, active) = (self.rest, self.eps, self.active);
        q.par_iter_mut()
            .with_min_len(GRAIN)
            .enumerate()
            .for_each(|(i, q)| {
                *q = if active[i] {
                    let mut sum = own[i].dot(&u[i]);
                    for b in offsets[i] as usize..offsets[i + 1] as usize {
                        sum += grads[b].dot(&u[indices[b] as usize]);
                    }
                    sum / rest[i] + eps[i] * p[i]
                } else {
                    T::zero()
                };
            });
    }

    /// The diagonal `A_ii = sum_k w_k |P_k grad_k C_i|^2 + eps_i` (1/m^2, `P_k` the slide of
    /// [`slide`]) of the active constraints, with the members' weights `w` (1 on the inactive
    /// ones).
    pub fn diagonal(&self, weights: &[T], out: &mut [T]) {
        let (offsets, indices, own, grads) = (self.offsets, self.indices, self.own, self.grads);
        let walls = self.walls;
        let slide = |g: &Vector3<T>, k: usize| slide(&walls[k], *g).norm_squared();
        let (rest, eps, active) = (self.rest, self.eps, self.active);
        out.par_iter_mut()
            .with_min_len(GRAIN)
            .enumerate()
            .for_each(|(i, d)| {
                *d = if active[i] {
                    let mut norm2 = slide(&own[i], i) * weights[i];
                    for b in offsets[i] as usize..offsets[i + 1] as usize {
                        let j = indices[b] as usize;
                        norm2 += slide(&grads[b], j) * weights[j];
                    }
                    norm2 / (rest[i] * rest[i]) + eps[i]
                } else {
                    T::one()
                };
            });
    }
}

/// The work vectors of the conjugate gradients (see the module's doc), kept between steps.
#[derive(Default)]
pub(super) struct ConjugateGradients<T: Real> {
    residual: Vec<T>,
    preconditioned: Vec<T>,
    direction: Vec<T>,
    product: Vec<T>,
    diagonal: Vec<T>,
    moves: Vec<Vector3<T>>,
    partial: Vec<f64>,
}

impl<T: Real> ConjugateGradients<T> {
    /// Sizes the work vectors for `n` constraints (allocates only when `n` grows).
    pub fn resize(&mut self, n: usize) {
        for v in [
            &mut self.residual,
            &mut self.preconditioned,
            &mut self.direction,
            &mut self.product,
            &mut self.diagonal,
        ] {
            v.resize(n, T::zero());
        }
        self.moves.resize(n, Vector3::zeros());
        self.partial.resize(n.div_ceil(DOT_CHUNK), 0.0);
    }

    /// Solves `A lambda = b` (`b` 0 on the inactive constraints) from `lambda = 0` until
    /// every constraint's remainder is within `bound` or after `most` iterations; the
    /// iterations taken. After [`Self::resize`].
    ///
    /// The remainder is in the constraint's own units: row `i` asks the fraction `ask_i` of its
    /// violation (`b_i = -ask_i C_i`; 1, or the adhesion's relaxation), so `|b - A lambda|_i /
    /// ask_i` is the part of `C_i` the linearised moves still owe, and a linearisation whose
    /// largest violation is above `bound` takes at least one iteration (with `bound` on the
    /// residual itself, a relaxed row's `|b_i|` below `bound` stopped the solve before it
    /// started). A NaN remainder (a non-finite gradient, an overflow) stops the solve with
    /// `lambda` NaN: the moves carry it into the positions, and the step's check for non-finite
    /// velocities raises, as a diverged step does elsewhere.
    pub fn solve(
        &mut self,
        system: &DensitySystem<T>,
        (b, ask): (&[T], &[T]),
        lambda: &mut [T],
        bound: f64,
        most: usize,
    ) -> usize {
        system.diagonal(system.mobility, &mut self.diagonal);
        lambda.fill(T::zero());
        self.residual.copy_from_slice(b);
        let mut iterations = 0;
        let mut rz = self.precondition();
        self.direction.copy_from_slice(&self.preconditioned);
        while iterations < most {
            let left = remainder(&self.residual, ask);
            if left.is_nan() {
                lambda.fill(T::of(f64::NAN));
                break;
            }
            if left <= bound {
                break;
            }
            system.apply(&self.direction, &mut self.moves, &mut self.product);
            iterations += 1;
            let pq = dot(&self.direction, &self.product, &mut self.partial);
            if pq <= 0.0 || rz <= 0.0 {
                break;
            }
            let alpha = T::of(rz / pq);
            (lambda.par_iter_mut().zip(&self.direction))
                .with_min_len(GRAIN)
                .for_each(|(l, &p)| *l += alpha * p);
            (self.residual.par_iter_mut().zip(&self.product))
                .with_min_len(GRAIN)
                .for_each(|(r, &q)| *r -= alpha * q);
            let next = self.precondition();
            let beta = T::of(next / rz);
            rz = next;
            (self.direction.par_iter_mut().zip(&self.preconditioned))
                .with_min_len(GRAIN)
                .for_each(|(p, &z)| *p = z + beta * *p);
        }
        iterations
    }

    /// `z = r / diag(A)` and the inner product `r . z`.
    fn precondition(&mut self) -> f64 {
        (self.preconditioned.par_iter_mut())
            .zip(self.residual.par_iter().zip(&self.diagonal))
            .with_min_len(GRAIN)
            .for_each(|(z, (&r, &d))| *z = r / d);
        dot(&self.residual, &self.preconditioned, &mut self.partial)
    }
}

/// `a . b` summed in `f64` over fixed chunks in parallel, then over the chunks in order.
fn dot<T: Real>(a: &[T], b: &[T], partial: &mut [f64]) -> f64 {
    (partial.par_iter_mut())
        .zip(a.par_chunks(DOT_CHUNK).zip(b.par_chunks(DOT_CHUNK)))
        .for_each(|(sum, (a, b))| {
            *sum = a
                .iter()
                .zip(b)
                .map(|(&x, &y)| x.to_f64() * y.to_f64())
                .sum();
        });
    partial.iter().sum()
}

/// `max_i |r_i| / ask_i` (see [`ConjugateGradients::solve`]), NaN if any term is.
fn remainder<T: Real>(r: &[T], ask: &[T]) -> f64 {
    (r.par_iter().zip(ask))
        .with_min_len(GRAIN)
        .map(|(x, a)| (x.to_f64() / a.to_f64()).abs())
        .reduce(|| 0.0, nan_max)
}

#[cfg(test)]
#[path = "density_system_tests.rs"]
mod tests;
