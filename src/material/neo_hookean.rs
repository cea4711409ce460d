//! Compressible neo-Hookean model (Lu et al. 2023, eq. 36-38):
//! `Psi = s0 (I1 - 3 - ln I3) + s1 (J - 1)^2`, `I1 = sum lambda^2`, `I3 = J^2`,
//! `J = lambda_1 lambda_2 lambda_3`. Lame parameters `mu = 2 s0`, `lambda = 2 s1`.

use crate::real::Lanes;

/// `Psi` (J/m^3) for `s0`, `s1` (Pa), written as `s0 sum_m (x - 1 - ln x)` with `x = lambda_m^2`
/// (each term >= 0) plus `s1 (J - 1)^2`, and clamped at 0 against round-off. With
/// `u = x - 1 = (lambda - 1)(lambda + 1)` the term is `u - ln(1 + u)`, free of cancellation
/// near `lambda = 1`; far from it (`|u| >= 1/2`) `ln x` is taken directly, since `1 + u` no
/// longer holds `x` exactly when `x` is tiny (in f32, `lambda = 1e-4` gives `u = -1`).
#[inline]
pub fn energy<S: Lanes>(s0: S, s1: S, l: [S; 3]) -> S {
    let j = l[0] * l[1] * l[2];
    let shear = l.iter().fold(S::zero(), |acc, &s| {
        let u = (s - S::one()) * (s + S::one());
        let near_one = u.simd_abs().simd_lt(S::lit(0.5));
        let log = u.simd_ln_1p().select(near_one, (s * s).simd_ln());
        acc + (u - log).simd_max(S::zero())
    });
    s0 * shear + s1 * (j - S::one()) * (j - S::one())
}

/// `P+ = 2 s0 lambda + 2 s1 I3 / lambda`, `P- = -2 (s0 + s1 J) / lambda` (eq. 38).
#[inline]
pub fn stress_split<S: Lanes>(s0: S, s1: S, l: [S; 3]) -> ([S; 3], [S; 3]) {
    let two = S::lit(2.0);
    let j = l[0] * l[1] * l[2];
    (
        l.map(|s| two * s0 * s + two * s1 * j * j / s),
        l.map(|s| -two * (s0 + s1 * j) / s),
    )
}

/// `P+ / lambda = 2 s0 + 2 s1 I3 / lambda^2`.
#[inline]
pub fn implicit_stiffness<S: Lanes>(s0: S, s1: S, l: [S; 3]) -> [S; 3] {
    let two = S::lit(2.0);
    let j = l[0] * l[1] * l[2];
    l.map(|s| two * s0 + two * s1 * j * j / (s * s))
}

/// `d2Psi/dl_a^2 = 2 s0 (1 + l_a^-2) + 2 s1 (J / l_a)^2`, `d2Psi/dl1 dl2 = 2 s1 J (2J - 1) / (l1 l2)`.
#[inline]
pub fn in_plane_hessian<S: Lanes>(s0: S, s1: S, l: [S; 3]) -> [S; 3] {
    let two = S::lit(2.0);
    let j = l[0] * l[1] * l[2];
    let d = |s: S| two * s0 * (S::one() + S::one() / (s * s)) + two * s1 * (j / s) * (j / s);
    [
        d(l[0]),
        d(l[1]),
        two * s1 * j * (two * j - S::one()) / (l[0] * l[1]),
    ]
}
