//! The two-level correction's coarse matrix when some particle slides along a flat
//! frictionless collider ([`super::two_level`], "Sliding particles"): `P^T A P` with three
//! unknowns per aggregate (`3 a + c`, `c` the coordinate), since a sliding particle's row of
//! `P`, `T_i = I - n_i n_i^T` (`n_i` the collider's unit normal), couples the coordinates.
//! The block of aggregates `a` and `b` is `sum_(i in a, j in b) A_ij T_i T_j` (`T = I` for a
//! free particle; `A = M + h^2 L` of eq. 12), factored by a sparse Cholesky (AMD ordering,
//! [`SparseLlt`]) when the time step, the free set or a sliding particle's normal changes.
//!
//! An aggregate of sliding particles alone would leave its unknowns along their normals
//! without a mass (singular where the normals agree): there a sliding particle's own term is
//! `D_i I` rather than `D_i T_i` (`P^T A P` plus a positive semi-definite block that vanishes
//! on the tangential moves; the restricted residual has no normal part there, so the unknown
//! along a common normal stays zero). An aggregate without a row keeps a unit diagonal.
//!
//! Built at the first iteration a particle slides (once per working set): a body that slides
//! on nothing keeps the scalar matrix, one unknown per aggregate for the three coordinates,
//! and its iterates are those of a correction without sliding rows.

use nalgebra::{Matrix3, Vector3};

use crate::error::{invalid, Result};
use crate::particles::ParticleRest;
use crate::real::Real;
use crate::sparse_llt::SparseLlt;

use super::two_level::NONE;

/// The blocked coarse matrix, its pattern and its factor for one time step, free set and set
/// of normals.
pub(super) struct SlidingCoarse {
    /// The time step (s), the free set and the sliding normals of the last factor (`h = NaN`:
    /// no factor yet).
    h: f64,
    factored_free: Vec<bool>,
    factored_normal: Vec<Vector3<f64>>,
    /// `P^T A P` (one right-hand side of `3 x aggregates`); per block of two neighbouring
    /// aggregates `a >= b` the slots of its nine entries (row-major, [`NONE`] above the
    /// diagonal), per aggregate the block of its diagonal and per bond the block of its entry
    /// (or [`NONE`]).
    pub(super) llt: SparseLlt,
    pub(super) blocks: Vec<[usize; 9]>,
    pub(super) diagonal_block: Vec<usize>,
    pub(super) bond_block: Vec<usize>,
    /// Per aggregate whether it holds a free particle that does not slide (reused).
    has_free: Vec<bool>,
}

impl SlidingCoarse {
    /// The pattern of the `count` aggregates' blocks from the scalar matrix's lower triangle
    /// `lower` (pairs of aggregates `a >= b`, sorted), and its symbolic factor.
    pub fn new<T: Real>(
        rest: &ParticleRest<T>,
        aggregate: &[usize],
        lower: &[(usize, usize)],
    ) -> Result<Self> {
        let count = lower.iter().filter(|(a, b)| a == b).count();
        let entries = lower.iter().flat_map(|&(a, b)| {
            (0..9)
                .map(move |k| (3 * a + k / 3, 3 * b + k % 3))
                .filter(|(row, col)| row >= col)
        });
        let llt = SparseLlt::new(3 * count, entries, 1)
            .map_err(|e| invalid!("the two-level sliding matrix's pattern failed: {e}"))?;
        let blocks: Vec<[usize; 9]> = (lower.iter())
            .map(|&(a, b)| {
                std::array::from_fn(|k| {
                    let (row, col) = (3 * a + k / 3, 3 * b + k % 3);
                    if row >= col {
                        llt.slot(row, col)
                    } else {
                        NONE
                    }
                })
            })
            .collect();
        let block = |a: usize, b: usize| lower.binary_search(&(a, b)).unwrap_or(NONE);
        let diagonal_block = (0..count).map(|a| block(a, a)).collect();
        let mut bond_block = vec![NONE; rest.indices.len()];
        for (i, &a) in aggregate.iter().enumerate() {
            for b in rest.row(i) {
                let c = aggregate[rest.indices[b] as usize];
                if a != NONE && c != NONE && c <= a {
                    bond_block[b] = block(a, c);
                }
            }
        }
        let n = aggregate.len();
        Ok(Self {
            h: f64::NAN,
            factored_free: vec![false; n],
            factored_normal: vec![Vector3::zeros(); n],
            llt,
            blocks,
            diagonal_block,
            bond_block,
            has_free: vec![false; count],
        })
    }

