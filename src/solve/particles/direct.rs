//! The direct global solver of the particle family (He et al. 2017, section 4.2 and Fig. 7):
//! the matrix `M + h^2 L` of eq. 12 factored by a sparse Cholesky factorisation with a
//! fill-reducing (AMD) ordering (`faer`), and each global step a pair of triangular solves for
//! the three coordinates.
//!
//! **Held particles (pins and collider contacts).** A held particle's row and column keep only
//! their diagonal `D_i = m_i + h^2 L_ii`: the free particles' system is solved with the held
//! ones where they are (the pins as boundary values), and a held particle takes the Jacobi move
//! `r_i / D_i` (zero at a pin, whose residual is zero), which the colliders then project with
//! friction in the same diagonal metric as for the Jacobi solvers. This is the block-Jacobi
//! splitting `A = B - N` with `B = blockdiag(A_FF, D_H)`: its fixed point is the solution of
//! `A delta = r` whatever the held set, and since `A` is a strictly diagonally dominant
//! M-matrix (positive masses, non-positive couplings `-h^2 c_ij`) the splitting is regular and
//! converges (Varga, Matrix Iterative Analysis, Theorem 3.13). A particle that rests on a
//! collider must be held: the coupled solve would otherwise spread the collider's support into
//! the free particles, and the projection that stops the supported particle cannot take it back
//! (the iteration diverged at the first contact). A held contact's friction so acts on that
//! particle alone, and a body sliding on a collider would feel a small part of it (its held
//! layer's share through the bonds each iteration); the move is therefore followed, as the
//! Jacobi sweep is, by the bodies' coarse correction (`super::coarse`), whose translations
//! carry the contacts' tangential reactions within their Coulomb cones to the whole body.
//!
//! The pattern of the whole matrix and its symbolic factorisation are computed once per
//! pattern; a change of the time step, of the held set or of the rest data's values (the
//! stiffness of a granular body from its density, eq. 25-27, and the bonds a flowing body's
//! return re-anchors, [`crate::particles::PlasticLaw::reanchor`], both at the end of a step
//! whose neighbourhoods stayed: [`Self::values_changed`]) only refills the values (held
//! couplings as explicit zeros) and refactors them numerically in the buffers at hand, so a
//! refactorisation inside the iterations allocates nothing and every solve is exact for the
//! matrix of the current rest data. A change of a plastic body's neighbourhoods changes the
//! pattern: its owner builds the solver anew ([`super::system`]). The factor is computed in
//! f64 for either precision (one code path: the solver's values are converted on the way in
//! and out), sequentially, so its results do not depend on the number of threads.

use nalgebra::Vector3;

use crate::error::{invalid, Error, Result};
use crate::particles::ParticleRest;
use crate::real::Real;
use crate::sparse_llt::SparseLlt;

/// No slot: the bond's entry is in the upper triangle (its reverse holds it).
const UPPER: usize = usize::MAX;

/// The pattern of `M + h^2 L`, its symbolic factor, the numeric factor for one time step and
/// held set, and the workspace of its solves.
pub(crate) struct DirectSolver {
    /// The time step (s) the numeric factor is for, with `held`; `None` when there is no
    /// usable factor (none yet, a failed factorisation, or values changed since).
    factored: Option<f64>,
    held: Vec<bool>,
    /// `M + h^2 L` and its factor (right-hand sides `n x 3`); per particle the slot of its
    /// diagonal and per bond the slot of its entry in the values (or [`UPPER`]).
    llt: SparseLlt,
    diagonal_slot: Vec<usize>,
    bond_slot: Vec<usize>,
    /// Symbolic analyses (this solver's one, until taken) and numeric factorisations since
    /// the last [`Self::take_counts`].
    analyses: usize,
    factorizations: usize,
}

fn failed(e: &dyn std::fmt::Debug) -> Error {
    invalid!("the direct solver's factorisation failed: {e:?}")
}

