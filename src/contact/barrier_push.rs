//! The barrier part of the local step's descent direction, summed per vertex (eq. 49 of Lu et
//! al. 2023) and kept from one descent iteration to the next: where few vertices still move
//! (late in a local step, most of a sheet resting on another has settled while a fold goes on
//! sliding), only the pairs whose closest points were evaluated afresh have new terms, and
//! only the vertices of those pairs new sums. Every sum is taken over the vertex's pairs in
//! increasing order, whether afresh or kept, so it is the same to the bit as a sum over all
//! pairs in pair order.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::barrier::Barrier;
use super::distance::Closest;
use super::primitive_pairs::Pair;
use super::vertex_index::index_by_vertex;
use crate::symmetric::SymmetricMatrix3;

/// Per vertex of the local step, the sums of eq. 49 and 53 over its live pairs, and what they
/// are made of.
#[derive(Default)]
pub(super) struct BarrierPush {
    /// The live pairs `..head` by vertex (compressed rows, each increasing).
    head_rows: Rows,
    head: usize,
    /// The pairs from `head` on by vertex: the list grows by pairs appended at its end (many
    /// times in a local step where vertices outgrow their allowances), and indexing only
    /// them keeps an index of millions of pairs from being made again each time (a serial
    /// counting sort of four entries per pair).
    tail_rows: Rows,
    /// The version of the live list the rows are for (None: none yet).
    indexed: Option<u64>,
    /// Per pair at its last evaluation: `[s_c, k_c]`, its slope `-mu m_c B'(f(d_c) - xi)` (m)
    /// and its stiffness `mu m_c B''(f(d_c) - xi) f'(d_c) sum_j |alpha_c^j|` (dimensionless);
    /// `None` for a pair that feels no barrier (it adds nothing, not even to `alpha`).
    terms: Vec<Option<[f64; 2]>>,
}

/// The sums of [`BarrierPush::update`], per vertex.
pub(super) struct VertexSums<'a> {
    /// `p_i = sum_c s_c alpha_c^i n_c` (m), the barrier part of the descent direction.
    pub push: &'a mut [Vector3<f64>],
    /// `sum_c m_c |alpha_c^i|` of eq. 53.
    pub alpha: &'a mut [f64],
    /// `K_i = sum_c k_c |alpha_c^i| n_c n_c^T` of [`super::local_step::DescentStep::Curvature`].
    pub curvature: &'a mut [SymmetricMatrix3<f64>],
}

/// Compressed rows: the entries of vertex `v` are `entries[start[v]..start[v + 1]]`.
#[derive(Default)]
struct Rows {
    start: Vec<u32>,
    entries: Vec<u32>,
}

impl Rows {
    fn of(&self, v: usize) -> &[u32] {
        &self.entries[self.start[v] as usize..self.start[v + 1] as usize]
    }
}

/// The longest tail, as a share of the head, that is indexed on its own: beyond it the whole
/// list is indexed afresh (so an extension costs at most about this share of a full index).
const LONGEST_TAIL: f64 = 0.125;

