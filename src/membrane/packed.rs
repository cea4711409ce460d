//! The kernel pass over every vertex, with the rest data regrouped for SIMD.
//!
//! Each body's vertices are cut into windows of [`WINDOW_PACKS`] `x L` consecutive vertices
//! (`L` = [`SimdValue::LANES`] of the precision's [`Real::Pack`]); within a window the vertices
//! are ordered by their number of bonds (stably) and cut into packs of `L`, one vertex per
//! lane, so that a pack's lanes have about as many bonds as it has slots (on a grid with
//! alternating diagonals, vertices of 4 and 8 bonds alternate: consecutive packs would all pad
//! to 8 slots). A window's last pack, when short, repeats its last vertex in the spare lanes
//! (computed and discarded). The pack's bonds are stored in slots: slot `k` holds every lane's
//! `k`-th bond (in CSR order), as one [`BondRest`] of packs, and the neighbour each lane's bond
//! points to. A lane with fewer bonds than the pack has slots points its extra slots at itself
//! with zero rest data, so they contribute exactly nothing. The kernel then runs once per pack
//! with every operation on `L` vertices at a time, and every lane's result is bit-identical to
//! the scalar kernel's for that vertex (see [`Lanes`]). A pack never spans two bodies, so its
//! lanes share one material model.

use nalgebra::{SimdValue, Vector3};

use crate::error::Result;
use crate::isa;
use crate::material::MaterialModel;
use crate::mesh::Neighborhood;
use crate::parallel::{for_each_block, for_each_vertex};
use crate::real::{Lanes, Real};

use super::kernel::{bond_vectors, vertex_kernel, GatheredResponse, Preconditioner};
use super::{BondRest, Frame, RestData, RestSource, Stencil, VertexConstants, VertexRest};

/// Packs per window of vertices (see the module documentation): wide enough to find lanes of
/// equal bond counts, narrow enough to keep a pack's vertices close in memory.
const WINDOW_PACKS: usize = 8;

/// Rest data of whole packs of vertices (see the module documentation): everything the kernel
/// needs, built a window at a time from the rest data source, with no scalar copy kept.
#[derive(Debug, Clone)]
pub struct PackedRest<S: Lanes> {
    /// First vertex of each window, then the vertex count.
    windows: Vec<u32>,
    /// First pack of each window, then the pack count.
    window_packs: Vec<u32>,
    /// Per pack, the vertex of each of its `L` lanes.
    lanes: Vec<u32>,
    /// Per pack, how many of its lanes are distinct vertices (the rest repeat the last).
    filled: Vec<u8>,
    /// Slots of pack `p`: `slot_offsets[p]..slot_offsets[p + 1]`.
    slot_offsets: Vec<u32>,
    /// Per slot, `L` neighbour indices (lane-major within the slot).
    neighbors: Vec<u32>,
    bonds: Vec<BondRest<S>>,
    frames: Vec<Frame<S>>,
    constants: Vec<VertexConstants<S>>,
}

impl<S: Lanes> PackedRest<S> {
    /// No packs.
    pub fn empty() -> Self {
        Self {
            windows: vec![0],
            window_packs: vec![0],
            lanes: Vec::new(),
            filled: Vec::new(),
            slot_offsets: vec![0],
            neighbors: Vec::new(),
            bonds: Vec::new(),
            frames: Vec::new(),
            constants: Vec::new(),
        }
    }

