//! The kernel pass over every vertex, with the rest data regrouped for SIMD.
//!
//! Vertices `p L .. p L + L` (`L` = [`SimdValue::LANES`] of the precision's
//! [`Real::Pack`]) form pack `p`; lane `l` of the pack is vertex `p L + l`. The pack's bonds are
//! stored in slots: slot `k` holds every lane's `k`-th bond (in CSR order), as one
//! [`BondRest`] of packs, and the neighbour each lane's bond points to. A lane with fewer bonds
//! than the pack has slots points its extra slots at itself with zero rest data, so they
//! contribute exactly nothing. The kernel then runs once per pack with every operation on `L`
//! vertices at a time, and every lane's result is bit-identical to the scalar kernel's for that
//! vertex (see [`Lanes`]).
//!
//! A pack runs on the scalar path instead when its lanes have different material models (a
//! pack across two bodies), and so do the last `n mod L` vertices.

use nalgebra::{SimdValue, Vector3};

use crate::material::MaterialModel;
use crate::mesh::Neighborhood;
use crate::parallel::for_each_range;
use crate::real::{Lanes, Real};

use super::kernel::{bond_vectors, vertex_kernel, Preconditioner, VertexResponse};
use super::{BondRest, Frame, RestData, Stencil, VertexConstants};

/// Rest data of whole packs of vertices (see the module documentation).
#[derive(Debug, Clone)]
pub struct PackedRest<S: Lanes> {
    /// Storage index of each pack's data, or [`SCALAR`] for a pack run vertex by vertex.
    stored: Vec<u32>,
    /// Slots of stored pack `s`: `slot_offsets[s]..slot_offsets[s + 1]`.
    slot_offsets: Vec<u32>,
    /// Per slot, `L` neighbour indices (lane-major within the slot).
    neighbors: Vec<u32>,
    bonds: Vec<BondRest<S>>,
    frames: Vec<Frame<S>>,
    constants: Vec<VertexConstants<S>>,
}

/// Marks a pack that runs on the scalar path.
const SCALAR: u32 = u32::MAX;

impl<S: Lanes> PackedRest<S> {
    /// Regroups `rest` (whose neighbourhood is `nb`) into packs.
    pub fn new(nb: &Neighborhood, rest: &RestData<S::Scalar>) -> Self {
        let lanes = S::LANES;
        let packs = rest.vertices.len() / lanes;
        let slots_of = |p: usize| {
            (0..lanes)
                .map(|l| nb.of(p * lanes + l).len())
                .max()
                .unwrap_or(0)
        };
        let all_slots: usize = (0..packs).map(slots_of).sum();
        let mut out = Self {
            stored: Vec::with_capacity(packs),
            slot_offsets: Vec::with_capacity(packs + 1),
            neighbors: Vec::with_capacity(all_slots * lanes),
            bonds: Vec::with_capacity(all_slots),
            frames: Vec::with_capacity(packs),
            constants: Vec::with_capacity(packs),
        };
        out.slot_offsets.push(0);
        for p in 0..packs {
            let first = p * lanes;
            let vertex = |l: usize| first + l;
            let Some(material) = pack_material::<S>(|l| rest.vertices[vertex(l)].material) else {
                out.stored.push(SCALAR);
                continue;
            };
            out.stored.push(out.frames.len() as u32);
            let slots = (0..lanes)
                .map(|l| nb.of(vertex(l)).len())
                .max()
                .unwrap_or(0);
            for k in 0..slots {
                for l in 0..lanes {
                    let own = nb.of(vertex(l));
                    out.neighbors
                        .push(own.get(k).copied().unwrap_or(vertex(l) as u32));
                }
                let bond = |l: usize| {
                    let range = nb.bonds(vertex(l));
                    (k < range.len()).then(|| rest.bonds[range.start + k])
                };
                let part = |f: fn(&BondRest<S::Scalar>) -> S::Scalar| {
                    S::gather(|l| bond(l).map_or_else(nalgebra::zero, |b| f(&b)))
                };
                out.bonds.push(BondRest {
                    beta: [part(|b| b.beta[0]), part(|b| b.beta[1])],
                    xi: Vector3::new(part(|b| b.xi.x), part(|b| b.xi.y), part(|b| b.xi.z)),
                    curvature: Vector3::new(
                        part(|b| b.curvature.x),
                        part(|b| b.curvature.y),
                        part(|b| b.curvature.z),
                    ),
                });
            }
            out.slot_offsets.push(out.bonds.len() as u32);
            let frame = |f: fn(&Frame<S::Scalar>) -> Vector3<S::Scalar>| {
                let v = |c: usize| S::gather(|l| f(&rest.frames[vertex(l)])[c]);
                Vector3::new(v(0), v(1), v(2))
            };
            out.frames.push(Frame {
                t1: frame(|f| f.t1),
                t2: frame(|f| f.t2),
                nc: frame(|f| f.nc),
            });
            let constant = |f: fn(&VertexConstants<S::Scalar>) -> S::Scalar| {
                S::gather(|l| f(&rest.vertices[vertex(l)]))
            };
            out.constants.push(VertexConstants {
                volume: constant(|c| c.volume),
                mass: constant(|c| c.mass),
                k_iso: constant(|c| c.k_iso),
                k_bound: constant(|c| c.k_bound),
                kappa_t: constant(|c| c.kappa_t),
                kappa_n: constant(|c| c.kappa_n),
                half_thickness: constant(|c| c.half_thickness),
                material,
            });
        }
        out.shrink_to_fit();
        out
    }