impl BarrierPush {
    /// Brings `sums` up to date with the live pairs `pairs` (version `version` of the list,
    /// see [`super::local_step`], whose first `unchanged` pairs are those of the last update in
    /// their places) and their closest points `closest` at the current iterate:
    /// recomputes the terms of the pairs marked in `fresh` (those whose closest points were
    /// evaluated since the last update, every new pair among them), and the sums of every
    /// vertex of such a pair, or of every vertex where no pair is unchanged (the sums may have
    /// been reset, or the list lost pairs). The other sums are kept: none of their pairs
    /// changed. `fades` holds each
    /// pair's fade `m_c` (see [`super::parallel_fade`]), `barrier` and `mu` the barrier of
    /// eq. 47 and its weight.
    #[allow(clippy::too_many_arguments)]
    pub fn update(
        &mut self,
        pairs: &[Pair],
        (version, unchanged): (u64, usize),
        closest: &[Closest],
        fades: &[f64],
        fresh: &[bool],
        barrier: &Barrier,
        mu: f64,
        sums: VertexSums,
    ) {
        let n = sums.push.len();
        let all = unchanged == 0;
        let fits = self.head_rows.start.len() == n + 1;
        if self.indexed != Some(version) || !fits {
            let tail = pairs.len().saturating_sub(self.head);
            if fits && unchanged >= self.head && tail as f64 <= LONGEST_TAIL * self.head as f64 {
                let rows = &mut self.tail_rows;
                index_by_vertex(
                    pairs[self.head..].iter().map(|p| p.v),
                    n,
                    &mut rows.start,
                    &mut rows.entries,
                );
                let head = self.head as u32;
                rows.entries.iter_mut().for_each(|k| *k += head);
            } else {
                let rows = &mut self.head_rows;
                index_by_vertex(
                    pairs.iter().map(|p| p.v),
                    n,
                    &mut rows.start,
                    &mut rows.entries,
                );
                self.head = pairs.len();
                self.tail_rows.start.clear();
                self.tail_rows.start.resize(n + 1, 0);
                self.tail_rows.entries.clear();
            }
            self.indexed = Some(version);
        }
        let reach = barrier.reach();
        self.terms.resize(pairs.len(), None);
        self.terms
            .par_iter_mut()
            .zip(closest)
            .zip(fades)
            .zip(fresh)
            .for_each(|(((terms, c), &m), &fresh)| {
                if fresh {
                    *terms = pair_terms(c, m, barrier, mu, reach);
                }
            });
        let (head_rows, tail_rows, terms) = (&self.head_rows, &self.tail_rows, &self.terms);
        sums.push
            .par_iter_mut()
            .zip(sums.alpha.par_iter_mut())
            .zip(sums.curvature.par_iter_mut())
            .enumerate()
            .for_each(|(v, ((push, alpha), curvature))| {
                // The head's pairs come before the tail's: in increasing order.
                let rows = [head_rows.of(v), tail_rows.of(v)];
                if !all
                    && !rows
                        .iter()
                        .any(|row| row.iter().any(|&k| fresh[k as usize]))
                {
                    return;
                }
                (*push, *alpha, *curvature) = (Vector3::zeros(), 0.0, SymmetricMatrix3::zeros());
                for &k in rows.into_iter().flatten() {
                    let k = k as usize;
                    let Some([slope, stiffness]) = terms[k] else {
                        continue;
                    };
                    let c = &closest[k];
                    let Some(slot) = pairs[k].v.iter().position(|&u| u as usize == v) else {
                        debug_assert!(false, "vertex {v}'s row holds pair {k}, not its own");
                        continue;
                    };
                    let w = c.weights[slot];
                    let normal = c.separation / c.separation.norm();
                    *push += normal * (slope * w);
                    *alpha += fades[k] * w.abs();
                    *curvature += SymmetricMatrix3::outer(&normal, stiffness * w.abs());
                }
            });
    }
}

/// A pair's `[s_c, k_c]` (see [`BarrierPush::terms`]) at its closest points `c`, with its fade
/// `m`: none beyond the barrier's `reach` (m), at a zero distance (no normal) and for a
/// faded-out pair.
fn pair_terms(c: &Closest, m: f64, barrier: &Barrier, mu: f64, reach: f64) -> Option<[f64; 2]> {
    let d = c.separation.norm();
    if d >= reach || d == 0.0 || m == 0.0 {
        return None;
    }
    let gap = barrier.gap(d);
    // The slope's rate of change with d; the row sum `sum_j |alpha_c^j|` makes `k_i` a
    // Gershgorin bound of the pair's Hessian `B'' f' (alpha n)(alpha n)^T`.
    let rows: f64 = c.weights.iter().map(|w| w.abs()).sum();
    Some([
        -mu * m * barrier.derivative(gap),
        mu * m * barrier.second_derivative(gap) * barrier.rescale_derivative(d) * rows,
    ])
}

#[cfg(test)]
pub(super) mod tests {
    use super::super::broad_phase::ContactMesh;
    use super::super::distance::tests::Rng;
    use super::super::pair_cache::tests::{brute_force_pairs, spiral};
    use super::*;

    /// Asserts that the sums `a` and `b` are the same to the bit, naming the first vertex
    /// where they differ.
    pub(in crate::contact) fn assert_same_sums(a: &Sums, b: &Sums) {
        for v in 0..a.0.len() {
            assert!(
                a.0[v] == b.0[v] && a.1[v] == b.1[v] && a.2[v] == b.2[v],
                "vertex {v}: {:?} against {:?}",
                (a.0[v], a.1[v], a.2[v]),
                (b.0[v], b.1[v], b.2[v])
            );
        }
    }

    /// Per vertex sums over `n` vertices.
    pub(in crate::contact) type Sums = (Vec<Vector3<f64>>, Vec<f64>, Vec<SymmetricMatrix3<f64>>);

    /// The sums `(push, alpha, K)` of `pairs` with their closest points `closest` and fades
    /// `fades` over `n` vertices, from scratch, for the barrier `barrier` with weight `mu`.
    pub(in crate::contact) fn sums_from_scratch(
        pairs: &[Pair],
        closest: &[Closest],
        fades: &[f64],
        n: usize,
        (barrier, mu): (&Barrier, f64),
    ) -> Sums {
        let mut sums = (
            vec![Vector3::zeros(); n],
            vec![0.0; n],
            vec![SymmetricMatrix3::zeros(); n],
        );
        BarrierPush::default().update(
            pairs,
            (0, 0),
            closest,
            fades,
            &vec![true; pairs.len()],
            barrier,
            mu,
            VertexSums {
                push: &mut sums.0,
                alpha: &mut sums.1,
                curvature: &mut sums.2,
            },
        );
        sums
    }

