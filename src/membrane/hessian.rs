//! The diagonal 3x3 blocks of the elastic energy's Hessian, `H_kk = d^2 U / dy_k^2` with
//! `U = sum_i E_i`: the Jacobi preconditioner of the descent baseline (Wang and Yang 2016,
//! section 4: "Jacobi preconditioning" with the diagonal of the Hessian of the variational
//! energy, whose mass part `m_k I` the solver adds).
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
//! Cost: `6 (n_i + 1)` scalar kernel evaluations per vertex with `n_i` bonds, i.e. about 40
//! (1-ring) to 110 (2-ring) times one gradient evaluation of the SIMD pass. Only the descent
//! method pays it, once per accepted iteration; SISSM never calls this module.

use nalgebra::{Matrix3, Vector3};

use crate::mesh::Neighborhood;
use crate::parallel::for_each_vertex;

use super::kernel::{bond_vectors, vertex_kernel, Preconditioner};
use super::RestData;

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
        let mut trial = vec![Vector3::zeros(); n];
        // The bond gradients of E_i (left in `trial`) with bond `j` moved by `step`, or every
        // bond when `j` is `None`.
        let mut gradient = |j: Option<usize>, step: Vector3<f64>| {
            trial.copy_from_slice(&edges);
            match j {
                Some(j) => trial[j] += step,
                None => trial.iter_mut().for_each(|e| *e += step),
            }
            vertex_kernel(&stencil, Preconditioner::Tangent, &mut trial);
            match j {
                Some(j) => trial[j],
                None => trial.iter().sum(),
            }
        };
        for (j, block) in blocks.iter_mut().enumerate() {
            for a in 0..3 {
                let step = Vector3::ith(a, delta);
                let difference = gradient(Some(j), step) - gradient(Some(j), -step);
                block.set_column(a, &(difference / (2.0 * delta)));
            }
            *block = (*block + block.transpose()) * 0.5;
        }
        // Moving y_i by +step moves every bond by -step, and dE_i/dy_i = -sum_j g_j.
        let mut own = Matrix3::zeros();
        for a in 0..3 {
            let step = Vector3::ith(a, delta);
            let difference = gradient(None, step) - gradient(None, -step);
            own.set_column(a, &(difference / (2.0 * delta)));
        }
        (own + own.transpose()) * 0.5
    });
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

    use super::{hessian_diagonal_block, vertex_hessian_blocks};
    use crate::material::Material;
    use crate::membrane::{Membrane, MembraneParams};
    use crate::mesh::TriangleMesh;
    use crate::test_rng::Rng;

    /// `H_kk` assembled from the per-vertex blocks equals the central difference of the total
    /// elastic force at vertex `k` (`-d f_k / dy_k`, the force being the exactly tested
    /// gradient of the energy) for every vertex of a randomly deformed 6 x 5 sheet, both
    /// materials, stretched and compressed, 1-ring and 2-ring, with bending and hourglass:
    /// within 1e-8 of the largest block entry (measured: 2e-11). The reference differences the whole mesh, so
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
                vertex_hessian_blocks(&nb, m.rest(), &y0, &mut bond_blocks, &mut self_blocks);
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
                            m.internal_forces()[k]
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
