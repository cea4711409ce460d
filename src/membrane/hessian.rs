//! The diagonal 3x3 blocks of the elastic energy's Hessian, `H_kk = d^2 U / dy_k^2` with
//! `U = sum_i E_i`: the Jacobi preconditioner of the descent baseline (Wang and Yang 2016 precondition
//! gradient descent with the diagonal of the Hessian of the variational energy, whose mass part
//! `m_k I` the solver adds; see `solve/descent.rs`).
//!
//! `E_i` depends on the bond vectors `e_j = y_j - y_i` of vertex `i`'s stencil, so
//!
//! `H_kk = d^2 E_k / dy_k^2 + sum_{i : k in N(i)} d^2 E_i / de_k^2`,
//! `d^2 E_k / dy_k^2 = sum_{j, l} d^2 E_k / de_j de_l`
//!
//! (the bond neighbourhoods are symmetric, so the vertices `i` whose stencil holds `k` are
//! `k`'s own neighbours, reached through [`Neighborhood::reverse`]).
//!
//! ## How the blocks are computed: central differences of the exact gradient
//!
//! The per-vertex blocks are central differences, in f64, of the kernel's exact bond gradients
//! ([`vertex_kernel`], itself tested against differences of the energy): column `a` of
//! `d^2 E_i / de_j^2` is `(g_j(e_j + delta u_a) - g_j(e_j - delta u_a)) / (2 delta)`, and of
//! `d^2 E_i / dy_i^2` the same with every bond moved by `-+ delta u_a` and `g = -sum_j g_j`.
//! The step is `delta = 1e-5` times the RMS rest bond length of vertex `i` (the cube root of
//! f64's epsilon, about where the truncation and round-off errors of a central difference of a
//! smooth function balance). The blocks are symmetrised. Analytic second derivatives of the
//! kernel (SVD of the 1-ring tangent map, director, bending and hourglass residuals) would be
//! exact and cheaper; the differences are the baseline's documented approximation, accurate to
//! about 1e-8 of the block where the energy is smooth.
//!
//! Cost: `6 (n_i + 1)` kernel evaluations per vertex with `n_i` bonds, run four at a time in
//! the lanes of an f64 SIMD pack: 11 pack evaluations per vertex of a 1-ring grid (n = 6), 29
//! of a 2-ring one (n = 18), against a quarter (f64) or an eighth (f32) of one for the
//! gradient pass, so a Hessian diagonal costs some 40-100 gradient evaluations. Only the descent
//! method pays it, once per accepted iteration; SISSM never calls this module.

use nalgebra::{Matrix3, SimdValue, Vector3};

use crate::material::MaterialModel;
use crate::mesh::Neighborhood;
use crate::parallel::for_each_vertex;
use crate::real::{F64Pack, Lanes};

use super::kernel::{bond_vectors, vertex_kernel, Preconditioner};
use super::{BondRest, Frame, RestData, Stencil, VertexConstants};

/// Central-difference step relative to the RMS rest bond length (see the module docs).
const RELATIVE_STEP: f64 = 1e-5;

/// Second derivatives of every vertex's own energy `E_i` at the positions `y` (m): for each
/// bond `b` of `i` (CSR order of `nb`), `d^2 E_i / de_b^2` into `bond_blocks[b]`, and
/// `d^2 E_i / dy_i^2` into `self_blocks[i]` (N/m).
pub fn vertex_hessian_blocks(
    nb: &Neighborhood,
    rest: &RestData<f64>,
    y: &[Vector3<f64>],
    bond_blocks: &mut [Matrix3<f64>],
    self_blocks: &mut [Matrix3<f64>],
) {
    for_each_vertex(&nb.offsets, bond_blocks, self_blocks, &|i, blocks| {
        let stencil = rest.stencil(nb, i);
        let n = blocks.len();
        let mut edges = vec![Vector3::zeros(); n];
        bond_vectors(i, y, nb.of(i), &mut edges);
        let rest_sq: f64 = stencil.bonds.iter().map(|b| b.xi.norm_squared()).sum();
        let delta = RELATIVE_STEP * (rest_sq / n.max(1) as f64).sqrt();
        let gradients = shifted_gradients(&stencil, &edges, delta);
        // Column `a` of the block of slot `s`: the difference of its two shifted gradients.
        let block = |s: usize| {
            let mut block = Matrix3::zeros();
            for a in 0..3 {
                let (plus, minus) = (gradients[6 * s + 2 * a], gradients[6 * s + 2 * a + 1]);
                block.set_column(a, &((plus - minus) / (2.0 * delta)));
            }
            (block + block.transpose()) * 0.5
        };
        for (j, out) in blocks.iter_mut().enumerate() {
            *out = block(j);
        }
        block(n)
    });
}

