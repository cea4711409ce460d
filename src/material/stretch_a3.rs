//! The A3 stretching model (Lu et al. 2023, eq. 39-41; A_n of Xu et al. 2018 with n = 3):
//! `Psi = s0 sum_m A3(lambda_m)`, `A3(s) = ((s^4 - 1)/4 + (s^-2 - 1)/2) / 3`.
//! Each principal stretch is independent: shear modulus `s0`, no Poisson coupling.

use crate::real::Lanes;

/// `Psi` (J/m^3) for stiffness `s0` (Pa), evaluated as the product
/// `A3(s) = (s^2 - 1)^2 (s^2 + 2) / (12 s^2)`, which is >= 0 in floating point too (the
/// textbook sum cancels near s = 1).
#[inline]
pub fn energy<S: Lanes>(s0: S, l: [S; 3]) -> S {
    let twelfth = S::lit(1.0 / 12.0);
    l.iter().fold(S::zero(), |acc, &s| {
        let s2 = s * s;
        let strain = (s - S::one()) * (s + S::one());
        acc + strain * strain * (s2 + S::lit(2.0)) / s2 * twelfth
    }) * s0
}

/// `P+ = s0 lambda^3 / 3`, `P- = -s0 / (3 lambda^3)` (eq. 41).
#[inline]
pub fn stress_split<S: Lanes>(s0: S, l: [S; 3]) -> ([S; 3], [S; 3]) {
    let third = s0 * S::lit(1.0 / 3.0);
    (
        l.map(|s| third * s * s * s),
        l.map(|s| -third / (s * s * s)),
    )
}

/// `P+ / lambda = s0 lambda^2 / 3`.
#[inline]
pub fn implicit_stiffness<S: Lanes>(s0: S, l: [S; 3]) -> [S; 3] {
    let third = s0 * S::lit(1.0 / 3.0);
    l.map(|s| third * s * s)
}

/// `(s0 (l1^2 + l1^-4), s0 (l2^2 + l2^-4), 0)`: the stretches are uncoupled.
#[inline]
pub fn in_plane_hessian<S: Lanes>(s0: S, l: [S; 3]) -> [S; 3] {
    let d = |s: S| s0 * (s * s + S::one() / (s * s * s * s));
    [d(l[0]), d(l[1]), S::zero()]
}
