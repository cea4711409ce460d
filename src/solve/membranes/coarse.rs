//! The coarse level of the Newton CG's two-level preconditioner (issue 44, scope item 2).
//!
//! Block Jacobi (SISSM's `D_k^-1`) removes the error that varies from vertex to vertex, but
//! the error that is smooth across the mesh, the slow modes of a fine, stiff membrane, falls
//! only by a factor of order `1 - 1/cond` per CG step. The coarse level removes it directly:
//!
//! - the vertices are grouped into aggregates by greedy aggregation of the bond graph (a
//!   vertex whose neighbours are all unassigned seeds an aggregate of itself and its
//!   neighbours, the rest join a neighbouring aggregate), applied [`PASSES`] times (the second
//!   pass aggregates the aggregates): aggregates of some tens of vertices;
//! - the prolongation `P` moves every free vertex of an aggregate by the aggregate's
//!   translation (3 unknowns per aggregate): the smooth modes are, locally, translations;
//! - the coarse matrix is the Galerkin product `A_c = P^T K P` (kg) of the Newton matrix
//!   `K = M + h^2 sum_i G_i^T H_i G_i` ([`super::newton::hessian_product`]), summed from each
//!   vertex model's action on the translations of the aggregates its stencil touches (a
//!   stencil inside one aggregate, all of it free, is translated rigidly and adds only mass),
//!   and factored by a sparse Cholesky factorisation with a fill-reducing ordering (`faer`;
//!   the pattern, and so the symbolic factorisation, is fixed by the aggregates).
//!
//! The preconditioner is additive, `M^-1 = D^-1 + P A_c^-1 P^T`: symmetric positive
//! definite whenever `D` is (the coarse term is positive semi-definite), so CG stays a
//! descent method whatever the iterate. Everything on the coarse level is in f64 and
//! sequential (it is some hundreds of unknowns), so results do not depend on the thread count.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::error::{invalid, Result};
use crate::membrane::RestData;
use crate::mesh::Neighborhood;
use crate::real::Real;
use crate::solve::NewtonTimings;
use crate::sparse_llt::SparseLlt;
use crate::timing::millis;
use std::time::Instant;

use super::hessian_model::VertexModel;

/// Rounds of aggregation: one gives aggregates of about a vertex and its ring (7 vertices
/// on a triangle grid), two aggregates of those.
const PASSES: usize = 2;

/// Greedy aggregation of a symmetric graph in CSR form (`offsets`, `indices`): the aggregate
/// of every node, and the number of aggregates. Deterministic (nodes in index order).
fn aggregate_graph(offsets: &[usize], indices: &[usize]) -> (Vec<usize>, usize) {
    const NONE: usize = usize::MAX;
    let n = offsets.len() - 1;
    let of = |i: usize| &indices[offsets[i]..offsets[i + 1]];
    let mut group = vec![NONE; n];
    let mut count = 0;
    for i in 0..n {
        if group[i] == NONE && of(i).iter().all(|&j| group[j] == NONE) {
            group[i] = count;
            for &j in of(i) {
                group[j] = count;
            }
            count += 1;
        }
    }
    for i in 0..n {
        if group[i] == NONE {
            group[i] = match of(i).iter().map(|&j| group[j]).find(|&g| g != NONE) {
                Some(g) => g,
                None => {
                    count += 1;
                    count - 1
                }
            };
        }
    }
    (group, count)
}

/// The aggregates' graph: `a` and `b` are adjacent when a bond joins them.
fn aggregate_adjacency(
    offsets: &[usize],
    indices: &[usize],
    group: &[usize],
    count: usize,
) -> (Vec<usize>, Vec<usize>) {
    let mut sets = vec![Vec::new(); count];
    for i in 0..offsets.len() - 1 {
        for &j in &indices[offsets[i]..offsets[i + 1]] {
            if group[i] != group[j] {
                sets[group[i]].push(group[j]);
            }
        }
    }
    let mut out = (vec![0], Vec::new());
    for mut set in sets {
        set.sort_unstable();
        set.dedup();
        out.1.extend(set);
        out.0.push(out.1.len());
    }
    out
}