/// The shifted gradients of one vertex's energy, four shifts at a time in the lanes of an
/// [`F64Pack`] (every lane is bit-identical to the scalar kernel). Shift `p` moves slot
/// `s = p / 6` by `+-delta` (sign `p % 2`) along axis `(p % 6) / 2`; slot `s < n` is bond `s`,
/// whose gradient `g_s` is returned, and slot `n` moves every bond and returns `sum_j g_j`.
/// Moving `y_i` by `+u` moves every bond by `-u` and `dE_i/dy_i = -sum_j g_j`, so slot `n`'s
/// difference is `d^2 E_i / dy_i^2` with the same sign as the bonds'.
fn shifted_gradients(
    stencil: &Stencil<'_, f64>,
    edges: &[Vector3<f64>],
    delta: f64,
) -> Vec<Vector3<f64>> {
    let n = edges.len();
    let bonds: Vec<BondRest<F64Pack>> = stencil
        .bonds
        .iter()
        .map(|b| BondRest {
            beta: b.beta.map(F64Pack::splat),
            xi: b.xi.map(F64Pack::splat),
            curvature: b.curvature.map(F64Pack::splat),
        })
        .collect();
    let frame = Frame {
        t1: stencil.frame.t1.map(F64Pack::splat),
        t2: stencil.frame.t2.map(F64Pack::splat),
        nc: stencil.frame.nc.map(F64Pack::splat),
    };
    let c = stencil.constants;
    let constants = VertexConstants {
        volume: F64Pack::splat(c.volume),
        mass: F64Pack::splat(c.mass),
        k_iso: F64Pack::splat(c.k_iso),
        k_bound: F64Pack::splat(c.k_bound),
        kappa_t: F64Pack::splat(c.kappa_t),
        kappa_n: F64Pack::splat(c.kappa_n),
        half_thickness: F64Pack::splat(c.half_thickness),
        material: match c.material {
            MaterialModel::StretchA3 { s0 } => MaterialModel::StretchA3 {
                s0: F64Pack::splat(s0),
            },
            MaterialModel::NeoHookean { s0, s1 } => MaterialModel::NeoHookean {
                s0: F64Pack::splat(s0),
                s1: F64Pack::splat(s1),
            },
        },
    };
    let packed = Stencil {
        bonds: &bonds,
        frame: &frame,
        constants: &constants,
    };
    let count = 6 * (n + 1);
    let shift = |p: usize| {
        let sign = if p % 2 == 0 { delta } else { -delta };
        (p / 6, Vector3::ith((p % 6) / 2, sign))
    };
    let mut out = vec![Vector3::zeros(); count];
    let mut trial = vec![Vector3::<F64Pack>::zeros(); n];
    for first in (0..count).step_by(F64Pack::LANES) {
        // Spare lanes of the last pack repeat its last shift.
        let lane_shift = |l: usize| shift((first + l).min(count - 1));
        for (j, t) in trial.iter_mut().enumerate() {
            let component = |a: usize| {
                F64Pack::gather(|l| {
                    let (s, step) = lane_shift(l);
                    edges[j][a] + if s == j || s == n { step[a] } else { 0.0 }
                })
            };
            *t = Vector3::new(component(0), component(1), component(2));
        }
        vertex_kernel(&packed, Preconditioner::Tangent, &mut trial);
        for (l, slot) in out[first..].iter_mut().take(F64Pack::LANES).enumerate() {
            let lane =
                |v: &Vector3<F64Pack>| Vector3::new(v.x.extract(l), v.y.extract(l), v.z.extract(l));
            let (s, _) = lane_shift(l);
            *slot = if s < n {
                lane(&trial[s])
            } else {
                trial.iter().map(lane).sum()
            };
        }
    }
    out
}

