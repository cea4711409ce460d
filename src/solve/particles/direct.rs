//! The direct global solver of the particle family (He et al. 2017, section 4.2 and Fig. 7):
//! the constant matrix `M + h^2 L` of eq. 12 factored once by a sparse Cholesky
//! factorisation with a fill-reducing (AMD) ordering (`faer`), and each global step a pair of
//! triangular solves for the three coordinates.
//!
//! Pinned particles are held: their rows and columns keep only the diagonal, so their move
//! is zero and the free particles' system is the one with the pins as boundary values. The
//! factor is rebuilt only when the time step or the set of pinned particles changes (the
//! bonds of an elastic body never do). It is computed in f64 for either precision (one code
//! path: the solver's values are converted on the way in and out), sequentially, so its
//! results do not depend on the number of threads.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Conj, Mat, Par, Side};
use nalgebra::Vector3;

use crate::error::{invalid, Result};
use crate::particles::ParticleRest;
use crate::real::Real;

/// A factored `M + h^2 L` and the workspace of its solves.
pub(crate) struct DirectSolver {
    /// The time step (s) and pins it was factored for.
    h: f64,
    pinned: Vec<bool>,
    symbolic: SymbolicCholesky<usize>,
    values: Vec<f64>,
    /// Right-hand sides and solutions, `n x 3` (reused).
    rhs: Mat<f64>,
    scratch: MemBuffer,
}

impl DirectSolver {
    /// Whether the factor is the one for the time step `h` (s) and these pins.
    pub fn matches(&self, h: f64, pinned: &[bool]) -> bool {
        self.h == h && self.pinned == pinned
    }

    /// Factors `M + h^2 L` for the rest data's bonds and masses, `h` in s.
    pub fn factor<T: Real>(rest: &ParticleRest<T>, h: f64, pinned: &[bool]) -> Result<Self> {
        let n = rest.len();
        let h2 = h * h;
        let mut triplets = Vec::with_capacity(n + rest.indices.len() / 2);
        for i in 0..n {
            let mass = rest.mass[i].to_f64();
            if pinned[i] {
                triplets.push(Triplet::new(i, i, mass));
                continue;
            }
            triplets.push(Triplet::new(i, i, mass + h2 * rest.stiffness[i].to_f64()));
            for b in rest.row(i) {
                let j = rest.indices[b] as usize;
                // The lower triangle: each pair once, from its larger index.
                if j < i && !pinned[j] {
                    triplets.push(Triplet::new(i, j, -h2 * rest.coupling[b].to_f64()));
                }
            }
        }
        let failed =
            |e: &dyn std::fmt::Debug| invalid!("the direct solver's factorisation failed: {e:?}");
        let matrix = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &triplets)
            .map_err(|e| failed(&e))?;
        let symbolic = factorize_symbolic_cholesky(
            matrix.symbolic(),
            Side::Lower,
            Default::default(),
            Default::default(),
        )
        .map_err(|e| failed(&e))?;
        let mut values = vec![0.0; symbolic.len_val()];
        let factor_scratch =
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default());
        let solve_scratch = symbolic.solve_in_place_scratch::<f64>(3, Par::Seq);
        let mut scratch = MemBuffer::new(factor_scratch.or(solve_scratch));
        symbolic
            .factorize_numeric_llt::<f64>(
                &mut values,
                matrix.as_ref(),
                Side::Lower,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut scratch),
                Default::default(),
            )
            .map_err(|e| failed(&e))?;
        Ok(Self {
            h,
            pinned: pinned.to_vec(),
            symbolic,
            values,
            rhs: Mat::zeros(n, 3),
            scratch,
        })
    }

    /// `delta = (M + h^2 L)^-1 r` (m) for the residual `r` (N s^2 = kg m), zero at pins.
    pub fn solve<T: Real>(&mut self, residual: &[Vector3<T>], delta: &mut [Vector3<T>]) {
        for (i, r) in residual.iter().enumerate() {
            let r = if self.pinned[i] { Vector3::zeros() } else { *r };
            for c in 0..3 {
                self.rhs[(i, c)] = r[c].to_f64();
            }
        }
        LltRef::<usize, f64>::new(&self.symbolic, &self.values).solve_in_place_with_conj(
            Conj::No,
            self.rhs.as_mut(),
            Par::Seq,
            MemStack::new(&mut self.scratch),
        );
        for (i, d) in delta.iter_mut().enumerate() {
            *d = Vector3::new(self.rhs[(i, 0)], self.rhs[(i, 1)], self.rhs[(i, 2)]).map(T::of);
        }
    }
}
