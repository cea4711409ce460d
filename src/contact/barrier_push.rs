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
use super::primitive_pairs::Pair;
use crate::geometry::distance::Closest;
use crate::geometry::vertex_index::index_incidences;
use crate::parallel::chunked_sum;
use crate::symmetric::SymmetricMatrix3;

/// Per vertex of the local step, the sums of eq. 49 and 53 over its live pairs, and what they
/// are made of.
#[derive(Default)]
pub(super) struct BarrierPush {
    /// The live pairs `..head` by vertex.
    head_rows: Rows,
    head: usize,
    /// The pairs from `head` on by vertex: the list grows by pairs appended at its end (many
    /// times in a local step where vertices outgrow their allowances), and indexing only
    /// them keeps an index of millions of pairs from being made again each time (a serial
    /// counting sort of four entries per pair).
    tail_rows: Rows,
    /// The version of the live list the rows are for (None: none yet).
    indexed: Option<u64>,
    /// Per pair, whether it felt the barrier at its last evaluation; `false` for a pair that
    /// adds nothing to the sums, not even to `alpha`. A list of its own, a byte per pair, so
    /// that a vertex's sum skips the many live pairs beyond the barrier's reach without reading
    /// their terms.
    felt: Vec<bool>,
    /// Per pair that [`felt`](Self::felt) the barrier, its term at its last evaluation (others
    /// hold a stale one).
    terms: Vec<Term>,
}

/// What a pair that feels the barrier adds to the sums of its vertices, in one record: a
/// vertex's sum gathers the terms of its pairs from lists of millions of pairs, one cache miss
/// per record (the closest points, the fades and the pairs themselves, read at each pair's
/// place, would take one each).
#[derive(Clone, Copy)]
pub(super) struct Term {
    /// `n_c = d_c / |d_c|`, the unit separation.
    pub(super) normal: Vector3<f64>,
    /// `s_c = -mu m_c B'(f(d_c) - xi)` (m), its slope.
    pub(super) slope: f64,
    /// `k_c = mu m_c B''(f(d_c) - xi) f'(d_c) sum_j |alpha_c^j|` (dimensionless), its stiffness.
    pub(super) stiffness: f64,
    /// `m_c`, its fade (see [`super::parallel_fade`]).
    pub(super) fade: f64,
    /// `alpha_c^j`, the closest points' weights of its four vertices.
    pub(super) weights: [f64; 4],
    /// The pair, the order its term is summed in (see [`BarrierPush::update`]).
    pub(super) pair: Pair,
}

const STALE: Term = Term {
    normal: Vector3::new(0.0, 0.0, 0.0),
    slope: 0.0,
    stiffness: 0.0,
    fade: 0.0,
    weights: [0.0; 4],
    pair: Pair {
        edge_edge: false,
        v: [0; 4],
    },
};

/// The vertices of a pair: its entry in vertex `v`'s row is `SLOTS k + s`, with `v` in slot `s`
/// of pair `k`, so that the sum finds `v`'s weight without reading the pair.
const SLOTS: usize = 4;

/// The sums of [`BarrierPush::update`], per vertex.
pub(super) struct VertexSums<'a> {
    /// `p_i = sum_c s_c alpha_c^i n_c` (m), the barrier part of the descent direction.
    pub push: &'a mut [Vector3<f64>],
    /// `sum_c m_c |alpha_c^i|` of eq. 53.
    pub alpha: &'a mut [f64],
    /// `K_i = sum_c k_c |alpha_c^i| n_c n_c^T` of [`super::local_step::DescentStep::Curvature`].
    pub curvature: &'a mut [SymmetricMatrix3<f64>],
}

/// Compressed rows of pair slots: the entries of vertex `v` are `entries[start[v]..start[v +
/// 1]]`, each `SLOTS k + s` for the pair `k` that holds `v` in its slot `s`, in the order of
/// the pairs themselves (the order a vertex sums its terms in, see [`BarrierPush::update`]).
#[derive(Default)]
struct Rows {
    start: Vec<u32>,
    entries: Vec<u32>,
    /// The pairs indexed last with their places in the list, sorted by pair (kept for its
    /// capacity).
    by_pair: Vec<(Pair, u32)>,
}