    const MU: f64 = 1.0;

    /// On a rolled-up grid whose turns lie within the barrier's reach (6 mm apart, reach 7.5
    /// mm), with some pairs faded: pairs appended to the list (a new version, only they fresh,
    /// indexed on their own or with the others), new terms for the pairs with a vertex moved
    /// by up to 1 mm and new sums for those pairs' vertices, and a list that lost pairs, all of
    /// one vertex's among them (every sum made again) give, to the bit, the sums over every pair from scratch, though
    /// vertices that did not move have new sums too.
    #[test]
    fn kept_sums_equal_sums_from_scratch_to_the_bit() {
        let mut rng = Rng::new(5);
        let (mut x, triangles) = spiral(12, 0.006, &mut rng);
        let body = vec![0; triangles.len()];
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &body,
            self_contact: &[true],
        };
        let barrier = Barrier {
            thickness: 1.5e-3,
            d_hat: 6e-3,
            eps: 0.1,
        };
        let (_, every) = brute_force_pairs(&mesh, &x);
        let fades: Vec<f64> = (0..every.len())
            .map(|k| [1.0, 1.0, 0.5, 0.0][k % 4])
            .collect();
        let n = x.len();
        let mut sums = (
            vec![Vector3::zeros(); n],
            vec![0.0; n],
            vec![SymmetricMatrix3::zeros(); n],
        );
        let mut kept = BarrierPush::default();
        let update = |kept: &mut BarrierPush,
                      sums: &mut Sums,
                      pairs: &[Pair],
                      version: (u64, usize),
                      x: &[Vector3<f64>],
                      fresh: &[bool]| {
            let closest: Vec<Closest> = pairs.iter().map(|p| p.closest(x)).collect();
            kept.update(
                pairs,
                version,
                &closest,
                &fades[..pairs.len()],
                fresh,
                &barrier,
                MU,
                VertexSums {
                    push: &mut sums.0,
                    alpha: &mut sums.1,
                    curvature: &mut sums.2,
                },
            );
        };
        let assert_from_scratch = |sums: &Sums, pairs: &[Pair], x: &[Vector3<f64>]| {
            let closest: Vec<Closest> = pairs.iter().map(|p| p.closest(x)).collect();
            let scratch = sums_from_scratch(
                pairs,
                &closest,
                &fades[..pairs.len()],
                x.len(),
                (&barrier, MU),
            );
            assert_same_sums(sums, &scratch);
        };
        // The list grows three times, only the new pairs fresh: twice by a twenty-fifth of the
        // pairs (each time the tail indexed on its own, the second time with the first), then
        // by three more (the tail, now a quarter of the head, beyond the longest: the whole
        // list indexed afresh).
        let lengths = [20, 21, 22, 25].map(|twentyfifths| every.len() * twentyfifths / 25);
        let heads = [lengths[0], lengths[0], lengths[0], lengths[3]];
        let mut unchanged = 0;
        for (version, (&len, &head)) in lengths.iter().zip(&heads).enumerate() {
            let appended: Vec<bool> = (0..len).map(|k| k >= unchanged).collect();
            let list = &every[..len];
            update(
                &mut kept,
                &mut sums,
                list,
                (version as u64, unchanged),
                &x,
                &appended,
            );
            assert_eq!(kept.head, head, "list of {len}");
            assert_from_scratch(&sums, list, &x);
            unchanged = len;
        }
        let before = sums.clone();

        // The same list (the same version, its index kept), five vertices moved.
        let moved: Vec<usize> = (0..5).map(|k| 17 + 23 * k).collect();
        for &v in &moved {
            x[v] += rng.vector() * 1e-3;
        }
        let fresh: Vec<bool> = every
            .iter()
            .map(|p| p.v.iter().any(|v| moved.contains(&(*v as usize))))
            .collect();
        let count = fresh.iter().filter(|&&f| f).count();
        assert!(count > 0 && count < every.len() / 4, "{count} fresh pairs");
        update(&mut kept, &mut sums, &every, (3, every.len()), &x, &fresh);
        assert_from_scratch(&sums, &every, &x);
        let changed_still = (0..n)
            .filter(|v| !moved.contains(v) && sums.0[*v] != before.0[*v])
            .count();
        assert!(changed_still > 0, "no vertex that stayed has a new push");

        // A list that lost pairs, among them every pair of a vertex that felt the barrier: its
        // sums go to zero.
        let left_out = (0..n as u32)
            .find(|&v| sums.0[v as usize] != Vector3::zeros())
            .expect("some vertex feels the barrier");
        let fewer: Vec<Pair> = every
            .iter()
            .copied()
            .filter(|p| !p.v.contains(&left_out))
            .step_by(3)
            .collect();
        update(
            &mut kept,
            &mut sums,
            &fewer,
            (4, 0),
            &x,
            &vec![true; fewer.len()],
        );
        assert_from_scratch(&sums, &fewer, &x);
    }
}