/// The coarse level: aggregates, the coarse matrix's pattern and symbolic factorisation, and
/// the scratch of its assembly and solves.
pub(crate) struct CoarseLevel {
    /// The aggregate of every vertex, and the number of aggregates.
    aggregate: Vec<usize>,
    count: usize,
    /// `A_c` (3 rows and columns per aggregate, kg) and its factor; its pattern holds every
    /// pair of aggregates that share a stencil. Its right-hand side: `P^T r`, then
    /// `A_c^-1 P^T r`.
    llt: SparseLlt,
}

/// One stencil's contribution to `A_c`: the block of rows of aggregate `.0` and columns of
/// aggregate `.1`.
type Contribution = Vec<(usize, usize, Matrix3<f64>)>;

impl CoarseLevel {
    /// The aggregates of the bond graph `nb` and the coarse matrix's symbolic factorisation.
    pub fn new(nb: &Neighborhood) -> Result<Self> {
        let mut offsets: Vec<usize> = nb.offsets.iter().map(|&o| o as usize).collect();
        let mut indices: Vec<usize> = nb.indices.iter().map(|&j| j as usize).collect();
        let n = offsets.len() - 1;
        let mut aggregate: Vec<usize> = (0..n).collect();
        let mut count = n;
        for _ in 0..PASSES {
            let (group, groups) = aggregate_graph(&offsets, &indices);
            (offsets, indices) = aggregate_adjacency(&offsets, &indices, &group, groups);
            for a in &mut aggregate {
                *a = group[*a];
            }
            count = groups;
        }
        let mut pattern = Vec::new();
        for a in 0..count {
            for c in 0..3 {
                for r in c..3 {
                    pattern.push((3 * a + r, 3 * a + c));
                }
            }
        }
        for i in 0..n {
            let mut touched: Vec<usize> = std::iter::once(i)
                .chain(nb.of(i).iter().map(|&j| j as usize))
                .map(|v| aggregate[v])
                .collect();
            touched.sort_unstable();
            touched.dedup();
            for &a in &touched {
                for &b in touched.iter().filter(|&&b| b > a) {
                    for c in 0..3 {
                        for r in 0..3 {
                            pattern.push((3 * b + r, 3 * a + c));
                        }
                    }
                }
            }
        }
        let llt = SparseLlt::new(3 * count, pattern, 1)
            .map_err(|e| invalid!("the coarse level's set-up failed: {e}"))?;
        Ok(Self {
            aggregate,
            count,
            llt,
        })
    }

    /// The number of aggregates (3 coarse unknowns each).
    #[cfg(test)]
    pub fn aggregates(&self) -> usize {
        self.count
    }

    /// The aggregate of vertex `k`.
    #[cfg(test)]
    pub fn aggregate_of(&self, k: usize) -> usize {
        self.aggregate[k]
    }

    /// Vertex `i`'s stencil's contribution to `A_c / h^2` (its model's action on the
    /// translations of the aggregates the stencil touches, restricted to the free vertices):
    /// empty for a stencil inside one aggregate with every vertex free.
    fn contribution<T: Real>(
        &self,
        i: usize,
        nb: &Neighborhood,
        rest: &RestData<T>,
        model: &VertexModel<T>,
        free: &[bool],
    ) -> Contribution {
        let neighbors = nb.of(i);
        let stencil = || std::iter::once(i).chain(neighbors.iter().map(|&j| j as usize));
        let own = self.aggregate[i];
        if stencil().all(|v| free[v] && self.aggregate[v] == own) {
            return Vec::new();
        }
        let mut touched: Vec<usize> = stencil().map(|v| self.aggregate[v]).collect();
        touched.sort_unstable();
        touched.dedup();
        let moved = |v: usize, a: usize| free[v] && self.aggregate[v] == a;
        let mut out = Vec::with_capacity(touched.len() * touched.len());
        let mut bonds = vec![Vector3::zeros(); neighbors.len()];
        for &a in &touched {
            let mut columns = vec![Matrix3::<f64>::zeros(); touched.len()];
            for c in 0..3 {
                let unit = Vector3::ith(c, T::one());
                let at = |v: usize| if moved(v, a) { unit } else { Vector3::zeros() };
                for (x, &j) in bonds.iter_mut().zip(neighbors) {
                    *x = at(j as usize) - at(i);
                }
                model.apply(&rest.stencil(nb, i), &mut bonds);
                // The gradient of the quadratic form: `y_j` on neighbour j, `-sum_j y_j` on i;
                // summed over each aggregate's free vertices (the rows of `P^T`).
                let mut add = |v: usize, y: Vector3<f64>| {
                    if free[v] {
                        let b = touched.binary_search(&self.aggregate[v]).expect("touched");
                        let mut column = columns[b].column_mut(c);
                        column += y;
                    }
                };
                let mut own_force = Vector3::zeros();
                for (y, &j) in bonds.iter().zip(neighbors) {
                    let y = y.map(|v| v.to_f64());
                    own_force -= y;
                    add(j as usize, y);
                }
                add(i, own_force);
            }
            for (b, block) in touched.iter().zip(columns) {
                out.push((*b, a, block));
            }
        }
        out
    }