    /// Appends the packs of one body, given by its own neighbourhood `nb` and its rest data
    /// `source` (in f64, converted here), whose vertices follow the ones already packed. The
    /// rest data are computed a window at a time, never for the whole body at once; `each` sees
    /// every vertex's, in order (for a user that keeps per-vertex data of its own).
    pub fn add_body(
        &mut self,
        nb: &Neighborhood,
        source: &RestSource,
        each: &mut impl FnMut(&VertexRest<f64>),
    ) -> Result<()> {
        let lanes = S::LANES;
        let n = source.len();
        let base = self.windows.pop().expect("windows holds the vertex count") as usize;
        let window = WINDOW_PACKS * lanes;
        // The windows' vertices in pack order: ascending bond count, stably.
        let ordered = |w: usize, order: &mut Vec<usize>| {
            order.clear();
            order.extend(w..(w + window).min(n));
            order.sort_by_key(|&i| nb.of(i).len());
        };
        let mut order = Vec::with_capacity(window);
        let (mut packs, mut slots) = (0, 0);
        for w in (0..n).step_by(window) {
            ordered(w, &mut order);
            for members in order.chunks(lanes) {
                packs += 1;
                slots += nb.of(members[members.len() - 1]).len();
            }
        }
        self.slot_offsets.reserve_exact(packs);
        self.neighbors.reserve_exact(slots * lanes);
        self.bonds.reserve_exact(slots);
        self.frames.reserve_exact(packs);
        self.constants.reserve_exact(packs);
        self.lanes.reserve_exact(packs * lanes);
        self.filled.reserve_exact(packs);
        let of = |x: f64| <S::Scalar as Real>::of(x);
        let mut rests = Vec::with_capacity(window);
        for w in (0..n).step_by(window) {
            let end = (w + window).min(n);
            self.windows.push((base + w) as u32);
            rests.clear();
            for i in w..end {
                rests.push(source.vertex(i)?);
                each(&rests[i - w]);
            }
            ordered(w, &mut order);
            for members in order.chunks(lanes) {
                // Lane `l` computes vertex `vertex(l)` (the pack's last one in spare lanes).
                let vertex = |l: usize| members[l.min(members.len() - 1)];
                let rest = |l: usize| &rests[vertex(l) - w];
                self.lanes
                    .extend((0..lanes).map(|l| (base + vertex(l)) as u32));
                self.filled.push(members.len() as u8);
                let slots = members.iter().map(|&i| nb.of(i).len()).max().unwrap_or(0);
                for k in 0..slots {
                    for l in 0..lanes {
                        let own = nb.of(vertex(l));
                        let j = own.get(k).map_or(vertex(l), |&j| j as usize);
                        self.neighbors.push((base + j) as u32);
                    }
                    let part = |f: fn(&BondRest<f64>) -> f64| {
                        S::gather(|l| of(rest(l).bonds.get(k).map_or(0.0, f)))
                    };
                    self.bonds.push(BondRest {
                        beta: [part(|b| b.beta[0]), part(|b| b.beta[1])],
                        xi: Vector3::new(part(|b| b.xi.x), part(|b| b.xi.y), part(|b| b.xi.z)),
                        curvature: Vector3::new(
                            part(|b| b.curvature.x),
                            part(|b| b.curvature.y),
                            part(|b| b.curvature.z),
                        ),
                    });
                }
                self.slot_offsets.push(self.bonds.len() as u32);
                let frame = |f: fn(&Frame<f64>) -> Vector3<f64>| {
                    let c = |c: usize| S::gather(|l| of(f(&rest(l).frame)[c]));
                    Vector3::new(c(0), c(1), c(2))
                };
                self.frames.push(Frame {
                    t1: frame(|f| f.t1),
                    t2: frame(|f| f.t2),
                    nc: frame(|f| f.nc),
                });
                let constant =
                    |f: fn(&VertexConstants<f64>) -> f64| S::gather(|l| of(f(&rest(l).constants)));
                self.constants.push(VertexConstants {
                    volume: constant(|c| c.volume),
                    mass: constant(|c| c.mass),
                    k_iso: constant(|c| c.k_iso),
                    k_bound: constant(|c| c.k_bound),
                    kappa_t: constant(|c| c.kappa_t),
                    kappa_n: constant(|c| c.kappa_n),
                    half_thickness: constant(|c| c.half_thickness),
                    material: pack_material(|l| rest(l).constants.material.to_real())
                        .expect("a body has one material"),
                });
            }
            self.window_packs.push(self.frames.len() as u32);
        }
        self.windows.push((base + n) as u32);
        Ok(())
    }

    /// Most slots of any pack.
    fn max_slots(&self) -> usize {
        self.slot_offsets
            .windows(2)
            .map(|w| (w[1] - w[0]) as usize)
            .max()
            .unwrap_or(0)
    }
}