impl Rows {
    /// Indexes by their vertices (of `vertices`) `pairs`, those from `first` on of the list.
    /// The pairs are sorted once and then counted into the rows in that order (a stable
    /// counting sort), so that every row comes out in the order of the pairs.
    fn index(&mut self, pairs: &[Pair], first: usize, vertices: usize) {
        assert!(
            (first + pairs.len()) * SLOTS <= u32::MAX as usize,
            "{} live pairs: more than the index by vertex holds",
            first + pairs.len()
        );
        let by_pair = &mut self.by_pair;
        by_pair.clear();
        by_pair.par_extend(
            pairs
                .par_iter()
                .enumerate()
                .map(|(k, &pair)| (pair, (first + k) as u32)),
        );
        by_pair.par_sort_unstable();
        index_incidences(
            by_pair.iter().flat_map(|&(pair, k)| {
                (0..SLOTS).map(move |s| (k * SLOTS as u32 + s as u32, pair.v[s]))
            }),
            vertices,
            &mut self.start,
            &mut self.entries,
        );
    }

    /// Whether vertex `v` has no pair.
    fn is_empty(&self, v: usize) -> bool {
        self.start[v] == self.start[v + 1]
    }

    /// Vertex `v`'s pairs and its slot in each.
    fn of(&self, v: usize) -> impl Iterator<Item = (usize, usize)> + Clone + '_ {
        self.entries[self.start[v] as usize..self.start[v + 1] as usize]
            .iter()
            .map(|&e| (e as usize / SLOTS, e as usize % SLOTS))
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
    /// pair's fade `m_c` (see [`super::parallel_fade`]), `scales` each pair's barrier scale `s_c`
    /// from its rest gap (empty: all 1; see [`pair_term`]), `barrier` and `mu` the barrier of
    /// eq. 47 and its weight.
    #[allow(clippy::too_many_arguments)]
    pub fn update(
        &mut self,
        pairs: &[Pair],
        (version, unchanged): (u64, usize),
        closest: &[Closest],
        (fades, scales): (&[f64], &[f64]),
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
                self.tail_rows.index(&pairs[self.head..], self.head, n);
            } else {
                self.head_rows.index(pairs, 0, n);
                self.head = pairs.len();
                self.tail_rows.index(&[], self.head, n);
            }
            self.indexed = Some(version);
        }
        let reach = barrier.reach();
        self.felt.resize(pairs.len(), false);
        self.terms.resize(pairs.len(), STALE);
        self.terms
            .par_iter_mut()
            .zip(&mut self.felt)
            .zip(closest)
            .zip(fades)
            .zip(fresh)
            .zip(pairs)
            .enumerate()
            .for_each(|(k, (((((term, felt), c), &m), &fresh), pair))| {
                if fresh {
                    let s = scales.get(k).copied().unwrap_or(1.0);
                    let evaluated = pair_term(pair, c, (m, s), barrier, mu, reach);
                    *felt = evaluated.is_some();
                    *term = evaluated.unwrap_or(STALE);
                }
            });
        let rows = [&self.head_rows, &self.tail_rows];
        let (felt, terms) = (&self.felt, &self.terms);
        // Each vertex sums its terms in the order of the pairs themselves, not of their places
        // in the list: the list's order depends on its history (when the pair cache was built,
        // what extended it since), the pairs and their terms do not, and a sum of floats
        // depends on its order. So a simulation restored into a fresh solver (fresh caches)
        // continues bit for bit. Where every sum is taken afresh, those of the vertices without
        // a pair are zero; elsewhere a vertex none of whose pairs is fresh keeps its sums.
        sums.push
            .par_iter_mut()
            .zip(sums.alpha.par_iter_mut())
            .zip(sums.curvature.par_iter_mut())
            .enumerate()
            .for_each(|(v, ((push, alpha), curvature))| {
                if rows.iter().all(|r| r.is_empty(v)) {
                    if all {
                        (*push, *alpha, *curvature) =
                            (Vector3::zeros(), 0.0, SymmetricMatrix3::zeros());
                    }
                    return;
                }
                if !all && !rows.iter().any(|r| r.of(v).any(|(k, _)| fresh[k])) {
                    return;
                }
                (*push, *alpha, *curvature) = (Vector3::zeros(), 0.0, SymmetricMatrix3::zeros());
                for (term, slot) in felt_in_pair_order(rows, v, felt, terms) {
                    let w = term.weights[slot];
                    *push += term.normal * (term.slope * w);
                    *alpha += term.fade * w.abs();
                    *curvature += SymmetricMatrix3::outer(&term.normal, term.stiffness * w.abs());
                }
            });
    }
}

