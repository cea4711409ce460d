//! Compressible neo-Hookean model (Lu et al. 2023, eq. 36-38):
//! `Psi = s0 (I1 - 3 - ln I3) + s1 (J - 1)^2`, `I1 = sum lambda^2`, `I3 = J^2`,
//! `J = lambda_1 lambda_2 lambda_3`. Lame parameters `mu = 2 s0`, `lambda = 2 s1`.

use crate::real::Real;

/// `Psi` (J/m^3) for `s0`, `s1` (Pa), written as `s0 sum_m (x - 1 - ln x)` with `x = lambda_m^2`
/// (each term >= 0) plus `s1 (J - 1)^2`, and clamped at 0 against round-off.
#[inline]
pub fn energy<T: Real>(s0: T, s1: T, l: [T; 3]) -> T {
    let j = l[0] * l[1] * l[2];
    let shear = l.iter().fold(T::zero(), |acc, &s| {
        let u = (s - T::one()) * (s + T::one());
        acc + (u - u.ln_1p()).max(T::zero())
    });
    s0 * shear + s1 * (j - T::one()) * (j - T::one())
}

/// `P+ = 2 s0 lambda + 2 s1 I3 / lambda`, `P- = -2 (s0 + s1 J) / lambda` (eq. 38).
#[inline]
pub fn stress_split<T: Real>(s0: T, s1: T, l: [T; 3]) -> ([T; 3], [T; 3]) {
    let two = T::of(2.0);
    let j = l[0] * l[1] * l[2];
    (
        l.map(|s| two * s0 * s + two * s1 * j * j / s),
        l.map(|s| -two * (s0 + s1 * j) / s),
    )
}

/// `P+ / lambda = 2 s0 + 2 s1 I3 / lambda^2`.
#[inline]
pub fn implicit_stiffness<T: Real>(s0: T, s1: T, l: [T; 3]) -> [T; 3] {
    let two = T::of(2.0);
    let j = l[0] * l[1] * l[2];
    l.map(|s| two * s0 + two * s1 * j * j / (s * s))
}

/// `d2Psi/dl_a^2 = 2 s0 (1 + l_a^-2) + 2 s1 (J / l_a)^2`, `d2Psi/dl1 dl2 = 2 s1 J (2J - 1) / (l1 l2)`.
#[inline]
pub fn in_plane_hessian<T: Real>(s0: T, s1: T, l: [T; 3]) -> [T; 3] {
    let two = T::of(2.0);
    let j = l[0] * l[1] * l[2];
    let d = |s: T| two * s0 * (T::one() + T::one() / (s * s)) + two * s1 * (j / s) * (j / s);
    [
        d(l[0]),
        d(l[1]),
        two * s1 * j * (two * j - T::one()) / (l[0] * l[1]),
    ]
}
