//! A sparse Cholesky factorisation `A = L L^T` of a symmetric positive definite matrix whose
//! pattern is fixed while its values change: the global matrix of the particles' direct
//! solver (He et al. 2017, Fig. 7) and the coarse matrix of Newton's two-level preconditioner.
//!
//! `faer` computes it with a fill-reducing (AMD) ordering. The pattern and its symbolic
//! factorisation are computed once; a refactorisation after new values, and every solve, runs
//! in the buffers at hand (no allocation), in f64 and sequentially, so results do not depend on
//! the number of threads.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Conj, Mat, Par, Side};

/// The lower triangle of `A`, its symbolic and numeric factors, and the right-hand sides of
/// its solves (`n x columns`, solved in place).
pub(crate) struct SparseLlt {
    matrix: SparseColMat<usize, f64>,
    symbolic: SymbolicCholesky<usize>,
    factor: Vec<f64>,
    rhs: Mat<f64>,
    scratch: MemBuffer,
}

impl SparseLlt {
    /// The `n x n` matrix with the lower-triangle entries `lower` (`(row, col)`, `row >= col`,
    /// repeats allowed; the diagonal must be among them), all values zero, and `columns`
    /// right-hand sides per solve. Fails (with faer's message) on an entry out of range.
    pub fn new(
        n: usize,
        lower: impl IntoIterator<Item = (usize, usize)>,
        columns: usize,
    ) -> Result<Self, String> {
        let triplets: Vec<Triplet<usize, usize, f64>> = lower
            .into_iter()
            .map(|(row, col)| Triplet::new(row, col, 0.0))
            .collect();
        let matrix = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &triplets)
            .map_err(|e| format!("{e:?}"))?;
        let symbolic = factorize_symbolic_cholesky(
            matrix.symbolic(),
            Side::Lower,
            Default::default(),
            Default::default(),
        )
        .map_err(|e| format!("{e:?}"))?;
        let factor_scratch =
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default());
        let solve_scratch = symbolic.solve_in_place_scratch::<f64>(columns, Par::Seq);
        Ok(Self {
            factor: vec![0.0; symbolic.len_val()],
            symbolic,
            matrix,
            rhs: Mat::zeros(n, columns),
            scratch: MemBuffer::new(factor_scratch.or(solve_scratch)),
        })
    }

    /// The index in [`Self::values_mut`] of the entry `(row, col)` (`row >= col`); panics if
    /// the pattern does not hold it (a caller's bug: the pattern is the caller's own).
    pub fn slot(&self, row: usize, col: usize) -> usize {
        let symbolic = self.matrix.symbolic();
        symbolic.col_ptr()[col]
            + symbolic
                .row_idx_of_col_raw(col)
                .binary_search(&row)
                .expect("an entry of the pattern")
    }

    /// The lower triangle's values, in the order of [`Self::slot`].
    pub fn values_mut(&mut self) -> &mut [f64] {
        self.matrix.val_mut()
    }

    /// Adds `value` to the entry `(row, col)` (`row >= col`).
    pub fn add(&mut self, row: usize, col: usize, value: f64) {
        let slot = self.slot(row, col);
        self.matrix.val_mut()[slot] += value;
    }

    /// Factors the current values. Fails (with faer's message) where they are not positive
    /// definite; the previous factor is then unusable until a factorisation succeeds.
    pub fn factor(&mut self) -> Result<(), String> {
        self.symbolic
            .factorize_numeric_llt::<f64>(
                &mut self.factor,
                self.matrix.as_ref(),
                Side::Lower,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut self.scratch),
                Default::default(),
            )
            .map(|_| ())
            .map_err(|e| format!("{e:?}"))
    }

    /// The numeric factor's values, to put back with [`Self::restore_factor`].
    pub fn factor_values(&self) -> &[f64] {
        &self.factor
    }

    /// Puts back the factor `values` read with [`Self::factor_values`] (of this pattern).
    pub fn restore_factor(&mut self, values: &[f64]) {
        self.factor.copy_from_slice(values);
    }

    /// The right-hand sides, `n x columns`: filled by the caller, then overwritten by
    /// [`Self::solve`] with the solutions.
    pub fn rhs_mut(&mut self) -> &mut Mat<f64> {
        &mut self.rhs
    }

    /// The solutions of the last [`Self::solve`].
    pub fn rhs(&self) -> &Mat<f64> {
        &self.rhs
    }

    /// Replaces the right-hand sides by `A^-1` times them, with the last factor.
    pub fn solve(&mut self) {
        LltRef::<usize, f64>::new(&self.symbolic, &self.factor).solve_in_place_with_conj(
            Conj::No,
            self.rhs.as_mut(),
            Par::Seq,
            MemStack::new(&mut self.scratch),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::SparseLlt;
    use nalgebra::{DMatrix, DVector};

    /// A 1D Laplacian plus a mass (tridiagonal, SPD), factored, solved, then refactored with
    /// new values: both solutions match a dense solve.
    #[test]
    fn solves_and_refactors_like_a_dense_cholesky() {
        let n = 7;
        let lower = (0..n).flat_map(|i| std::iter::once((i, i)).chain((i > 0).then(|| (i, i - 1))));
        let mut llt = SparseLlt::new(n, lower, 2).unwrap();
        for mass in [1.0, 5.0] {
            let mut dense = DMatrix::<f64>::zeros(n, n);
            for i in 0..n {
                let diagonal = mass + 2.0;
                let slot = llt.slot(i, i);
                llt.values_mut()[slot] = diagonal;
                dense[(i, i)] = diagonal;
                if i > 0 {
                    let slot = llt.slot(i, i - 1);
                    llt.values_mut()[slot] = 0.0;
                    llt.add(i, i - 1, -1.0);
                    dense[(i, i - 1)] = -1.0;
                    dense[(i - 1, i)] = -1.0;
                }
            }
            llt.factor().unwrap();
            let b = DVector::from_fn(n, |i, _| (i as f64 * 0.7).sin() + 0.1);
            for c in 0..2 {
                for i in 0..n {
                    llt.rhs_mut()[(i, c)] = b[i] * (c + 1) as f64;
                }
            }
            llt.solve();
            let x = dense.cholesky().unwrap().solve(&b);
            for c in 0..2 {
                for i in 0..n {
                    let expected = x[i] * (c + 1) as f64;
                    assert!((llt.rhs()[(i, c)] - expected).abs() < 1e-12 * expected.abs().max(1.0));
                }
            }
        }
    }

    /// A matrix that is not positive definite is refused, not factored.
    #[test]
    fn refuses_an_indefinite_matrix() {
        let mut llt = SparseLlt::new(2, [(0, 0), (1, 1), (1, 0)], 1).unwrap();
        for (row, col, value) in [(0, 0, 1.0), (1, 1, 1.0), (1, 0, 2.0)] {
            llt.add(row, col, value);
        }
        assert!(llt.factor().is_err());
    }
}