impl BarrierPush {
    /// Vertex `v`'s terms of the pairs that felt the barrier at their last
    /// [`BarrierPush::update`], each with `v`'s slot in it, in the order of the pairs (the
    /// order the sums take them in).
    pub(super) fn felt_terms(&self, v: usize) -> impl Iterator<Item = (&Term, usize)> + '_ {
        felt_in_pair_order(
            [&self.head_rows, &self.tail_rows],
            v,
            &self.felt,
            &self.terms,
        )
    }
}

/// The terms of vertex `v`'s pairs in `rows` (its head row, then its tail row, each sorted by
/// pair) that `felt` the barrier, each with `v`'s slot in it, in the order of the pairs: the
/// two rows merged (the head's first among equal pairs, as a stable sort of the two would
/// put them), with no list gathered and no sort.
fn felt_in_pair_order<'a>(
    rows: [&'a Rows; 2],
    v: usize,
    felt: &'a [bool],
    terms: &'a [Term],
) -> impl Iterator<Item = (&'a Term, usize)> + 'a {
    let side = move |rows: &'a Rows| {
        rows.of(v)
            .filter(move |&(k, _)| felt[k])
            .map(move |(k, slot)| (&terms[k], slot))
            .peekable()
    };
    let (mut head, mut tail) = (side(rows[0]), side(rows[1]));
    std::iter::from_fn(move || match (head.peek(), tail.peek()) {
        (Some(a), Some(b)) if b.0.pair < a.0.pair => tail.next(),
        (Some(_), _) => head.next(),
        (None, _) => tail.next(),
    })
}

/// The [`Term`] of `pair` at its closest points `c`, with its fade `m` and its barrier scale
/// `s` (1, or its rest gap over the reach, see `local_step/rest_gaps.rs`): the barrier in
/// lengths scaled by `s`, `s^2 B(f(d / s) - xi)` (m^2), whose slope is `s B'` and whose
/// curvature `B'' f'` at `d / s` (eq. 3, 49, 51). None beyond the scaled `reach` (m), at a zero
/// distance (no normal) and for a faded-out pair.
fn pair_term(
    pair: &Pair,
    c: &Closest,
    (m, s): (f64, f64),
    barrier: &Barrier,
    mu: f64,
    reach: f64,
) -> Option<Term> {
    let d = c.separation.norm();
    if d >= s * reach || d == 0.0 || m == 0.0 {
        return None;
    }
    let scaled = d / s;
    let gap = barrier.gap(scaled);
    // The slope's rate of change with d; the row sum `sum_j |alpha_c^j|` makes `k_i` a
    // Gershgorin bound of the pair's Hessian `B'' f' (alpha n)(alpha n)^T`.
    let rows: f64 = c.weights.iter().map(|w| w.abs()).sum();
    Some(Term {
        normal: c.separation / d,
        slope: -mu * m * s * barrier.derivative(gap),
        stiffness: mu
            * m
            * barrier.second_derivative(gap)
            * barrier.rescale_derivative(scaled)
            * rows,
        fade: m,
        weights: c.weights,
        pair: *pair,
    })
}

/// The barrier energy `mu sum_c m_c s_c^2 B(f(d_c / s_c) - xi)` (m^2) of the pairs with closest
/// points `closest`, fades `fades` and barrier scales `scales` (empty: all 1), as [`pair_term`]
/// weighs them (eq. 47's second term).
pub fn barrier_energy(
    closest: &[Closest],
    (fades, scales): (&[f64], &[f64]),
    barrier: &Barrier,
    mu: f64,
) -> f64 {
    let reach = barrier.reach();
    let term = |k: usize| {
        let (c, m) = (&closest[k], fades[k]);
        let s = scales.get(k).copied().unwrap_or(1.0);
        let d = c.separation.norm();
        if d >= s * reach || m == 0.0 {
            return 0.0;
        }
        mu * m * s * s * barrier.value(barrier.gap(d / s))
    };
    chunked_sum(closest.len(), &mut Vec::new(), term)
}

