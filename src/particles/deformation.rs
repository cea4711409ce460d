//! The deformation gradient of a particle (He et al. 2017, section 3) and the treatment of
//! inverted neighbourhoods.

use nalgebra::{Matrix3, SimdValue, Vector3};

use crate::error::Result;
use crate::geometry::Horizons;
use crate::real::{Lanes, Real};

use super::bond::BondRest;
use super::influence::influence;

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
    deformation_and_strain(i, neighbors, bonds, shape_inverse, y, |_, _| {}).0
}

/// [`deformation_gradient`] and, from the same pass over the bonds (each neighbour's position
/// read once), particle `i`'s weighted mean bond strain `s_i = sum_j a_j (|Y_j| - |xi_j|)`
/// (dimensionless; `a_j` the bonds' `share`, see [`super::bond`]); `keep(k, Y)` receives the
/// `k`-th bond's vector `Y = y_j - y_i` (m), for a caller that needs it again.
///
/// The bonds go [`Lanes`] at a time: their lengths `|Y|` are taken in one SIMD pack (one square
/// root instruction for eight `f32` bonds), the sums stay in the bonds' order, so the result
/// is bit for bit that of one bond at a time.
#[inline(always)]
pub fn deformation_and_strain<T: Real>(
    i: usize,
    neighbors: &[u32],
    bonds: &[BondRest<T>],
    shape_inverse: &Matrix3<T>,
    y: &[Vector3<T>],
    mut keep: impl FnMut(usize, Vector3<T>),
) -> (Matrix3<T>, T) {
    let (mut sum, mut strain) = (Matrix3::zeros(), T::zero());
    let y_i = y[i];
    let lanes = <T::Pack as SimdValue>::LANES;
    const {
        assert!(
            <T::Pack as SimdValue>::LANES <= 8,
            "a pack holds at most eight bonds"
        )
    };
    // One pack's bond vectors by component.
    let mut pack = [[T::zero(); 8]; 3];
    let mut k = 0;
    for (js, group) in neighbors.chunks(lanes).zip(bonds.chunks(lanes)) {
        for (l, (&j, bond)) in js.iter().zip(group).enumerate() {
            let d = y[j as usize] - y_i;
            sum += (d * bond.weight) * bond.xi.transpose();
            keep(k + l, d);
            for (c, component) in pack.iter_mut().enumerate() {
                component[l] = d[c];
            }
        }
        if group.len() == lanes {
            let component = |c: usize| T::Pack::gather(|l| pack[c][l]);
            let norm = Vector3::new(component(0), component(1), component(2)).norm();
            for (l, bond) in group.iter().enumerate() {
                strain += bond.share * (norm.extract(l) - bond.length);
            }
        } else {
            for (l, bond) in group.iter().enumerate() {
                let d = Vector3::new(pack[0][l], pack[1][l], pack[2][l]);
                strain += bond.share * (d.norm() - bond.length);
            }
        }
        k += group.len();
    }
    (uninverted(sum * shape_inverse), strain)
}

/// `F` with an inverted neighbourhood turned back (Irving et al. 2004): where `det F < 0`,
/// the smallest singular value, negative in a rotation-only SVD `F = U diag(s) V^T`
/// (`det U = det V = 1`), is made positive: `F' = F - 2 s_min u v^T` with `u`, `v` the
/// singular vectors of the smallest singular value of the plain SVD. Then `det F' = -det F`
/// and the deviatoric projections `dir(F' xi)` push the neighbourhood back towards its
/// orientation at rest. (The paper swaps the first two rows of `F`, which changes the
/// deformation it describes whatever the inversion looks like.)
#[inline(always)]
pub fn uninverted<T: Real>(f: Matrix3<T>) -> Matrix3<T> {
    if f.determinant() >= T::zero() {
        return f;
    }
    turned_back(f)
}

/// [`uninverted`] of an inverted `f` (`det f < 0`): the rare case, kept out of the kernel's
/// loop.
#[cold]
#[inline(never)]
fn turned_back<T: Real>(f: Matrix3<T>) -> Matrix3<T> {
    let svd = f.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return f;
    };
    let k = svd.singular_values.imin();
    let s = svd.singular_values[k];
    f - u.column(k) * v_t.row(k) * (s + s)
}

/// `K^-1` (1/m^2) for a shape matrix `K` (m^2) that is safely invertible: its determinant
/// above `1e-6` times that of the isotropic matrix of the same trace (so a flat or linear
/// neighbourhood, whose `K` is singular up to round-off, is refused).
pub fn shape_inverse(k: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let scale = k.trace() / 3.0;
    // NaN scales are refused too: `partial_cmp` is `None` for them.
    if scale.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
        || k.determinant() <= 1e-6 * scale * scale * scale
    {
        return None;
    }
    k.try_inverse()
}

/// The error for particle `i`, with `count` neighbours within the horizon `delta` (m), whose
/// shape matrix is singular.
pub fn flat_neighbourhood(i: usize, count: usize, delta: f64) -> crate::error::Error {
    crate::error::invalid!(
        "particle {i} has no three-dimensional neighbourhood ({count} neighbours within the \
         horizon {delta} m): its shape matrix is singular; sample the body more densely or \
         widen the horizon"
    )
}

/// Checks that every particle of the reference positions `x` (m) with the `horizons` of
/// radius `delta` (m) has an invertible shape matrix `K_i` (any positive weights give the
/// same answer: `K_i` is singular exactly when the neighbours' bonds span less than 3D);
/// fails naming the first that has not, or the first two particles at the same position (a
/// bond of length 0 has no direction, and its influence `1 / |xi|` no value).
pub fn check_shapes(x: &[Vector3<f64>], horizons: &Horizons, delta: f64) -> Result<()> {
    for i in 0..x.len() {
        let mut shape = Matrix3::<f64>::zeros();
        for &j in horizons.of(i) {
            let xi = x[j as usize] - x[i];
            if xi == Vector3::zeros() {
                return Err(crate::error::invalid!(
                    "particles {i} and {j} are at the same position {:?}: a bond needs two \
                     distinct ends",
                    x[i].as_slice()
                ));
            }
            shape += xi * xi.transpose() * influence(xi.norm(), delta);
        }
        if shape_inverse(&shape).is_none() {
            return Err(flat_neighbourhood(i, horizons.of(i).len(), delta));
        }
    }
    Ok(())
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