/// The lanes' materials as one pack, if they are all of the same model.
fn pack_material<S: Lanes>(
    lane: impl Fn(usize) -> MaterialModel<S::Scalar>,
) -> Option<MaterialModel<S>> {
    let models: Vec<_> = (0..S::LANES).map(lane).collect();
    match models[0] {
        MaterialModel::StretchA3 { .. } => {
            let s0 = |l: usize| match models[l] {
                MaterialModel::StretchA3 { s0 } => Some(s0),
                _ => None,
            };
            (0..S::LANES)
                .all(|l| s0(l).is_some())
                .then(|| MaterialModel::StretchA3 {
                    s0: S::gather(|l| s0(l).expect("checked above")),
                })
        }
        MaterialModel::NeoHookean { .. } => {
            let params = |l: usize| match models[l] {
                MaterialModel::NeoHookean { s0, s1 } => Some((s0, s1)),
                _ => None,
            };
            (0..S::LANES)
                .all(|l| params(l).is_some())
                .then(|| MaterialModel::NeoHookean {
                    s0: S::gather(|l| params(l).expect("checked above").0),
                    s1: S::gather(|l| params(l).expect("checked above").1),
                })
        }
    }
}

/// The kernel at every vertex of `y`: per-bond gradients `dE_i/d(y_j - y_i)` into `bond_grad`
/// (CSR order of `nb`) and per-vertex responses (their gathered part) into `response`. With `packed` (the same rest
/// data regrouped; `rest.bonds` is then not read) whole packs of vertices run at once; the
/// results are the same bit for bit, and for any number of threads.
pub fn evaluate_vertices<T: Real>(
    nb: &Neighborhood,
    rest: &RestData<T>,
    packed: Option<&PackedRest<T::Pack>>,
    y: &[Vector3<T>],
    mode: Preconditioner,
    bond_grad: &mut [Vector3<T>],
    response: &mut [GatheredResponse<T>],
) {
    let Some(p) = packed else {
        for_each_vertex(
            &nb.offsets,
            bond_grad,
            response,
            &|i, grads: &mut [Vector3<T>]| {
                bond_vectors(i, y, nb.of(i), grads);
                GatheredResponse::from(&vertex_kernel(&rest.stencil(nb, i), mode, grads))
            },
        );
        return;
    };
    let slots = p.max_slots();
    for_each_block(
        &nb.offsets,
        &p.windows,
        bond_grad,
        response,
        &|windows, first, bonds, out| {
            isa::run(
                #[inline(always)]
                || evaluate_packs(nb, p, slots, y, mode, windows, first, bonds, out),
            )
        },
    );
}

