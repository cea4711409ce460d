//! Symmetric 3x3 matrices stored as their six distinct entries: the SISSM preconditioner
//! blocks `C_i` and the per-vertex systems `D_k = m_k I + h^2 (n_k C_k + sum_j C_j)` (N/m, kg).
//!
//! Every operation but the inverse performs, entry for entry, the IEEE operations nalgebra
//! performs on the full `Matrix3` of an exactly symmetric matrix, in the same order, so the
//! results are the same bit for bit (up to the sign of a zero); only the redundant lower
//! triangle is neither stored nor computed. The inverse multiplies by one reciprocal of the
//! determinant where nalgebra divides six times, and agrees with it to a rounding or two.

use std::ops::{Add, AddAssign, Mul};

use nalgebra::{Matrix3, Vector3};

use crate::real::{Lanes, Real};

/// A symmetric 3x3 matrix `A` (of scalars, or of SIMD packs: one matrix per lane).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SymmetricMatrix3<S> {
    /// `(A_00, A_11, A_22)`.
    pub diagonal: [S; 3],
    /// `(A_01, A_02, A_12)`.
    pub upper: [S; 3],
}

impl<S: Copy> SymmetricMatrix3<S> {
    /// The matrix of `f` of each entry (a change of precision).
    #[inline]
    pub fn map<U>(&self, f: impl Fn(S) -> U) -> SymmetricMatrix3<U> {
        SymmetricMatrix3 {
            diagonal: self.diagonal.map(&f),
            upper: self.upper.map(&f),
        }
    }
}

impl<S: Lanes> SymmetricMatrix3<S> {
    pub fn zeros() -> Self {
        Self {
            diagonal: [S::zero(); 3],
            upper: [S::zero(); 3],
        }
    }

    /// `diag(d)`.
    #[inline]
    pub fn from_diagonal(d: &Vector3<S>) -> Self {
        Self {
            diagonal: [d.x, d.y, d.z],
            upper: [S::zero(); 3],
        }
    }

    /// `w u u^T`, entry `(u_a u_b) w`.
    #[inline(always)]
    pub fn outer(u: &Vector3<S>, w: S) -> Self {
        Self {
            diagonal: [u.x * u.x * w, u.y * u.y * w, u.z * u.z * w],
            upper: [u.x * u.y * w, u.x * u.z * w, u.y * u.z * w],
        }
    }

    /// `a I + A`.
    #[inline(always)]
    pub fn plus_identity(&self, a: S) -> Self {
        let [d0, d1, d2] = self.diagonal;
        Self {
            diagonal: [a + d0, a + d1, a + d2],
            upper: self.upper,
        }
    }

    /// `A v`, each entry summed over the columns in order (as nalgebra's product).
    #[inline(always)]
    pub fn mul_vector(&self, v: &Vector3<S>) -> Vector3<S> {
        let [a00, a11, a22] = self.diagonal;
        let [a01, a02, a12] = self.upper;
        Vector3::new(
            a00 * v.x + a01 * v.y + a02 * v.z,
            a01 * v.x + a11 * v.y + a12 * v.z,
            a02 * v.x + a12 * v.y + a22 * v.z,
        )
    }

    /// Entry `e` of `(a00, a11, a22, a01, a02, a12)`.
    #[inline(always)]
    pub fn entry(&self, e: usize) -> S {
        if e < 3 {
            self.diagonal[e]
        } else {
            self.upper[e - 3]
        }
    }

    /// The full matrix.
    pub fn to_matrix(&self) -> Matrix3<S> {
        let [a00, a11, a22] = self.diagonal;
        let [a01, a02, a12] = self.upper;
        Matrix3::new(a00, a01, a02, a01, a11, a12, a02, a12, a22)
    }
}

impl<S: Lanes> SymmetricMatrix3<S> {
    /// The adjugate (transposed cofactors) and the determinant, from the products nalgebra's
    /// `Matrix3::try_inverse` forms on the full matrix (its lower-triangle cofactors are the
    /// negated or equal differences of the same products, so the adjugate is exactly
    /// symmetric).
    #[inline(always)]
    fn adjugate(&self) -> (Self, S) {
        let [a00, a11, a22] = self.diagonal;
        let [a01, a02, a12] = self.upper;
        let c00 = a11 * a22 - a12 * a12;
        let c01 = a01 * a22 - a02 * a12;
        let c02 = a01 * a12 - a02 * a11;
        let det = a00 * c00 - a01 * c01 + a02 * c02;
        let adjugate = Self {
            diagonal: [c00, a00 * a22 - a02 * a02, a00 * a11 - a01 * a01],
            upper: [a02 * a12 - a22 * a01, c02, a02 * a01 - a12 * a00],
        };
        (adjugate, det)
    }

