//! The deformation gradient of a particle (He et al. 2017, section 3) and the treatment of
//! inverted neighbourhoods.

use nalgebra::{Matrix3, Vector3};

use crate::real::Real;

use super::bond::BondRest;

/// `F_i = (sum_j w V_j Y xi^T) K_i^-1` with `Y = y_j - y_i`: the rest data of particle `i`'s
/// bonds (their `xi`, m, and weights `w V_j`, dimensionless), its neighbours `j`, the
/// positions `y` (m) and the inverse shape matrix `K_i^-1` (1/m^2), inversions turned back
/// ([`uninverted`]).
#[inline]
pub fn deformation_gradient<T: Real>(
    i: usize,
    neighbors: &[u32],
    bonds: &[BondRest<T>],
    shape_inverse: &Matrix3<T>,
    y: &[Vector3<T>],
) -> Matrix3<T> {
    let mut sum = Matrix3::zeros();
    for (&j, bond) in neighbors.iter().zip(bonds) {
        let d = (y[j as usize] - y[i]) * bond.weight;
        sum += d * bond.xi.transpose();
    }
    uninverted(sum * shape_inverse)
}

/// `F` with an inverted neighbourhood turned back (Irving et al. 2004): where `det F < 0`,
/// the smallest singular value, negative in a rotation-only SVD `F = U diag(s) V^T`
/// (`det U = det V = 1`), is made positive: `F' = F - 2 s_min u v^T` with `u`, `v` the
/// singular vectors of the smallest singular value of the plain SVD. Then `det F' = -det F`
/// and the deviatoric projections `dir(F' xi)` push the neighbourhood back towards its
/// orientation at rest. (The paper swaps the first two rows of `F`, which changes the
/// deformation it describes whatever the inversion looks like.)
#[inline]
pub fn uninverted<T: Real>(f: Matrix3<T>) -> Matrix3<T> {
    if f.determinant() >= T::zero() {
        return f;
    }
    let svd = f.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return f;
    };
    let k = svd.singular_values.imin();
    let s = svd.singular_values[k];
    f - u.column(k) * v_t.row(k) * (s + s)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A mirror image (`det F = -1`) comes back as a proper rotation-stretch: `F'` has the
    /// singular values of `F` and a positive determinant.
    #[test]
    fn an_inverted_gradient_gets_a_positive_determinant_and_keeps_its_stretches() {
        let f = Matrix3::new(1.2, 0.1, 0.0, -0.05, 0.9, 0.2, 0.0, 0.1, -0.5f64);
        assert!(f.determinant() < 0.0);
        let g = uninverted(f);
        assert!((g.determinant() + f.determinant()).abs() < 1e-12);
        let (a, b) = (f.singular_values(), g.singular_values());
        let (mut a, mut b) = (a.as_slice().to_vec(), b.as_slice().to_vec());
        a.sort_by(f64::total_cmp);
        b.sort_by(f64::total_cmp);
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() < 1e-12, "{a:?} {b:?}");
        }
        let r = Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0f64);
        assert_eq!(uninverted(r), r, "a proper gradient is left alone");
    }
}