#[cfg(test)]
pub(super) mod tests {
    use super::super::broad_phase::ContactMesh;
    use super::super::test_meshes::{brute_force_pairs, spiral};
    use super::*;
    use crate::geometry::distance::tests::Rng;

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
        (fades, scales): (&[f64], &[f64]),
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
            (fades, scales),
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
                (&fades[..pairs.len()], &[]),
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
                (&fades[..pairs.len()], &[]),
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

    /// A list that grew by a tail indexed on its own, whose pairs interleave with the head's in
    /// pair order (every other pair of a rolled-up grid's list, then the rest): each vertex's
    /// felt terms come in increasing pair order, one for each pair that holds the vertex and
    /// lies within the barrier's reach, and for some vertices a tail pair comes between head
    /// pairs (the merge is needed).
    #[test]
    fn felt_terms_merge_head_and_tail_in_pair_order() {
        let (x, pairs, barrier) = rolled_up_grid(7);
        let list: Vec<Pair> = pairs
            .iter()
            .step_by(2)
            .chain(pairs.iter().skip(1).step_by(2))
            .copied()
            .collect();
        let head = list.len() * 19 / 20;
        let closest: Vec<Closest> = list.iter().map(|p| p.closest(&x)).collect();
        let fades = vec![1.0; list.len()];
        let n = x.len();
        let mut sums: Sums = (
            vec![Vector3::zeros(); n],
            vec![0.0; n],
            vec![SymmetricMatrix3::zeros(); n],
        );
        let mut kept = BarrierPush::default();
        for (version, (len, unchanged)) in [(head, 0), (list.len(), head)].into_iter().enumerate() {
            let fresh: Vec<bool> = (0..len).map(|k| k >= unchanged).collect();
            kept.update(
                &list[..len],
                (version as u64, unchanged),
                &closest[..len],
                (&fades[..len], &[]),
                &fresh,
                &barrier,
                MU,
                VertexSums {
                    push: &mut sums.0,
                    alpha: &mut sums.1,
                    curvature: &mut sums.2,
                },
            );
        }
        assert_eq!(kept.head, head, "the tail indexed on its own");
        let mut interleaved = 0;
        for v in 0..n as u32 {
            let felt: Vec<Pair> = kept.felt_terms(v as usize).map(|(t, _)| t.pair).collect();
            assert!(felt.windows(2).all(|w| w[0] < w[1]), "vertex {v}: {felt:?}");
            let within = list
                .iter()
                .zip(&closest)
                .filter(|(p, c)| {
                    let d = c.separation.norm();
                    p.v.contains(&v) && d > 0.0 && d < barrier.reach()
                })
                .count();
            assert_eq!(felt.len(), within, "vertex {v}");
            let from_tail = |p: &Pair| list[head..].contains(p);
            interleaved += usize::from(
                felt.windows(2)
                    .any(|w| from_tail(&w[0]) && !from_tail(&w[1])),
            );
        }
        assert!(
            interleaved > 10,
            "{interleaved} vertices with a tail pair before a head pair"
        );
    }

    /// A rolled-up grid (turns 6 mm apart, seeded jitter `seed`), its primitive pairs within a
    /// 7.5 mm reach and that barrier.
    fn rolled_up_grid(seed: u64) -> (Vec<Vector3<f64>>, Vec<Pair>, Barrier) {
        let mut rng = Rng::new(seed);
        let (x, triangles) = spiral(10, 0.006, &mut rng);
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
        let (_, pairs) = brute_force_pairs(&mesh, &x);
        (x, pairs, barrier)
    }

