//! The two-level correction of the particles' Jacobi sweep (issue 38): a coarse-grid
//! correction on aggregates of particles, which holds the slow elastic modes the sweep barely
//! moves (a body's compression against the floor after a landing: its Jacobi factor is
//! `1 - (1 + (h w)^2) m / D`, within 1e-3 of 1 at 8K particles).
//!
//! **What.** The global step's linear system is `A delta = r` with `A = M + h^2 L` (eq. 12;
//! `L` the constant bond matrix, the same for the three coordinates). After the sweep's move
//! `delta_J = D^-1 r` the correction adds `delta += P e`, the Galerkin coarse-grid correction
//!
//! `(P^T A P) e = P^T (r - A delta_J)`,
//!
//! with `P` the piecewise-constant prolongation of the free particles' aggregates: `P_ia = 1`
//! where free particle `i` lies in aggregate `a`, 0 otherwise (the multiplicative two-level
//! method with a Jacobi smoother; Vanek, Mandel and Brezina 1996 for the aggregation).
//! `P^T A P` is formed from `A`'s entries (`(P^T A P)_ab = sum_(i in a, j in b) A_ij`, `i`
//! and `j` free) and factored by a sparse Cholesky (AMD ordering, [`SparseLlt`]) when the time
//! step or the held set changes; each iteration then restricts the sweep's residual
//! `r - A delta_J` (one pass over the bonds), solves for the three coordinates and prolongs.
//!
//! **Held particles.** A pinned particle, one another family holds (a membrane's reaction,
//! [`crate::solve::coupling`]), one a collider or the repulsion moved in the last trial
//! (`touched`) and one within [`CONTACT_GAP`] of a collider's margin at the current iterate
//! has no column in `P`: the correction leaves it where the sweep put it, and the body's
//! aggregates above a floor compress against it (the contact held in the coarse space, as the
//! direct solver holds it, [`super::direct`]). The colliders, the repulsion and the
//! translations' coarse problem ([`super::coarse`], which keeps the contacts one-sided) follow.
//! Since the correction is a Galerkin projection it leaves the fixed point `r = 0` alone.
//!
//! **Aggregates.** Plain aggregation on the bond graph, once per working set, in particle
//! order (the same for any thread count): a particle whose neighbours are all unaggregated
//! founds an aggregate of itself and them (about the 30 particles of a horizon); a leftover
//! joins the aggregate of its first aggregated neighbour, else founds one with its
//! unaggregated neighbours. Granular and fluid bodies take no part (their particles are held
//! by their own constraints, not by bonds), nor does a family with a plastic body (its bonds
//! change every step); their particles have no aggregate.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::collider::ColliderModel;
use crate::error::{invalid, Result};
use crate::particles::ParticleRest;
use crate::real::Real;
use crate::solve::points::Points;
use crate::sparse_llt::SparseLlt;

use super::step::CONTACT_GAP;
use super::system::ParticleSystem;

/// No aggregate (a particle of a body that takes no part), or no slot (a bond whose entry is
/// in the upper triangle or outside the coarse matrix).
const NONE: usize = usize::MAX;

/// The aggregates, the coarse matrix `P^T A P` and its factor for one time step and held set.
pub(crate) struct TwoLevel {
    /// Per particle its aggregate, or [`NONE`].
    aggregate: Vec<usize>,
    /// The time step (s) and per particle whether it was free when last factored (`h = NaN`:
    /// no factor yet), and this iteration's free set.
    h: f64,
    factored_free: Vec<bool>,
    free: Vec<bool>,
    /// `P^T A P` (right-hand sides `aggregates x 3`); per aggregate the slot of its diagonal
    /// and per bond the slot of its entry (or [`NONE`]).
    llt: SparseLlt,
    diagonal_slot: Vec<usize>,
    bond_slot: Vec<usize>,
    /// Per particle the sweep's residual `r - A delta_J` (kg m), and a held particle's move
    /// (m): the sweep's, out of the colliders along their normals.
    remainder: Vec<Vector3<f64>>,
    held_move: Vec<Vector3<f64>>,
    /// Numeric factorisations since the last [`Self::take_factorizations`].
    factorizations: usize,
}

