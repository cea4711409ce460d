//! The surface correction of calibrated particle bodies (beyond the paper): the bonds near a
//! free surface are stiffened, by direction, so that a particle there stores the bulk's energy
//! density under a stretch along the surface.
//!
//! Under a small affine strain a particle's pair springs store `c sum_j V_j w_j (n_j . eps
//! n_j)^2` per unit volume ([`super::calibration`]): under a uniaxial strain `e` along the axis
//! `a`, `c S^i_aaaa e^2` with the particle's own axial moment `S^i_aaaa = sum_j V_j w_j
//! n_ja^4` over the bonds it has. A particle on a free face misses the bonds that point out of
//! the body, mostly ones across the face: on a flat face normal to `z` of the default lattice
//! (horizon 2.2 spacings) it keeps 0.70 of the bulk's weight sum `A`, 0.87 of `S_xxxx` and
//! half of `S_zzzz`; on an edge along `x`, 0.49 of `A` and 0.77 of `S_xxxx`. A single factor
//! per particle (such as `A / A_i`) cannot make up for both: scaled to the weight sum, a face
//! is 1.25 times too stiff along itself and an edge 1.59 times, so a bar four particles across
//! was 1.31 times too stiff in stretch.
//!
//! Here particle `i` gets one factor per lattice axis, `g_ia = S_aaaa / S^i_aaaa` (the bulk's
//! axial moment over its own), and a bond `i -> j` along the unit vector `n` the factor
//! `G(n) = (sum_a n_a^2 / G_a^2)^(-1/2)` with `G_a = (g_ia + g_ja) / 2`: the axis factor for a
//! bond along an axis, an ellipsoidal blend between them (the energy method of Madenci and
//! Oterkus, Peridynamic Theory and Its Applications, 2014, section 4.2; Le and Bobaru 2018
//! compare such corrections). The mean over the bond's two particles keeps the springs
//! symmetric (the same factor for `i -> j` and `j -> i`), so forces balance and the isotropic
//! force stays an exact gradient. In the interior every factor is 1. The axes are the
//! sampling lattice's, taken as the coordinate axes ([`super::sampling`] samples on them).
//!
//! The dilatation term ([`super::bond`]) stores `9 kappa V_i / 2 s_i^2` with the particle's
//! mean bond strain `s_i = sum_j a_j (|Y_j| - |xi_j|)`: in the bulk the shares
//! `a_j = w V_j / (A_i |xi_j|)` make `s_i = tr eps / 3` under a small affine strain, but on a
//! face they lean towards the bonds along it (under a uniaxial stress along a face at
//! nu = 0.4, `s_i` is 1.8 times the bulk's, its energy 3 times). So [`strain_shares`] corrects
//! them, `a_j = a0_j (1 + n_j . L n_j)` with the symmetric `L` (6 unknowns) that makes
//! `sum_j a_j |xi_j| n_j n_j^T = I / 3`: then `s_i = tr eps / 3` for every small affine strain,
//! at every particle (`L = 0` in the interior).

use nalgebra::{Matrix6, Vector3, Vector6};

/// Largest axis factor: a particle of a convex lattice body keeps at least the moment of a
/// cube's corner (factor 2.6 on the default lattice); only a plastic particle that has lost
/// most of its bonds along an axis reaches this bound, which keeps its springs finite.
pub const MAX_AXIS_FACTOR: f64 = 4.0;

/// Per particle its axis factors `g_ia` (see the module's doc): `bulk_moment` is the bulk
/// lattice's `S_1111`; `bonds(i)` yields particle `i`'s bonds as (vector `xi`, m; weight
/// `w V_j`, dimensionless).
pub fn axis_factors<I>(
    particles: usize,
    bulk_moment: f64,
    bonds: impl Fn(usize) -> I,
) -> Vec<Vector3<f64>>
where
    I: Iterator<Item = (Vector3<f64>, f64)>,
{
    (0..particles)
        .map(|i| {
            let mut moment = Vector3::<f64>::zeros();
            for (xi, weight) in bonds(i) {
                let n2 = xi.component_mul(&xi) / xi.norm_squared();
                moment += n2.component_mul(&n2) * weight;
            }
            moment.map(|s| {
                if s > 0.0 {
                    (bulk_moment / s).min(MAX_AXIS_FACTOR)
                } else {
                    MAX_AXIS_FACTOR
                }
            })
        })
        .collect()
}

/// The shares `a_j` (1/m) of a particle's mean bond strain over its bonds (vector `xi_j`, m;
/// weight `w V_j`), into `out`: `a0_j = w V_j / (A_i |xi_j|)` corrected so that
/// `sum_j a_j |xi_j| n_j n_j^T = I / 3` (see the module's doc); `a0` where the correction's
/// 6 x 6 system is singular.
pub fn strain_shares(bonds: &[(Vector3<f64>, f64)], out: &mut Vec<f64>) {
    let total: f64 = bonds.iter().map(|(_, w)| w).sum();
    // `u(n)`: the six components of `n n^T`; `v(n)`: those of `L` in `n . L n = v . l`.
    let parts = |xi: &Vector3<f64>| {
        let n = xi / xi.norm();
        let u = Vector6::new(
            n.x * n.x,
            n.y * n.y,
            n.z * n.z,
            n.x * n.y,
            n.x * n.z,
            n.y * n.z,
        );
        let v = Vector6::new(u[0], u[1], u[2], 2.0 * u[3], 2.0 * u[4], 2.0 * u[5]);
        (u, v)
    };
    let mut system = Matrix6::<f64>::zeros();
    let mut rhs = Vector6::new(1.0, 1.0, 1.0, 0.0, 0.0, 0.0) / 3.0;
    for (xi, w) in bonds {
        let (u, v) = parts(xi);
        let p = w / total;
        system += u * v.transpose() * p;
        rhs -= u * p;
    }
    let l = system.lu().solve(&rhs).unwrap_or_else(Vector6::zeros);
    out.clear();
    out.extend(bonds.iter().map(|(xi, w)| {
        let (_, v) = parts(xi);
        w / (total * xi.norm()) * (1.0 + v.dot(&l))
    }));
}