    /// The sums gathered by vertex (each vertex's slot in each pair taken from the index, the
    /// pairs that feel no barrier skipped) equal a plain scatter of every pair's terms onto
    /// its four vertices, on a rolled-up grid (turns 6 mm apart within the 7.5 mm reach, some
    /// pairs faded, some out): pairs of each kind, vertices in every slot.
    #[test]
    fn the_gathered_sums_equal_a_scatter_of_each_pairs_terms() {
        let (x, pairs, barrier) = rolled_up_grid(11);
        let fades: Vec<f64> = (0..pairs.len())
            .map(|k| [1.0, 0.75, 1.0, 0.0, 0.25][k % 5])
            .collect();
        let closest: Vec<Closest> = pairs.iter().map(|p| p.closest(&x)).collect();
        let n = x.len();
        let mut scattered: Sums = (
            vec![Vector3::zeros(); n],
            vec![0.0; n],
            vec![SymmetricMatrix3::zeros(); n],
        );
        let mut felt = [0, 0];
        for ((pair, c), &m) in pairs.iter().zip(&closest).zip(&fades) {
            let d = c.separation.norm();
            if d >= barrier.reach() || m == 0.0 {
                continue;
            }
            felt[usize::from(pair.edge_edge)] += 1;
            let gap = barrier.gap(d);
            let normal = c.separation / d;
            let slope = -MU * m * barrier.derivative(gap);
            let rows: f64 = c.weights.iter().map(|w| w.abs()).sum();
            let stiffness =
                MU * m * barrier.second_derivative(gap) * barrier.rescale_derivative(d) * rows;
            for (&v, &w) in pair.v.iter().zip(&c.weights) {
                let v = v as usize;
                scattered.0[v] += normal * (slope * w);
                scattered.1[v] += m * w.abs();
                scattered.2[v] += SymmetricMatrix3::outer(&normal, stiffness * w.abs());
            }
        }
        assert!(
            felt[0] > 50 && felt[1] > 50,
            "{felt:?} point-triangle, edge-edge pairs felt"
        );
        let gathered = sums_from_scratch(&pairs, &closest, (&fades, &[]), n, (&barrier, MU));
        let mut pushed = 0;
        for v in 0..n {
            let (push, alpha) = (scattered.0[v], scattered.1[v]);
            let curvature = scattered.2[v].to_matrix();
            pushed += usize::from(alpha > 0.0);
            assert!(
                (gathered.0[v] - push).norm() <= 1e-12 * push.norm()
                    && (gathered.1[v] - alpha).abs() <= 1e-12 * alpha
                    && (gathered.2[v].to_matrix() - curvature).norm() <= 1e-12 * curvature.norm(),
                "vertex {v}: {:?} against {:?}",
                (gathered.0[v], gathered.1[v]),
                (push, alpha)
            );
        }
        assert!(pushed > n / 4, "{pushed} of {n} vertices feel the barrier");
    }
    /// The sums do not depend on the order of the pairs in the list, to the bit (the list's
    /// order depends on its history, and a restored simulation, with a fresh list, must
    /// continue bit for bit): the pairs of a rolled-up grid, reversed and rotated.
    #[test]
    fn the_sums_do_not_depend_on_the_order_of_the_pairs() {
        let (x, pairs, barrier) = rolled_up_grid(5);
        let sums_in = |order: &[usize]| {
            let pairs: Vec<Pair> = order.iter().map(|&k| pairs[k]).collect();
            let closest: Vec<Closest> = pairs.iter().map(|p| p.closest(&x)).collect();
            let fades = vec![1.0; pairs.len()];
            sums_from_scratch(&pairs, &closest, (&fades, &[]), x.len(), (&barrier, MU))
        };
        let listed: Vec<usize> = (0..pairs.len()).collect();
        let reversed: Vec<usize> = listed.iter().rev().copied().collect();
        let mut rotated = listed.clone();
        rotated.rotate_left(pairs.len() / 3);
        let sums = sums_in(&listed);
        assert!(sums.1.iter().filter(|&&a| a > 0.0).count() > x.len() / 4);
        assert_same_sums(&sums, &sums_in(&reversed));
        assert_same_sums(&sums, &sums_in(&rotated));
    }