/// The kernel on the packs of the windows `windows` of `p` (see [`evaluate_vertices`]), whose
/// first vertex is `first`: their bonds' gradients into `bonds` and their responses into `out`
/// (the run's parts of the whole arrays). `slots`: the most slots of any pack. Inlined into each
/// copy [`isa::run`] chooses from.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn evaluate_packs<T: Real>(
    nb: &Neighborhood,
    p: &PackedRest<T::Pack>,
    slots: usize,
    y: &[Vector3<T>],
    mode: Preconditioner,
    windows: std::ops::Range<usize>,
    first: usize,
    bonds: &mut [Vector3<T>],
    out: &mut [GatheredResponse<T>],
) {
    let lanes = T::Pack::LANES;
    let base = nb.offsets[first] as usize;
    let mut edges = Vec::with_capacity(slots);
    let packs = p.window_packs[windows.start] as usize..p.window_packs[windows.end] as usize;
    for pack in packs {
        let members = &p.lanes[pack * lanes..(pack + 1) * lanes];
        let slot_range = p.slot_offsets[pack] as usize..p.slot_offsets[pack + 1] as usize;
        let own = |c: usize| T::Pack::gather(|l| y[members[l] as usize][c]);
        let yi = Vector3::new(own(0), own(1), own(2));
        edges.clear();
        for slot in slot_range.clone() {
            let j = &p.neighbors[slot * lanes..(slot + 1) * lanes];
            let at = |c: usize| T::Pack::gather(|l| y[j[l] as usize][c]);
            edges.push(Vector3::new(at(0), at(1), at(2)) - yi);
        }
        let stencil = Stencil {
            bonds: &p.bonds[slot_range],
            frame: &p.frames[pack],
            constants: &p.constants[pack],
        };
        let r = GatheredResponse::from(&vertex_kernel(&stencil, mode, &mut edges));
        for (l, &i) in members[..p.filled[pack] as usize].iter().enumerate() {
            let i = i as usize;
            let range = nb.bonds(i);
            for (e, g) in edges
                .iter()
                .zip(&mut bonds[range.start - base..range.end - base])
            {
                *g = Vector3::new(e.x.extract(l), e.y.extract(l), e.z.extract(l));
            }
            out[i - first] = r.lane(l);
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::*;
    use crate::material::Material;
    use crate::membrane::{Membrane, MembraneParams};
    use crate::mesh::{Neighborhood, TriangleMesh};
    use crate::symmetric::SymmetricMatrix3;
    use crate::test_rng::Rng;

    /// A 9 x 7 grid (63 vertices, so the last pack is short; corner, edge and interior vertices
    /// have different bond counts) with 2-ring bonds, bending and hourglass,
    /// deformed by a smooth bend plus noise, with one neighbourhood collapsed to a point and
    /// one flattened to a line (the director fallbacks).
    fn body(material: Material) -> Membrane {
        let params = MembraneParams {
            thickness: 1e-3,
            density: 200.0,
            material,
            bending: 1e-5,
            hourglass: MembraneParams::DEFAULT_HOURGLASS,
            neighbors: 2,
        };
        let mut m = Membrane::new(TriangleMesh::grid(9, 7, 0.8, 0.6).unwrap(), params).unwrap();
        let mut rng = Rng::new(5);
        let mut y: Vec<Vector3<f64>> = m
            .positions()
            .iter()
            .map(|p| {
                let bend = Vector3::new(p.x, p.y, 0.3 * (2.0 * p.x).sin() * p.y);
                bend + rng.vector() * 0.02
            })
            .collect();
        let hub = 9 * 3 + 4;
        for &j in m.neighborhood().of(hub) {
            y[j as usize] = y[hub];
        }
        for &j in m.neighborhood().of(9 * 5 + 6) {
            y[j as usize] = Vector3::new(y[j as usize].x, 0.5, 0.1);
        }
        m.set_positions(y).unwrap();
        m
    }

    fn zero<T: Real>() -> GatheredResponse<T> {
        GatheredResponse::new(SymmetricMatrix3::zeros(), T::zero())
    }

    /// The bodies concatenated (as the solver does) and evaluated in packs, against each body
    /// evaluated alone by the scalar kernel: equal bit for bit.
    fn check<T: Real>(bodies: &[&Membrane], mode: Preconditioner) {
        let mut nb = Neighborhood {
            offsets: vec![0],
            indices: Vec::new(),
            reverse: Vec::new(),
        };
        let (mut y, mut packed) = (Vec::new(), PackedRest::<T::Pack>::empty());
        let (mut grads, mut out) = (Vec::new(), Vec::new());
        for m in bodies {
            let own = m.neighborhood();
            let (vertex_base, bond_base) = (y.len() as u32, nb.indices.len() as u32);
            nb.offsets
                .extend(own.offsets[1..].iter().map(|o| o + bond_base));
            nb.indices
                .extend(own.indices.iter().map(|j| j + vertex_base));
            nb.reverse.extend(own.reverse.iter().map(|b| b + bond_base));
            let yb: Vec<Vector3<T>> = m.positions().iter().map(|p| p.map(T::of)).collect();
            let mut g = vec![Vector3::zeros(); own.indices.len()];
            let mut o = vec![zero(); yb.len()];
            let source = m.rest_source().unwrap();
            let mut rest = RestData::<T>::empty();
            rest.extend_from(&source, true).unwrap();
            evaluate_vertices(own, &rest, None, &yb, mode, &mut g, &mut o);
            packed.add_body(own, &source, &mut |_| {}).unwrap();
            y.extend(yb);
            grads.extend(g);
            out.extend(o);
        }
        let mut simd_grads = vec![Vector3::zeros(); nb.indices.len()];
        let mut simd_out = vec![zero(); y.len()];
        let unused = RestData::empty();
        evaluate_vertices(
            &nb,
            &unused,
            Some(&packed),
            &y,
            mode,
            &mut simd_grads,
            &mut simd_out,
        );
        for (i, (a, b)) in out.iter().zip(&simd_out).enumerate() {
            assert!(
                a.energy().is_finite() && a.precond().to_matrix().iter().all(|x| x.is_finite()),
                "{} {i} {a:?}",
                T::NAME
            );
            assert_eq!(a, b, "{} vertex {i}", T::NAME);
        }
        for (k, (a, b)) in grads.iter().zip(&simd_grads).enumerate() {
            assert!(a.iter().all(|x| x.is_finite()));
            assert_eq!(a, b, "{} bond {k}", T::NAME);
        }
    }

    /// The SIMD packs give the scalar kernel's results bit for bit, for both precisions,
    /// materials and preconditioners, degenerate neighbourhoods, short packs and a body
    /// boundary (two bodies of different materials) included.
    #[test]
    fn packs_match_the_scalar_kernel_exactly() {
        let a3 = body(Material::stretch_a3(3e4).unwrap());
        let nh = body(Material::neo_hookean(1e4, 2e4).unwrap());
        for mode in [Preconditioner::Tangent, Preconditioner::Paper] {
            check::<f32>(&[&a3, &nh], mode);
            check::<f64>(&[&nh, &a3], mode);
        }
    }

    /// Packs are cut at body boundaries and group vertices of equal bond counts: two bodies of
    /// 63 vertices (one window each in f32) give 8 packs each, every vertex in exactly one
    /// pack's filled lanes, the lanes of a window in ascending bond count, spare lanes repeating
    /// the last vertex, and no more slots than the pack's largest bond count.
    #[test]
    fn packs_stay_in_one_body_and_group_equal_bond_counts() {
        let m = body(Material::stretch_a3(1e3).unwrap());
        let mut packed = PackedRest::<crate::real::F32Pack>::empty();
        let source = m.rest_source().unwrap();
        let nb = m.neighborhood();
        packed.add_body(nb, &source, &mut |_| {}).unwrap();
        packed.add_body(nb, &source, &mut |_| {}).unwrap();
        assert_eq!(packed.windows, [0, 63, 126]);
        assert_eq!(packed.window_packs, [0, 8, 16]);
        assert_eq!(packed.frames.len(), 16);
        let degree = |v: u32| nb.of(v as usize % 63).len();
        let mut seen = vec![0; 126];
        for (p, lanes) in packed.lanes.chunks(8).enumerate() {
            let filled = &lanes[..packed.filled[p] as usize];
            let body = filled[0] / 63;
            assert!(
                filled.iter().all(|&v| v / 63 == body),
                "pack {p}: {lanes:?}"
            );
            assert!(lanes[filled.len()..]
                .iter()
                .all(|&v| v == filled[filled.len() - 1]));
            assert!(filled.windows(2).all(|w| degree(w[0]) <= degree(w[1])));
            let slots = packed.slot_offsets[p + 1] - packed.slot_offsets[p];
            assert_eq!(slots as usize, degree(filled[filled.len() - 1]), "pack {p}");
            filled.iter().for_each(|&v| seen[v as usize] += 1);
        }
        assert!(seen.iter().all(|&c| c == 1));
    }

    /// Lanes of different material models do not make a pack.
    #[test]
    fn mixed_materials_do_not_pack() {
        let a3 = MaterialModel::StretchA3 { s0: 1.0f32 };
        let nh = MaterialModel::NeoHookean {
            s0: 1.0f32,
            s1: 2.0,
        };
        assert!(pack_material::<crate::real::F32Pack>(|_| a3).is_some());
        assert!(pack_material::<crate::real::F32Pack>(|l| if l == 5 { nh } else { a3 }).is_none());
    }
}