    /// Fills the blocked `P^T A P` for the time step `h` (s), the free set `free` and the
    /// sliding particles' unit normals `normal` (zero: not sliding), and factors it, unless
    /// the factor at hand is that one. Returns whether it factored.
    pub fn factor<T: Real>(
        &mut self,
        rest: &ParticleRest<T>,
        aggregate: &[usize],
        free: &[bool],
        normal: &[Vector3<f64>],
        h: f64,
    ) -> Result<bool> {
        if self.h == h && self.factored_free == free && self.factored_normal == normal {
            return Ok(false);
        }
        let h2 = h * h;
        self.has_free.fill(false);
        for i in 0..aggregate.len() {
            if free[i] && normal[i] == Vector3::zeros() {
                self.has_free[aggregate[i]] = true;
            }
        }
        let values = self.llt.values_mut();
        values.fill(0.0);
        let mut add = |block: &[usize; 9], m: &Matrix3<f64>| {
            for (k, &slot) in block.iter().enumerate() {
                if slot != NONE {
                    values[slot] += m[(k / 3, k % 3)];
                }
            }
        };
        for i in 0..aggregate.len() {
            let a = aggregate[i];
            if a == NONE || !free[i] {
                continue;
            }
            let t_i = tangent(&normal[i]);
            let d_i = rest.mass[i].to_f64() + h2 * rest.stiffness[i].to_f64();
            let own = if self.has_free[a] {
                t_i
            } else {
                Matrix3::identity()
            };
            add(&self.blocks[self.diagonal_block[a]], &(own * d_i));
            for b in rest.row(i) {
                let j = rest.indices[b] as usize;
                let block = self.bond_block[b];
                if block != NONE && free[j] {
                    let m = t_i * tangent(&normal[j]) * (-h2 * rest.coupling[b].to_f64());
                    add(&self.blocks[block], &m);
                }
            }
        }
        for &block in &self.diagonal_block {
            for c in 0..3 {
                let slot = self.blocks[block][4 * c];
                if values[slot] == 0.0 {
                    values[slot] = 1.0;
                }
            }
        }
        self.h = f64::NAN;
        self.llt
            .factor()
            .map_err(|e| invalid!("the two-level sliding factorisation failed: {e}"))?;
        self.h = h;
        self.factored_free.copy_from_slice(free);
        self.factored_normal.copy_from_slice(normal);
        Ok(true)
    }

    /// Replaces the restricted residuals `coarse` (kg m, per aggregate) by the coarse
    /// solution `e` (m), with the last factor.
    pub fn solve(&mut self, coarse: &mut [Vector3<f64>]) {
        let rhs = self.llt.rhs_mut().col_as_slice_mut(0);
        for (out, sum) in rhs.chunks_exact_mut(3).zip(coarse.iter()) {
            out.copy_from_slice(sum.as_slice());
        }
        self.llt.solve();
        let x = self.llt.rhs().col_as_slice(0);
        for (e, x) in coarse.iter_mut().zip(x.chunks_exact(3)) {
            *e = Vector3::from_column_slice(x);
        }
    }
}

/// `I - n n^T`: the prolongator row of a particle sliding on a collider of unit normal `n`
/// (`I` for `n = 0`, a free particle).
#[inline]
pub(super) fn tangent(n: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::identity() - n * n.transpose()
}