    /// The push of a lone pair against central differences of its barrier energy
    /// `E(x) = mu B(f(d(x)) - xi)` (eq. 47, fade 1), on random point-triangle and edge-edge
    /// pairs set at distances across the barrier's range: beyond the rescale (`d > (1 + 2 eps)
    /// xi`, `f' = 1`) the push is the energy's descent direction `-grad E` exactly; within it
    /// eq. 49 leaves `f'(d)` out, so the push is `-grad E / f'`, larger (the rescaled
    /// barrier's slope, not the energy's: it keeps pushing apart as `f'` falls to 0 at `xi`).
    #[test]
    fn the_push_is_the_descent_direction_of_the_barrier_energy_up_to_the_rescale_slope() {
        let barrier = Barrier {
            thickness: 1.5e-3,
            d_hat: 6e-3,
            eps: 0.1,
        };
        let xi = barrier.thickness;
        let rescale_end = (1.0 + 2.0 * barrier.eps) * xi;
        let mut rng = Rng::new(23);
        let mut checked = [[0; 2]; 2];
        for case in 0..400 {
            let pair = Pair {
                edge_edge: case % 2 == 1,
                v: [0, 1, 2, 3],
            };
            let mut x: Vec<Vector3<f64>> = (0..4).map(|_| rng.vector() * 0.01).collect();
            // Set the pair at a distance drawn within the rescale `(xi, (1 + 2 eps) xi)` or
            // beyond it, up to `reach`, by moving its second primitive along the separation.
            let c = pair.closest(&x);
            let d = c.separation.norm();
            let (near, far) = if case % 4 < 2 {
                (xi, rescale_end)
            } else {
                (rescale_end, barrier.reach())
            };
            let target = near + (far - near) * (0.02 + 0.96 * rng.uniform().abs());
            let (_, second) = pair.sides();
            for &v in second {
                x[v as usize] -= c.separation * ((target - d) / d);
            }
            let c = pair.closest(&x);
            let d = c.separation.norm();
            let normal = c.separation / d;
            let edges_parallel = pair.edge_edge && {
                let (a, b) = (x[1] - x[0], x[3] - x[2]);
                a.cross(&b).norm() < 0.1 * a.norm() * b.norm()
            };
            // Away from the rescale's breakpoint (f'' jumps there) and from nearly parallel
            // edges (closest points that jump with the motion).
            if (d - rescale_end).abs() < 1e-5 || edges_parallel || d >= barrier.reach() - 1e-5 {
                continue;
            }
            let sums = sums_from_scratch(&[pair], &[c], (&[1.0], &[]), 4, (&barrier, MU));
            let energy = |x: &[Vector3<f64>]| {
                MU * barrier.value(barrier.gap(pair.closest(x).separation.norm()))
            };
            let h = 1e-8;
            let slope = barrier.rescale_derivative(d);
            // Within a millionth of the largest slope, `|B'(eps xi)|`.
            let tolerance = 1e-6 * MU * barrier.derivative_bound();
            for v in 0..4 {
                let mut descent = Vector3::zeros();
                for k in 0..3 {
                    let (mut ahead, mut behind) = (x.clone(), x.clone());
                    ahead[v][k] += h;
                    behind[v][k] -= h;
                    descent[k] = -(energy(&ahead) - energy(&behind)) / (2.0 * h);
                }
                assert!(
                    (sums.0[v] * slope - descent).norm() <= tolerance,
                    "case {case} ({} at d = {d:e} m, f' = {slope}), vertex {v}: push {:?} \
                     times f' against -grad E {:?}",
                    if pair.edge_edge {
                        "edge-edge"
                    } else {
                        "point-triangle"
                    },
                    sums.0[v] * slope,
                    descent
                );
                // The push points along the separation, apart, on the side of each vertex.
                assert!(
                    sums.0[v].dot(&normal) * c.weights[v] >= 0.0,
                    "case {case}, vertex {v}"
                );
            }
            checked[usize::from(pair.edge_edge)][usize::from(d < rescale_end)] += 1;
        }
        assert!(
            checked.iter().flatten().all(|&n| n >= 10),
            "{checked:?} [point-triangle, edge-edge] x [beyond, within the rescale]"
        );
    }
}
