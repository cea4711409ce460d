//! Compressible neo-Hookean model (Lu et al. 2023, eq. 36-38):
//! `Psi = s0 (I1 - 3 - ln I3) + s1 (J - 1)^2`, `I1 = sum lambda^2`, `I3 = J^2`,
//! `J = lambda_1 lambda_2 lambda_3`. Lame parameters `mu = 2 s0`, `lambda = 2 s1`.

use crate::real::Lanes;

/// `Psi` (J/m^3) for `s0`, `s1` (Pa), written as `s0 sum_m (x - 1 - ln x)` with `x = lambda_m^2`
/// (each term >= 0) plus `s1 (J - 1)^2`, and clamped at 0 against round-off. With
/// `u = x - 1 = (lambda - 1)(lambda + 1)` the term is [`u_minus_ln_1p`]`(u)`; far from
/// `lambda = 1` (`|u| >= 1/2`) it is `u - ln x` with `ln x` taken directly, since `1 + u` no
/// longer holds `x` exactly when `x` is tiny (in f32, `lambda = 1e-4` gives `u = -1`).
#[inline]
pub fn energy<S: Lanes>(s0: S, s1: S, l: [S; 3]) -> S {
    let j = l[0] * l[1] * l[2];
    let shear = l.iter().fold(S::zero(), |acc, &s| {
        let u = (s - S::one()) * (s + S::one());
        let near_one = u.simd_abs().simd_lt(S::lit(0.5));
        let term = u_minus_ln_1p(u).select(near_one, u - (s * s).simd_ln());
        acc + term.simd_max(S::zero())
    });
    s0 * shear + s1 * (j - S::one()) * (j - S::one())
}

/// Terms of the series `u - ln(1 + u) = u^2 (1/2 - u/3 + u^2/4 - ...)` used below
/// [`SERIES_BELOW`]: the truncation is below `2 |u|^14 / 16 < 1e-15` of the value there.
const SERIES_TERMS: usize = 14;
/// `|u|` below which the series replaces `u - ln(1 + u)`, whose two terms cancel: their
/// difference is `u^2 / 2`, so computing it as a difference loses `-log2(|u| / 2)` bits.
const SERIES_BELOW: f64 = 0.1;

/// `u - ln(1 + u)` (>= 0) for `|u| < 1/2`, accurate to round-off for small `u` as well.
#[inline]
fn u_minus_ln_1p<S: Lanes>(u: S) -> S {
    let small = u.simd_abs().simd_lt(S::lit(SERIES_BELOW));
    let mut series = S::zero();
    for k in (2..SERIES_TERMS + 2).rev() {
        let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
        series = series * u + S::lit(sign / k as f64);
    }
    (u * u * series).select(small, u - u.simd_ln_1p())
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

#[cfg(test)]
mod tests {
    use super::u_minus_ln_1p;

    /// The series agrees with the closed form where that is accurate (|u| >= 1e-3, 1e-12
    /// relative), with the leading terms where it is not, and joins it at the switch.
    #[test]
    fn u_minus_ln_1p_is_accurate_on_both_sides_of_the_switch() {
        for u in [-0.4, -0.0999, -0.05, -1e-3, 1e-3, 0.03, 0.0999, 0.1, 0.3f64] {
            let exact = u - u.ln_1p();
            let got = u_minus_ln_1p(u);
            assert!(
                (got - exact).abs() <= 1e-12 * exact,
                "u {u}: {got} vs {exact}"
            );
        }
        for u in [1e-8, -3e-7, 2e-5f64] {
            // Truncated after u^6 / 6: the rest is below 1e-15 of the value for these u.
            let leading = u * u * (0.5 - u / 3.0 + u * u / 4.0 - u.powi(3) / 5.0 + u.powi(4) / 6.0);
            assert!(
                (u_minus_ln_1p(u) - leading).abs() <= 1e-14 * leading,
                "u {u}"
            );
        }
        for u in [0.1f64 - 1e-12, 0.1 + 1e-12, -0.1 - 1e-12, -0.1 + 1e-12] {
            let exact = u - u.ln_1p();
            assert!((u_minus_ln_1p(u) - exact).abs() <= 1e-12 * exact, "u {u}");
        }
    }
}