impl TwoLevel {
    /// The aggregates of the particles `takes_part` marks, on the bonds of `rest`, the
    /// pattern of their coarse matrix and its symbolic factor (no numeric factor yet).
    pub fn new<T: Real>(rest: &ParticleRest<T>, takes_part: &[bool]) -> Result<Self> {
        let n = rest.len();
        let neighbours = |i: usize| rest.row(i).map(|b| rest.indices[b] as usize);
        let mut aggregate = vec![NONE; n];
        let mut count = 0;
        for i in 0..n {
            if takes_part[i] && aggregate[i] == NONE && neighbours(i).all(|j| aggregate[j] == NONE)
            {
                aggregate[i] = count;
                neighbours(i).for_each(|j| aggregate[j] = count);
                count += 1;
            }
        }
        let founded = aggregate.clone();
        for i in 0..n {
            if takes_part[i] && aggregate[i] == NONE {
                if let Some(j) = neighbours(i).find(|&j| founded[j] != NONE) {
                    aggregate[i] = founded[j];
                } else {
                    aggregate[i] = count;
                    for j in neighbours(i) {
                        if aggregate[j] == NONE {
                            aggregate[j] = count;
                        }
                    }
                    count += 1;
                }
            }
        }
        let mut lower: Vec<(usize, usize)> = (0..count).map(|a| (a, a)).collect();
        for i in 0..n {
            let a = aggregate[i];
            if a == NONE {
                continue;
            }
            lower.extend(
                neighbours(i)
                    .map(|j| aggregate[j])
                    .filter(|&b| b != NONE && b < a)
                    .map(|b| (a, b)),
            );
        }
        lower.sort_unstable();
        lower.dedup();
        let llt = SparseLlt::new(count, lower, 3)
            .map_err(|e| invalid!("the two-level coarse matrix's pattern failed: {e}"))?;
        let diagonal_slot = (0..count).map(|a| llt.slot(a, a)).collect();
        let mut bond_slot = vec![NONE; rest.indices.len()];
        for i in 0..n {
            let a = aggregate[i];
            for b in rest.row(i) {
                let c = aggregate[rest.indices[b] as usize];
                if a != NONE && c != NONE && c <= a {
                    bond_slot[b] = llt.slot(a, c);
                }
            }
        }
        Ok(Self {
            aggregate,
            h: f64::NAN,
            factored_free: vec![false; n],
            free: vec![false; n],
            llt,
            diagonal_slot,
            bond_slot,
            remainder: vec![Vector3::zeros(); n],
            held_move: vec![Vector3::zeros(); n],
            factorizations: 0,
        })
    }

    /// Numeric factorisations since the last call (a measure for [`crate::solve::StepStats`]).
    pub fn take_factorizations(&mut self) -> usize {
        std::mem::take(&mut self.factorizations)
    }

    /// Fills `P^T A P` for the time step `h` (s) and the free set, and factors it, unless the
    /// factor at hand is that one. An aggregate without a free particle keeps a unit diagonal
    /// (its unknown is decoupled and its right-hand side zero).
    fn factor<T: Real>(&mut self, rest: &ParticleRest<T>, h: f64) -> Result<()> {
        if self.h == h && self.factored_free == self.free {
            return Ok(());
        }
        let h2 = h * h;
        let (aggregate, free) = (&self.aggregate, &self.free);
        let values = self.llt.values_mut();
        values.fill(0.0);
        for i in 0..aggregate.len() {
            let a = aggregate[i];
            if a == NONE || !free[i] {
                continue;
            }
            values[self.diagonal_slot[a]] +=
                rest.mass[i].to_f64() + h2 * rest.stiffness[i].to_f64();
            for b in rest.row(i) {
                let slot = self.bond_slot[b];
                if slot != NONE && free[rest.indices[b] as usize] {
                    values[slot] -= h2 * rest.coupling[b].to_f64();
                }
            }
        }
        for &slot in &self.diagonal_slot {
            if values[slot] == 0.0 {
                values[slot] = 1.0;
            }
        }
        self.h = f64::NAN;
        self.factorizations += 1;
        self.llt
            .factor()
            .map_err(|e| invalid!("the two-level coarse factorisation failed: {e}"))?;
        self.h = h;
        self.factored_free.copy_from_slice(&self.free);
        Ok(())
    }
}

/// Whether particle `i` takes part in the two-level correction: every particle of a solid
/// body (not granular, no fluid particle) when no body is plastic.
fn takes_part<T: Real>(sys: &ParticleSystem<T>) -> Vec<bool> {
    let mut part = vec![false; sys.points.y.len()];
    if sys.plastic.is_some() {
        return part;
    }
    for (b, range) in sys.points.ranges.iter().enumerate() {
        if sys.coarse.solid[b] {
            part[range.clone()].fill(true);
        }
    }
    part
}

/// Builds the aggregates and the coarse matrix's pattern on the first step that asks for the
/// correction, if some particle takes part ([`takes_part`]).
pub(crate) fn prepare<T: Real>(sys: &mut ParticleSystem<T>) -> Result<()> {
    if sys.two_level.is_none() {
        let part = takes_part(sys);
        if part.iter().any(|&p| p) {
            sys.two_level = Some(TwoLevel::new(&sys.rest, &part)?);
        }
    }
    Ok(())
}