    /// Releases the capacity left by packs that run on the scalar path.
    fn shrink_to_fit(&mut self) {
        self.slot_offsets.shrink_to_fit();
        self.neighbors.shrink_to_fit();
        self.bonds.shrink_to_fit();
        self.frames.shrink_to_fit();
        self.constants.shrink_to_fit();
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
/// (CSR order of `nb`) and per-vertex responses into `response`. With `packed` (the same rest
/// data regrouped) whole packs of vertices run at once; the results are the same bit for bit,
/// and for any number of threads.
pub fn evaluate_vertices<T: Real>(
    nb: &Neighborhood,
    rest: &RestData<T>,
    packed: Option<&PackedRest<T::Pack>>,
    y: &[Vector3<T>],
    mode: Preconditioner,
    bond_grad: &mut [Vector3<T>],
    response: &mut [VertexResponse<T>],
) {
    let lanes = T::Pack::LANES;
    let align = if packed.is_some() { lanes } else { 1 };
    let slots = packed.map_or(0, PackedRest::max_slots);
    for_each_range(
        &nb.offsets,
        align,
        bond_grad,
        response,
        &|first, bonds, out| {
            let base = nb.offsets[first] as usize;
            let mut edges = Vec::with_capacity(slots);
            let mut k = 0;
            while k < out.len() {
                let i = first + k;
                let pack = packed.filter(|_| i % lanes == 0 && k + lanes <= out.len());
                let stored = pack.map_or(SCALAR, |p| p.stored[i / lanes]);
                if let (Some(p), true) = (pack, stored != SCALAR) {
                    let s = stored as usize;
                    let slot_range = p.slot_offsets[s] as usize..p.slot_offsets[s + 1] as usize;
                    let own = |c: usize| T::Pack::gather(|l| y[i + l][c]);
                    let yi = Vector3::new(own(0), own(1), own(2));
                    edges.clear();
                    for slot in slot_range.clone() {
                        let j = &p.neighbors[slot * lanes..(slot + 1) * lanes];
                        let at = |c: usize| T::Pack::gather(|l| y[j[l] as usize][c]);
                        edges.push(Vector3::new(at(0), at(1), at(2)) - yi);
                    }
                    let stencil = Stencil {
                        bonds: &p.bonds[slot_range],
                        frame: &p.frames[s],
                        constants: &p.constants[s],
                    };
                    let r = vertex_kernel(&stencil, mode, &mut edges);
                    for l in 0..lanes {
                        let range = nb.bonds(i + l);
                        let local = range.start - base..range.end - base;
                        for (slot, g) in bonds[local].iter_mut().enumerate() {
                            let e = &edges[slot];
                            *g = Vector3::new(e.x.extract(l), e.y.extract(l), e.z.extract(l));
                        }
                        out[k + l] = r.lane(l);
                    }
                    k += lanes;
                } else {
                    let range = nb.bonds(i);
                    let grads = &mut bonds[range.start - base..range.end - base];
                    bond_vectors(i, y, nb.of(i), grads);
                    out[k] = vertex_kernel(&rest.stencil(nb, i), mode, grads);
                    k += 1;
                }
            }
        },
    );
}

#[cfg(test)]
mod tests {
    use nalgebra::{Matrix3, Vector3};

    use super::*;
    use crate::material::Material;
    use crate::membrane::{Membrane, MembraneParams};
    use crate::mesh::TriangleMesh;

    /// A 9 x 7 grid (63 vertices: packs of 8 and 4 plus a scalar remainder; corner, edge and
    /// interior vertices have different bond counts) with 2-ring bonds, bending and hourglass,
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
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut noise = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        };
        let mut y: Vec<Vector3<f64>> = m
            .positions()
            .iter()
            .map(|p| {
                let bend = Vector3::new(p.x, p.y, 0.3 * (2.0 * p.x).sin() * p.y);
                bend + Vector3::new(noise(), noise(), noise()) * 0.02
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

    fn check<T: Real>(m: &Membrane, mode: Preconditioner) {
        let (nb, rest) = (m.neighborhood(), m.rest().to_real::<T>());
        let y: Vec<Vector3<T>> = m.positions().iter().map(|p| p.map(T::of)).collect();
        let zero = VertexResponse {
            stretch: T::zero(),
            bending: T::zero(),
            hourglass: T::zero(),
            precond: Matrix3::zeros(),
        };
        let run = |packed: Option<&PackedRest<T::Pack>>| {
            let mut grads = vec![Vector3::zeros(); nb.indices.len()];
            let mut out = vec![zero; y.len()];
            evaluate_vertices(nb, &rest, packed, &y, mode, &mut grads, &mut out);
            (grads, out)
        };
        let packed = PackedRest::new(nb, &rest);
        assert!(packed.stored.iter().all(|&s| s != SCALAR));
        let (scalar, simd) = (run(None), run(Some(&packed)));
        for (i, (a, b)) in scalar.1.iter().zip(&simd.1).enumerate() {
            assert!(
                a.energy().is_finite() && a.precond.iter().all(|x| x.is_finite()),
                "{} {i} {a:?}",
                T::NAME
            );
            assert_eq!(a, b, "{} vertex {i}", T::NAME);
        }
        for (k, (a, b)) in scalar.0.iter().zip(&simd.0).enumerate() {
            assert!(a.iter().all(|x| x.is_finite()));
            assert_eq!(a, b, "{} bond {k}", T::NAME);
        }
    }

    /// The SIMD packs give the scalar kernel's results bit for bit, for both precisions,
    /// materials and preconditioners, degenerate neighbourhoods included.
    #[test]
    fn packs_match_the_scalar_kernel_exactly() {
        for material in [
            Material::stretch_a3(3e4).unwrap(),
            Material::neo_hookean(1e4, 2e4).unwrap(),
        ] {
            let m = body(material);
            for mode in [Preconditioner::Tangent, Preconditioner::Paper] {
                check::<f32>(&m, mode);
                check::<f64>(&m, mode);
            }
        }
    }

    /// A pack whose lanes hold different material models runs on the scalar path.
    #[test]
    fn mixed_materials_fall_back_to_scalar() {
        let a3 = MaterialModel::StretchA3 { s0: 1.0f32 };
        let nh = MaterialModel::NeoHookean {
            s0: 1.0f32,
            s1: 2.0,
        };
        assert!(pack_material::<crate::real::F32Pack>(|_| a3).is_some());
        assert!(pack_material::<crate::real::F32Pack>(|l| if l == 5 { nh } else { a3 }).is_none());
    }
}