/// The factor of a bond along `xi` between particles with the axis factors `a` and `b`:
/// `(sum_k n_k^2 / G_k^2)^(-1/2)` with `G = (a + b) / 2` (see the module's doc).
pub fn bond_factor(xi: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    let g = (a + b) * 0.5;
    let n2 = xi.component_mul(xi) / xi.norm_squared();
    let sum = n2.x / (g.x * g.x) + n2.y / (g.y * g.y) + n2.z / (g.z * g.z);
    1.0 / sum.sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::calibration::lattice_moduli;
    use crate::particles::influence::influence;

    /// The lattice vectors of the default horizon (2.2 spacings, spacing 1) with `w V`.
    fn lattice_bonds() -> Vec<(Vector3<f64>, f64)> {
        let mut bonds = Vec::new();
        for a in -2i32..=2 {
            for b in -2i32..=2 {
                for c in -2i32..=2 {
                    let xi = Vector3::new(a, b, c).map(f64::from);
                    if xi.norm() > 0.0 && xi.norm() < 2.2 {
                        bonds.push((xi, influence(xi.norm(), 2.2)));
                    }
                }
            }
        }
        bonds
    }

    /// An interior particle gets 1 along every axis; one on a face normal to `z` gets 2 across
    /// it (it keeps half of `S_zzzz`) and, along the face, the bulk's `S_xxxx` over its own
    /// (1e-12); every bond of two interior particles keeps its spring (factor 1), and a bond
    /// along an axis gets that axis's mean factor.
    #[test]
    fn factors_make_up_the_missing_axial_moment() {
        let bulk = lattice_moduli(1.0, 2.2).unwrap().s1111;
        let all = lattice_bonds();
        let face: Vec<_> = all.iter().copied().filter(|(xi, _)| xi.z <= 0.0).collect();
        let g = axis_factors(2, bulk, |i| {
            if i == 0 { all.clone() } else { face.clone() }.into_iter()
        });
        assert!((g[0] - Vector3::repeat(1.0)).norm() < 1e-12, "{}", g[0]);
        let own: f64 = face
            .iter()
            .map(|(xi, w)| w * (xi.x / xi.norm()).powi(4))
            .sum();
        assert!((g[1].x - bulk / own).abs() < 1e-12 && (g[1].x - g[1].y).abs() < 1e-12);
        assert!((g[1].z - 2.0).abs() < 1e-12, "{}", g[1]);
        let diagonal = Vector3::new(1.0, -1.0, 1.0);
        assert!((bond_factor(&diagonal, &g[0], &g[0]) - 1.0).abs() < 1e-12);
        let along_z = Vector3::new(0.0, 0.0, -2.0);
        assert!((bond_factor(&along_z, &g[0], &g[1]) - 1.5).abs() < 1e-12);
    }

    /// The corrected shares give every small affine strain its mean `tr eps / 3` (1e-12) on
    /// a face and an edge, and leave the interior's (`w V_j / (A |xi_j|)`) as they are.
    #[test]
    fn corrected_shares_measure_a_third_of_the_trace() {
        let all = lattice_bonds();
        let face: Vec<_> = all.iter().copied().filter(|(xi, _)| xi.z <= 0.0).collect();
        let edge: Vec<_> = face.iter().copied().filter(|(xi, _)| xi.y <= 0.0).collect();
        let eps = nalgebra::Matrix3::new(1.0, 0.3, -0.2, 0.3, -0.4, 0.1, -0.2, 0.1, 0.7);
        let mut shares = Vec::new();
        for bonds in [&all, &face, &edge] {
            strain_shares(bonds, &mut shares);
            let s: f64 = bonds
                .iter()
                .zip(&shares)
                .map(|((xi, _), a)| a * xi.dot(&(eps * xi)) / xi.norm())
                .sum();
            assert!((s - eps.trace() / 3.0).abs() < 1e-12, "{s}");
        }
        strain_shares(&all, &mut shares);
        let total: f64 = all.iter().map(|(_, w)| w).sum();
        for ((xi, w), a) in all.iter().zip(&shares) {
            assert!((a - w / (total * xi.norm())).abs() < 1e-12);
        }
    }

    /// Each factor lies between the least and the largest axis factor of its two particles.
    #[test]
    fn a_bond_factor_blends_its_axes() {
        let (a, b) = (Vector3::new(1.0, 1.3, 2.0), Vector3::new(1.0, 1.0, 1.2));
        for (xi, _) in lattice_bonds() {
            let f = bond_factor(&xi, &a, &b);
            assert!((1.0 - 1e-12..=1.6 + 1e-12).contains(&f), "{xi} {f}");
        }
    }
}