impl DirectSolver {
    /// The pattern of `M + h^2 L` for the rest data's bonds and its symbolic factorisation
    /// (no numeric factor yet).
    pub fn new<T: Real>(rest: &ParticleRest<T>) -> Result<Self> {
        let n = rest.len();
        // The lower triangle: each pair once, from its larger index.
        let lower = (0..n).flat_map(|i| {
            std::iter::once((i, i)).chain(
                rest.row(i)
                    .map(|b| rest.indices[b] as usize)
                    .filter(move |&j| j < i)
                    .map(move |j| (i, j)),
            )
        });
        let llt = SparseLlt::new(n, lower, 3).map_err(|e| failed(&e))?;
        let diagonal_slot = (0..n).map(|i| llt.slot(i, i)).collect();
        let mut bond_slot = vec![UPPER; rest.indices.len()];
        for i in 0..n {
            for b in rest.row(i) {
                let j = rest.indices[b] as usize;
                if j < i {
                    bond_slot[b] = llt.slot(i, j);
                }
            }
        }
        Ok(Self {
            factored: None,
            held: vec![false; n],
            llt,
            diagonal_slot,
            bond_slot,
            analyses: 1,
            factorizations: 0,
        })
    }

    /// Factors `M + h^2 L` (`h` in s) with the `held` particles' couplings taken out, unless
    /// the factor at hand is that one (same `h`, same held set, no [`Self::values_changed`]
    /// since); allocates nothing. Fails if the matrix is not positive definite (it always is
    /// for positive masses and couplings, see the module's doc).
    pub fn factor<T: Real>(&mut self, rest: &ParticleRest<T>, h: f64, held: &[bool]) -> Result<()> {
        if self.factored == Some(h) && self.held == held {
            return Ok(());
        }
        let h2 = h * h;
        let values = self.llt.values_mut();
        for i in 0..held.len() {
            values[self.diagonal_slot[i]] = rest.mass[i].to_f64() + h2 * rest.stiffness[i].to_f64();
            for b in rest.row(i) {
                let slot = self.bond_slot[b];
                if slot != UPPER {
                    let j = rest.indices[b] as usize;
                    values[slot] = if held[i] || held[j] {
                        0.0
                    } else {
                        -h2 * rest.coupling[b].to_f64()
                    };
                }
            }
        }
        // Marked stale first: a failed factorisation leaves no usable factor.
        self.factored = None;
        self.factorizations += 1;
        self.llt.factor().map_err(|e| failed(&e))?;
        self.factored = Some(h);
        self.held.copy_from_slice(held);
        Ok(())
    }

    /// Marks the numeric factor stale after the rest data's values changed on the same
    /// pattern (bond for bond): the next [`Self::factor`] refills and refactors them.
    pub fn values_changed(&mut self) {
        self.factored = None;
    }

    /// Symbolic analyses and numeric factorisations since the last call (measures for
    /// [`crate::solve::StepStats`]).
    pub fn take_counts(&mut self) -> (usize, usize) {
        (
            std::mem::take(&mut self.analyses),
            std::mem::take(&mut self.factorizations),
        )
    }

    /// `delta = B^-1 r` (m) for the residual `r` (N s^2 = kg m; zero at pins), with `B` the
    /// last factor's matrix (see the module's doc).
    pub fn solve<T: Real>(&mut self, residual: &[Vector3<T>], delta: &mut [Vector3<T>]) {
        let rhs = self.llt.rhs_mut();
        for (i, r) in residual.iter().enumerate() {
            for c in 0..3 {
                rhs[(i, c)] = r[c].to_f64();
            }
        }
        self.llt.solve();
        let x = self.llt.rhs();
        for (i, d) in delta.iter_mut().enumerate() {
            *d = Vector3::new(x[(i, 0)], x[(i, 1)], x[(i, 2)]).map(T::of);
        }
    }
}

#[cfg(test)]
#[path = "direct_tests.rs"]
mod tests;
