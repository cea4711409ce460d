//! The A3 stretching model (Lu et al. 2023, eq. 39-41; A_n of Xu et al. 2018 with n = 3):
//! `Psi = s0 sum_m A3(lambda_m)`, `A3(s) = ((s^4 - 1)/4 + (s^-2 - 1)/2) / 3`.
//! Each principal stretch is independent: shear modulus `s0`, no Poisson coupling.

use crate::real::Real;

/// `Psi` (J/m^3) for stiffness `s0` (Pa), evaluated as the product
/// `A3(s) = (s^2 - 1)^2 (s^2 + 2) / (12 s^2)`, which is >= 0 in floating point too (the
/// textbook sum cancels near s = 1).
#[inline]
pub fn energy<T: Real>(s0: T, l: [T; 3]) -> T {
    let twelfth = T::of(1.0 / 12.0);
    l.iter().fold(T::zero(), |acc, &s| {
        let s2 = s * s;
        let strain = (s - T::one()) * (s + T::one());
        acc + strain * strain * (s2 + T::of(2.0)) / s2 * twelfth
    }) * s0
}

/// `P+ = s0 lambda^3 / 3`, `P- = -s0 / (3 lambda^3)` (eq. 41).
#[inline]
pub fn stress_split<T: Real>(s0: T, l: [T; 3]) -> ([T; 3], [T; 3]) {
    let third = s0 * T::of(1.0 / 3.0);
    (
        l.map(|s| third * s * s * s),
        l.map(|s| -third / (s * s * s)),
    )
}

/// `P+ / lambda = s0 lambda^2 / 3`.
#[inline]
pub fn implicit_stiffness<T: Real>(s0: T, l: [T; 3]) -> [T; 3] {
    let third = s0 * T::of(1.0 / 3.0);
    l.map(|s| third * s * s)
}

/// `(s0 (l1^2 + l1^-4), s0 (l2^2 + l2^-4), 0)`: the stretches are uncoupled.
#[inline]
pub fn in_plane_hessian<T: Real>(s0: T, l: [T; 3]) -> [T; 3] {
    let d = |s: T| s0 * (s * s + T::one() / (s * s * s * s));
    [d(l[0]), d(l[1]), T::zero()]
}