/// Adds the two-level correction (module doc) to the sweep's move `sys.delta` from the
/// residual `sys.current.residual`; `coupled` holds another family's reaction per particle.
/// A failed factorisation leaves the move alone and is reported at the end of the step.
pub(crate) fn correct<T: Real>(
    sys: &mut ParticleSystem<T>,
    h: T,
    colliders: &[ColliderModel<T>],
    coupled: &[Vector3<T>],
) {
    let Some(mut two) = sys.two_level.take() else {
        return;
    };
    let h2 = h * h;
    {
        let (points, touched, delta) = (&sys.points, &sys.touched, &sys.delta);
        let aggregate = &two.aggregate;
        two.free
            .par_iter_mut()
            .zip(two.held_move.par_iter_mut())
            .enumerate()
            .for_each(|(i, (free, held_move))| {
                *held_move = Vector3::zeros();
                if points.pinned[i] {
                    *free = false;
                    return;
                }
                let margin = points.margin[i];
                let reach = margin * (T::one() + T::of(CONTACT_GAP));
                let to = points.y[i] + delta[i];
                let mut moved = delta[i];
                let mut near = false;
                for c in Points::colliders_of(&points.collides, i, colliders) {
                    let gap = c.signed_distance(&to);
                    near |= gap <= reach || c.signed_distance(&points.y[i]) <= reach;
                    if gap < margin {
                        moved += c.normal(&to) * (margin - gap);
                    }
                }
                let held =
                    near || touched[i] || coupled.get(i).is_some_and(|r| *r != Vector3::zeros());
                *free = aggregate[i] != NONE && !held;
                *held_move = moved.map(|c| c.to_f64());
            });
    }
    if let Err(e) = two.factor(&sys.rest, h.to_f64()) {
        sys.failure.get_or_insert(e);
        sys.two_level = Some(two);
        return;
    }
    {
        let (rest, residual, delta) = (&sys.rest, &sys.current.residual, &sys.delta);
        let (free, held_move) = (&two.free, &two.held_move);
        two.remainder
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, out)| {
                if !free[i] {
                    return;
                }
                let mut coupled = Vector3::<f64>::zeros();
                for b in rest.row(i) {
                    let j = rest.indices[b] as usize;
                    let d = if free[j] {
                        delta[j].map(|c| c.to_f64())
                    } else {
                        held_move[j]
                    };
                    coupled += d * rest.coupling[b].to_f64();
                }
                // In f64 whatever the body's precision (mixed precision: the restriction sums
                // some 30 nearly cancelling terms per aggregate).
                let d_i = rest.mass[i].to_f64() + h2.to_f64() * rest.stiffness[i].to_f64();
                let r = residual[i].map(|c| c.to_f64()) - delta[i].map(|c| c.to_f64()) * d_i;
                *out = r + coupled * h2.to_f64();
            });
    }
    let rhs = two.llt.rhs_mut();
    for a in 0..rhs.nrows() {
        for c in 0..3 {
            rhs[(a, c)] = 0.0;
        }
    }
    for (i, &a) in two.aggregate.iter().enumerate() {
        if two.free[i] {
            for c in 0..3 {
                rhs[(a, c)] += two.remainder[i][c];
            }
        }
    }
    two.llt.solve();
    {
        // The prolonged correction, then one Jacobi sweep on what it leaves,
        // `r - A (delta_J + P e)`, at the free particles (post-smoothing: the piecewise-constant
        // correction's jumps between aggregates are the sweep's to smooth).
        let (x, aggregate, free, remainder) =
            (two.llt.rhs(), &two.aggregate, &two.free, &two.remainder);
        let rest = &sys.rest;
        let at = |i: usize| {
            let a = aggregate[i];
            Vector3::new(x[(a, 0)], x[(a, 1)], x[(a, 2)])
        };
        let h2 = h2.to_f64();
        sys.delta.par_iter_mut().enumerate().for_each(|(i, d)| {
            if !free[i] {
                return;
            }
            let e = at(i);
            let d_i = rest.mass[i].to_f64() + h2 * rest.stiffness[i].to_f64();
            let mut coupled = Vector3::<f64>::zeros();
            for b in rest.row(i) {
                let j = rest.indices[b] as usize;
                if free[j] {
                    coupled += at(j) * rest.coupling[b].to_f64();
                }
            }
            let left = remainder[i] - e * d_i + coupled * h2;
            *d += (e + left / d_i).map(T::of);
        });
    }
    sys.two_level = Some(two);
}
