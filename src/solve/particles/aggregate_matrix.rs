//! The two-level correction's coarse matrix for one coordinate ([`super::two_level`]):
//! `P^T A P` on the aggregates for a free set, `(P^T A P)_ab = sum_(i in a, j in b) A_ij`
//! over the free particles `i` and `j` (`A = M + h^2 L` of eq. 12, the same for the three
//! coordinates), factored by a sparse Cholesky (AMD ordering, [`SparseLlt`]) when the time
//! step or the free set changes. The correction takes one for the three coordinates, and a
//! second for the coordinate along the collider's normal when particles slide (the sliding
//! particles held there; module doc of [`super::two_level`], "Sliding particles").

use nalgebra::Vector3;

use crate::error::{invalid, Result};
use crate::particles::ParticleRest;
use crate::real::Real;
use crate::sparse_llt::SparseLlt;

/// No aggregate (a particle of a body that takes no part), or no slot (a bond whose entry is
/// in the upper triangle or outside the coarse matrix).
pub(super) const NONE: usize = usize::MAX;

/// The coarse matrix, its pattern and its factor for one time step and free set.
pub(super) struct AggregateMatrix {
    /// The time step (s) and per particle whether it was free when last factored (`h = NaN`:
    /// no factor yet).
    h: f64,
    factored_free: Vec<bool>,
    /// `P^T A P` (right-hand sides `aggregates x columns`); per aggregate the slot of its
    /// diagonal and per bond the slot of its entry (or [`NONE`]).
    llt: SparseLlt,
    diagonal_slot: Vec<usize>,
    bond_slot: Vec<usize>,
}

impl AggregateMatrix {
    /// The matrix of the `count` aggregates `aggregate` (per particle, or [`NONE`]) on the
    /// lower triangle `lower` (pairs `a >= b`), with `columns` right-hand sides, and its
    /// symbolic factor (no numeric factor yet).
    pub fn new<T: Real>(
        rest: &ParticleRest<T>,
        aggregate: &[usize],
        lower: &[(usize, usize)],
        count: usize,
        columns: usize,
    ) -> Result<Self> {
        let llt = SparseLlt::new(count, lower.iter().copied(), columns)
            .map_err(|e| invalid!("the two-level coarse matrix's pattern failed: {e}"))?;
        let diagonal_slot = (0..count).map(|a| llt.slot(a, a)).collect();
        let mut bond_slot = vec![NONE; rest.indices.len()];
        for (i, &a) in aggregate.iter().enumerate() {
            for b in rest.row(i) {
                let c = aggregate[rest.indices[b] as usize];
                if a != NONE && c != NONE && c <= a {
                    bond_slot[b] = llt.slot(a, c);
                }
            }
        }
        Ok(Self {
            h: f64::NAN,
            factored_free: vec![false; aggregate.len()],
            llt,
            diagonal_slot,
            bond_slot,
        })
    }

    /// Fills `P^T A P` for the time step `h` (s) and the free set `free`, and factors it,
    /// unless the factor at hand is that one; returns whether it factored. An aggregate
    /// without a free particle keeps a unit diagonal (its unknown is decoupled and its
    /// right-hand side zero).
    pub fn factor<T: Real>(
        &mut self,
        rest: &ParticleRest<T>,
        aggregate: &[usize],
        free: &[bool],
        h: f64,
    ) -> Result<bool> {
        if self.h == h && self.factored_free == free {
            return Ok(false);
        }
        let h2 = h * h;
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
        self.llt
            .factor()
            .map_err(|e| invalid!("the two-level coarse factorisation failed: {e}"))?;
        self.h = h;
        self.factored_free.copy_from_slice(free);
        Ok(true)
    }

    /// Replaces the coordinates `first..first + columns` of the restricted residuals
    /// `coarse` (kg m, per aggregate) by the coarse solution's (m), with the last factor.
    pub fn solve(&mut self, coarse: &mut [Vector3<f64>], first: usize) {
        let columns = self.llt.rhs().ncols();
        let rhs = self.llt.rhs_mut();
        for k in 0..columns {
            for (out, sum) in rhs.col_as_slice_mut(k).iter_mut().zip(coarse.iter()) {
                *out = sum[first + k];
            }
        }
        self.llt.solve();
        let x = self.llt.rhs();
        for k in 0..columns {
            for (e, x) in coarse.iter_mut().zip(x.col_as_slice(k)) {
                e[first + k] = *x;
            }
        }
    }
}