    /// `A^-1 = adj(A) / det A` lane by lane, or `fallback I` in the lanes where `det A` is
    /// exactly zero or its reciprocal overflows (a NaN determinant keeps its NaN inverse).
    #[inline(always)]
    pub fn inverse_or(&self, fallback: S) -> Self {
        let (adjugate, det) = self.adjugate();
        let inv_det = S::one() / det;
        let invertible = det.simd_ne(S::zero()) & inv_det.simd_abs().simd_ne(S::lit(f64::INFINITY));
        let inverse = adjugate * inv_det;
        let pick = |a: S, b: S| a.select(invertible, b);
        Self {
            diagonal: [
                pick(inverse.diagonal[0], fallback),
                pick(inverse.diagonal[1], fallback),
                pick(inverse.diagonal[2], fallback),
            ],
            upper: inverse.upper.map(|u| pick(u, S::zero())),
        }
    }
}

impl<T: Real> SymmetricMatrix3<T> {
    /// `A^-1 = adj(A) / det A` by cofactors (one division, then products), or `None` when
    /// `det A` is exactly zero or its reciprocal overflows (the caller chooses the fallback).
    /// Within a rounding or two of nalgebra's `Matrix3::try_inverse`, which divides every
    /// cofactor by the determinant.
    #[inline(always)]
    pub fn try_inverse(&self) -> Option<Self> {
        let (adjugate, det) = self.adjugate();
        let inv_det = T::one() / det;
        (det != T::zero() && inv_det.abs() != T::of(f64::INFINITY)).then(|| adjugate * inv_det)
    }
}

impl<S: Lanes> Add for SymmetricMatrix3<S> {
    type Output = Self;

    #[inline(always)]
    fn add(mut self, rhs: Self) -> Self {
        self += rhs;
        self
    }
}

impl<S: Lanes> AddAssign for SymmetricMatrix3<S> {
    #[inline(always)]
    fn add_assign(&mut self, rhs: Self) {
        for k in 0..3 {
            self.diagonal[k] += rhs.diagonal[k];
            self.upper[k] += rhs.upper[k];
        }
    }
}

impl<S: Lanes> Mul<S> for SymmetricMatrix3<S> {
    type Output = Self;