/// `H_kk` (N/m) of the elastic energy from the blocks of [`vertex_hessian_blocks`]: vertex
/// `k`'s own block plus, for each neighbour `i`, the block of `E_i` for its bond to `k`.
#[inline]
pub fn hessian_diagonal_block(
    k: usize,
    nb: &Neighborhood,
    bond_blocks: &[Matrix3<f64>],
    self_blocks: &[Matrix3<f64>],
) -> Matrix3<f64> {
    nb.bonds(k)
        .map(|b| bond_blocks[nb.reverse[b] as usize])
        .fold(self_blocks[k], |sum, block| sum + block)
}

#[cfg(test)]
mod tests {
    use nalgebra::{Matrix3, Rotation3, Vector3};

    use super::{hessian_diagonal_block, vertex_hessian_blocks, RestData};
    use crate::material::Material;
    use crate::membrane::{Membrane, MembraneParams};
    use crate::mesh::TriangleMesh;
    use crate::test_rng::Rng;

    /// `H_kk` assembled from the per-vertex blocks equals the central difference of the total
    /// elastic force at vertex `k` (`-d f_k / dy_k`, the force being the exactly tested
    /// gradient of the energy) for every vertex of a randomly deformed 6 x 5 sheet, both
    /// materials, stretched and compressed, 1-ring and 2-ring, with bending and hourglass:
    /// within 1e-8 of the largest block entry. The reference differences the whole mesh, so
    /// it also checks the assembly (which stencils hold `k`, the sign of `y_k` in each bond).
    #[test]
    fn diagonal_blocks_match_differences_of_the_force() {
        let mut noise = Rng::new(0x5eed);
        for material in [
            Material::stretch_a3(5e3).unwrap(),
            Material::neo_hookean(2e3, 3e3).unwrap(),
        ] {
            for (scale, neighbors) in [(1.15, 1), (0.9, 1), (1.05, 2)] {
                let params = MembraneParams {
                    thickness: 2e-3,
                    density: 300.0,
                    material,
                    bending: 1e-3,
                    hourglass: 0.5,
                    neighbors,
                };
                let mesh = TriangleMesh::grid(6, 5, 0.4, 0.3).unwrap();
                let mut m = Membrane::new(mesh, params).unwrap();
                let rot = Rotation3::from_scaled_axis(Vector3::new(0.3, -0.2, 0.5));
                let y0: Vec<Vector3<f64>> = m
                    .positions()
                    .iter()
                    .map(|x| rot * (x * scale) + noise.vector() * 0.01)
                    .collect();
                m.set_positions(y0.clone()).unwrap();
                let nb = m.neighborhood().clone();
                let mut bond_blocks = vec![Matrix3::zeros(); nb.indices.len()];
                let mut self_blocks = vec![Matrix3::zeros(); y0.len()];
                let mut rest = RestData::empty();
                rest.extend_from(&m.rest_source().unwrap(), true).unwrap();
                vertex_hessian_blocks(&nb, &rest, &y0, &mut bond_blocks, &mut self_blocks);
                let blocks: Vec<Matrix3<f64>> = (0..y0.len())
                    .map(|k| hessian_diagonal_block(k, &nb, &bond_blocks, &self_blocks))
                    .collect();
                let largest = blocks.iter().map(|b| b.abs().max()).fold(0.0, f64::max);
                let eps = 1e-7;
                for (k, block) in blocks.iter().enumerate() {
                    let mut reference = Matrix3::zeros();
                    for a in 0..3 {
                        let force_at = |s: f64, m: &mut Membrane| {
                            let mut y = y0.clone();
                            y[k][a] += s;
                            m.set_positions(y).unwrap();
                            m.internal_forces().unwrap()[k]
                        };
                        let column = (force_at(-eps, &mut m) - force_at(eps, &mut m)) / (2.0 * eps);
                        reference.set_column(a, &column);
                    }
                    let error = (block - reference).abs().max();
                    assert!(
                        error <= 1e-8 * largest,
                        "{material:?} scale {scale} {neighbors}-ring vertex {k}: error {error:e} \
                         of {largest:e}\n{block}\n{reference}"
                    );
                }
            }
        }
    }
}
