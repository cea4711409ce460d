//! The influence function `w(|xi|)` of the particle model (He et al. 2017, eq. 4 and 8).
//!
//! `w(r) = 3 (1 - r / delta) / (pi delta^3)` for `r < delta`, else 0 (1/m^3): a cone that
//! falls to zero at the horizon `delta`, so a neighbour near the edge of the horizon carries
//! little weight, normalised so that its integral over the horizon ball is 1. The
//! normalisation makes `sum_j V_j w_ij` dimensionless, so the paper's `mu` and `lam` (eq. 8)
//! are in Pa and the model's continuum Young's modulus is `(2 mu + lam) / 6` (see
//! [`super::calibration`]). The authors' code uses `q^3 (1 - q^2)` with `q = r / (2 delta)`,
//! which is zero at `r = 0` and not zero at the horizon; the paper states no choice.

/// `w(r)` (1/m^3) for a bond of length `r` (m) and the horizon `delta` (m).
#[inline]
pub fn influence(r: f64, delta: f64) -> f64 {
    if r >= delta {
        return 0.0;
    }
    3.0 * (1.0 - r / delta) / (std::f64::consts::PI * delta * delta * delta)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `integral of w over the ball = int_0^delta w(r) 4 pi r^2 dr = 1` (midpoint rule, 1e-6).
    #[test]
    fn influence_integrates_to_one_over_the_horizon() {
        let delta = 0.037;
        let n = 200_000;
        let dr = delta / n as f64;
        let sum: f64 = (0..n)
            .map(|k| {
                let r = (k as f64 + 0.5) * dr;
                influence(r, delta) * 4.0 * std::f64::consts::PI * r * r * dr
            })
            .sum();
        assert!((sum - 1.0).abs() < 1e-6, "{sum}");
        assert_eq!(influence(delta, delta), 0.0);
    }
}