    /// Entry-wise `A_ab s`.
    #[inline(always)]
    fn mul(self, s: S) -> Self {
        Self {
            diagonal: self.diagonal.map(|x| x * s),
            upper: self.upper.map(|x| x * s),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::Rng;

    /// Random symmetric positive definite `B B^T + floor I`, as both representations.
    fn spd(rng: &mut Rng, floor: f64) -> (SymmetricMatrix3<f64>, Matrix3<f64>) {
        let b = Matrix3::from_columns(&[rng.vector(), rng.vector(), rng.vector()]);
        let mut a = SymmetricMatrix3::from_diagonal(&Vector3::repeat(floor));
        for c in b.column_iter() {
            a += SymmetricMatrix3::outer(&c.into_owned(), 1.0);
        }
        (a, a.to_matrix())
    }

    /// The product and the sums equal nalgebra's on the full matrix bit for bit, and the inverse
    /// (one reciprocal where nalgebra divides) agrees with nalgebra's to two roundings per entry,
    /// in f64 and f32, for well conditioned and nearly singular matrices (rank 2 plus 1e-12).
    #[test]
    fn operations_match_nalgebra_on_the_full_matrix() {
        let mut rng = Rng::new(17);
        for trial in 0..2000 {
            let floor = if trial % 2 == 0 { 0.1 } else { 1e-12 };
            let (a, full) = spd(&mut rng, floor);
            let (b, full_b) = spd(&mut rng, 0.5);
            let v = rng.vector();
            let s = rng.uniform();
            let inv = a.try_inverse().expect("positive definite").to_matrix();
            let reference = full.try_inverse().unwrap();
            for (x, r) in inv.iter().zip(reference.iter()) {
                assert!((x - r).abs() <= 2.0 * f64::EPSILON * r.abs(), "{full}");
            }
            assert_eq!(a.mul_vector(&v), full * v);
            assert_eq!((a + b * s).to_matrix(), full + full_b * s);
            assert_eq!(
                a.plus_identity(s).to_matrix(),
                full + Matrix3::identity() * s
            );
            let a32 = SymmetricMatrix3 {
                diagonal: a.diagonal.map(|x| x as f32),
                upper: a.upper.map(|x| x as f32),
            };
            let full32 = full.map(|x| x as f32);
            match (a32.try_inverse(), full32.try_inverse()) {
                (Some(i), Some(f)) => {
                    for (x, r) in i.to_matrix().iter().zip(f.iter()) {
                        assert!((x - r).abs() <= 2.0 * f32::EPSILON * r.abs(), "{full32}");
                    }
                }
                (None, None) => {}
                other => panic!("f32 invertibility differs: {other:?}"),
            }
            assert_eq!(
                a32.mul_vector(&v.map(|x| x as f32)),
                full32 * v.map(|x| x as f32)
            );
        }
    }

    /// `A A^-1 = I` to round-off relative to the condition number, and an exactly singular
    /// matrix (rank 2) has no inverse.
    #[test]
    fn inverse_inverts_and_singular_matrices_have_none() {
        let mut rng = Rng::new(3);
        for _ in 0..200 {
            let (a, full) = spd(&mut rng, 0.1);
            let inv = a.try_inverse().unwrap().to_matrix();
            let cond = full.norm() * inv.norm();
            assert!((full * inv - Matrix3::identity()).norm() < 1e-14 * cond);
        }
        let u = Vector3::new(1.0, 2.0, 4.0);
        let w = Vector3::new(0.5, -1.0, 0.25);
        let rank2 = SymmetricMatrix3::outer(&u, 2.0) + SymmetricMatrix3::outer(&w, 3.0);
        assert_eq!(rank2.try_inverse(), None);
        assert_eq!(SymmetricMatrix3::<f32>::zeros().try_inverse(), None);
    }

    /// A pack inverts lane by lane exactly as the scalar inverse does (f32 and f64 packs); the
    /// lanes that are singular (rank 2) or whose determinant's reciprocal overflows (and only
    /// those) take the fallback, and a NaN lane stays NaN.
    #[test]
    fn pack_inverse_is_the_scalar_inverse_in_every_lane() {
        use crate::real::{F32Pack, F64Pack, Lanes};
        fn check<P: Lanes>(lanes: &[SymmetricMatrix3<f64>]) {
            let of = |m: &SymmetricMatrix3<f64>| SymmetricMatrix3 {
                diagonal: m.diagonal.map(<P::Scalar as Real>::of),
                upper: m.upper.map(<P::Scalar as Real>::of),
            };
            let scalars: Vec<_> = lanes.iter().map(of).collect();
            let pack = SymmetricMatrix3 {
                diagonal: [0, 1, 2].map(|e| P::gather(|l| scalars[l].entry(e))),
                upper: [3, 4, 5].map(|e| P::gather(|l| scalars[l].entry(e))),
            };
            let fallback = <P::Scalar as Real>::of(0.25);
            let inverse = pack.inverse_or(P::splat(fallback));
            for (l, lane) in scalars.iter().enumerate() {
                let expected = lane
                    .try_inverse()
                    .unwrap_or_else(|| SymmetricMatrix3::from_diagonal(&Vector3::repeat(fallback)));
                for e in 0..6 {
                    let (got, want) = (inverse.entry(e).extract(l), expected.entry(e));
                    assert!(
                        got == want || (got != got && want != want),
                        "{}: lane {l}, entry {e}: {got:?} against {want:?}",
                        <P::Scalar as Real>::NAME
                    );
                }
            }
        }
        let mut rng = Rng::new(5);
        let mut spd = || spd(&mut rng, 0.1).0;
        let singular = SymmetricMatrix3::outer(&Vector3::new(1.0, 2.0, 4.0), 2.0);
        let nan = SymmetricMatrix3::from_diagonal(&Vector3::new(1.0, f64::NAN, 1.0));
        // det 1e-45: a subnormal f32 whose reciprocal overflows (in f64 it inverts).
        let tiny = SymmetricMatrix3::from_diagonal(&Vector3::repeat(1e-15));
        assert_eq!(singular.try_inverse(), None);
        assert_eq!(
            SymmetricMatrix3::from_diagonal(&Vector3::repeat(1e-15f32)).try_inverse(),
            None
        );
        check::<F64Pack>(&[spd(), singular, nan, tiny]);
        check::<F32Pack>(&[spd(), singular, spd(), nan, tiny, spd(), spd(), singular]);
    }
}