    /// Assembles `A_c = P^T K P` for the vertex models `models` at the current iterate, the
    /// `free` vertices (the others are not moved by `P`), the masses of `rest` (kg) and
    /// `h2 = h^2` (s^2), and factors it. An aggregate without a free vertex gets the identity
    /// block (its `P^T r` is zero, so its correction is too).
    pub fn factor<T: Real>(
        &mut self,
        nb: &Neighborhood,
        rest: &RestData<T>,
        models: &[VertexModel<T>],
        free: &[bool],
        h2: T,
        timings: &mut NewtonTimings,
    ) -> Result<()> {
        let t = Instant::now();
        let contributions: Vec<Contribution> = (0..free.len())
            .into_par_iter()
            .map(|i| self.contribution(i, nb, rest, &models[i], free))
            .collect();
        let h2 = h2.to_f64();
        self.llt.values_mut().fill(0.0);
        let mut has_free = vec![false; self.count];
        for (k, free) in free.iter().enumerate() {
            if *free {
                let a = self.aggregate[k];
                has_free[a] = true;
                for c in 0..3 {
                    self.llt
                        .add(3 * a + c, 3 * a + c, rest.vertices[k].mass.to_f64());
                }
            }
        }
        for (a, has) in has_free.iter().enumerate() {
            if !has {
                for c in 0..3 {
                    let slot = self.llt.slot(3 * a + c, 3 * a + c);
                    self.llt.values_mut()[slot] = 1.0;
                }
            }
        }
        for (b, a, block) in contributions.iter().flatten() {
            for c in 0..3 {
                for r in 0..3 {
                    let (row, col) = (3 * b + r, 3 * a + c);
                    if row >= col {
                        self.llt.add(row, col, h2 * block[(r, c)]);
                    }
                }
            }
        }
        timings.coarse_assembly += millis(t);
        let t = Instant::now();
        let out = self
            .llt
            .factor()
            .map_err(|e| invalid!("the coarse matrix is not positive definite: {e}"));
        timings.coarse_factor += millis(t);
        timings.factorizations += 1;
        out
    }

    /// The coarse factor's values, to put back with [`Self::restore_factor`].
    pub fn factor_values(&self) -> &[f64] {
        self.llt.factor_values()
    }

    /// Puts back the factor `values` read with [`Self::factor_values`] of this level.
    pub fn restore_factor(&mut self, values: &[f64]) {
        self.llt.restore_factor(values);
    }

    /// `z_k += (P A_c^-1 P^T r)_k` on the free vertices (m, for `r` in kg m).
    pub fn correct<T: Real>(&mut self, free: &[bool], r: &[Vector3<T>], z: &mut [Vector3<T>]) {
        let rhs = self.llt.rhs_mut();
        rhs.fill(0.0);
        for (k, r) in r.iter().enumerate() {
            if free[k] {
                let a = self.aggregate[k];
                for c in 0..3 {
                    rhs[(3 * a + c, 0)] += r[c].to_f64();
                }
            }
        }
        self.llt.solve();
        let (rhs, aggregate) = (self.llt.rhs(), &self.aggregate);
        z.par_iter_mut().enumerate().for_each(|(k, z)| {
            if free[k] {
                let a = aggregate[k];
                *z += Vector3::new(rhs[(3 * a, 0)], rhs[(3 * a + 1, 0)], rhs[(3 * a + 2, 0)])
                    .map(T::of);
            }
        });
    }
}
