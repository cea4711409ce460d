//! The barrier of Lu et al. 2023 (eq. 3) and the C1 distance rescale of eq. 51.
//!
//! In the local step the barrier acts on the rescaled gap `x = f(d) - xi` (eq. 50-51), where
//! `d` is the mid-surface distance between two primitives and `xi` the membrane thickness
//! (m). Because `f(d) >= (1 + eps) xi`, the gap never falls below `eps xi`, so `|B'(x)|` stays
//! below the bound `|B'(eps xi)|` that the step length of eq. 53 uses.

/// Parameters of the barrier on the rescaled gap.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Barrier {
    /// Membrane thickness `xi` (m): the mid-surfaces of two primitives stay `xi` apart.
    pub thickness: f64,
    /// Barrier range `d_hat` (m): the barrier acts where the gap `f(d) - xi` is below it.
    pub d_hat: f64,
    /// Minimal separation multiplier `eps` (dimensionless, eq. 51).
    pub eps: f64,
}

impl Barrier {
    /// `B(x) = -(x - d_hat)^2 log(x / d_hat)` for `0 < x < d_hat`, else 0 (eq. 3; m^2).
    pub fn value(&self, x: f64) -> f64 {
        if x >= self.d_hat {
            0.0
        } else {
            -(x - self.d_hat).powi(2) * (x / self.d_hat).ln()
        }
    }

    /// `B'(x) = -2 (x - d_hat) log(x / d_hat) - (x - d_hat)^2 / x` for `0 < x < d_hat`, else 0
    /// (m). Negative inside the range: the barrier falls with the gap.
    pub fn derivative(&self, x: f64) -> f64 {
        if x >= self.d_hat {
            0.0
        } else {
            let r = x - self.d_hat;
            -2.0 * r * (x / self.d_hat).ln() - r * r / x
        }
    }

    /// `B''(x) = -2 log(x / d_hat) - 4 (x - d_hat) / x + (x - d_hat)^2 / x^2` for
    /// `0 < x < d_hat`, else 0 (dimensionless). Positive inside the range (the barrier is
    /// convex), it grows like `d_hat^2 / x^2` as the gap closes.
    pub fn second_derivative(&self, x: f64) -> f64 {
        if x >= self.d_hat {
            0.0
        } else {
            let r = x - self.d_hat;
            -2.0 * (x / self.d_hat).ln() - 4.0 * r / x + r * r / (x * x)
        }
    }

    /// The rescaled distance of eq. 51 (m):
    /// `f(d) = (1 + eps) xi` for `d <= xi`,
    /// `(d - xi)^2 / (4 eps xi) + (1 + eps) xi` for `xi < d <= (1 + 2 eps) xi`, and `d` above.
    /// Value and slope match at both breakpoints (C1).
    pub fn rescale(&self, d: f64) -> f64 {
        let (xi, eps) = (self.thickness, self.eps);
        if d <= xi {
            (1.0 + eps) * xi
        } else if d <= (1.0 + 2.0 * eps) * xi {
            (d - xi).powi(2) / (4.0 * eps * xi) + (1.0 + eps) * xi
        } else {
            d
        }
    }

    /// `f'(d)`: 0, `(d - xi) / (2 eps xi)`, 1 on the three pieces of eq. 51.
    pub fn rescale_derivative(&self, d: f64) -> f64 {
        let (xi, eps) = (self.thickness, self.eps);
        if d <= xi {
            0.0
        } else if d <= (1.0 + 2.0 * eps) * xi {
            (d - xi) / (2.0 * eps * xi)
        } else {
            1.0
        }
    }

    /// The rescaled gap `x = f(d) - xi >= eps xi` (eq. 50-51; m).
    pub fn gap(&self, d: f64) -> f64 {
        self.rescale(d) - self.thickness
    }

    /// Mid-surface distance (m) beyond which a pair feels no barrier: `f(d) - xi >= d_hat`.
    pub fn reach(&self) -> f64 {
        (self.thickness + self.d_hat).max((1.0 + 2.0 * self.eps) * self.thickness)
    }

    /// `ceil|B'|` of eq. 53: `|B'|` is largest at the smallest gap, `eps xi` (m).
    pub fn derivative_bound(&self) -> f64 {
        self.derivative(self.eps * self.thickness).abs()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn barrier() -> Barrier {
        Barrier {
            thickness: 1.5e-3,
            d_hat: 6e-3,
            eps: 0.1,
        }
    }

    #[test]
    fn barrier_derivative_matches_finite_differences_and_vanishes_at_d_hat() {
        let b = barrier();
        for k in 1..200 {
            let x = b.d_hat * 1.2 * k as f64 / 200.0;
            let h = 1e-9;
            let fd = (b.value(x + h) - b.value(x - h)) / (2.0 * h);
            assert!(
                (fd - b.derivative(x)).abs() < 1e-6 * (1.0 + fd.abs()),
                "x = {x}"
            );
        }
        assert_eq!(b.value(b.d_hat), 0.0);
        assert!(b.derivative(b.d_hat * (1.0 - 1e-9)).abs() < 1e-12);
        assert!(b.derivative(0.5 * b.d_hat) < 0.0);
    }

    #[test]
    fn barrier_second_derivative_matches_finite_differences_of_the_slope() {
        let b = barrier();
        let mut previous = f64::INFINITY;
        for k in 1..200 {
            let x = b.d_hat * 1.2 * k as f64 / 200.0;
            let h = 1e-9;
            let fd = (b.derivative(x + h) - b.derivative(x - h)) / (2.0 * h);
            let exact = b.second_derivative(x);
            assert!((fd - exact).abs() < 1e-5 * (1.0 + fd.abs()), "x = {x}");
            // Convex inside the range, and flattening towards its end.
            if x < b.d_hat {
                assert!(exact > 0.0 && exact < previous, "x = {x}");
            }
            previous = exact;
        }
        assert_eq!(b.second_derivative(b.d_hat), 0.0);
    }

    #[test]
    fn rescale_is_c1_at_both_breakpoints_and_keeps_the_gap_above_eps_xi() {
        let b = barrier();
        let (xi, eps) = (b.thickness, b.eps);
        for d in [xi, (1.0 + 2.0 * eps) * xi] {
            let h = 1e-9 * xi;
            let (below, above) = (b.rescale(d - h), b.rescale(d + h));
            assert!((above - below).abs() < 1e-8 * xi, "value jumps at {d}");
            let slope_below = (b.rescale(d - h) - b.rescale(d - 2.0 * h)) / h;
            let slope_above = (b.rescale(d + 2.0 * h) - b.rescale(d + h)) / h;
            assert!(
                (slope_above - slope_below).abs() < 1e-5,
                "slope jumps at {d}"
            );
        }
        for k in 0..300 {
            let d = 3.0 * xi * k as f64 / 300.0;
            let h = 1e-10;
            let fd = (b.rescale(d + h) - b.rescale(d - h)) / (2.0 * h);
            assert!((fd - b.rescale_derivative(d)).abs() < 1e-4, "d = {d}");
            assert!(b.gap(d) >= eps * xi * (1.0 - 1e-12));
            assert!(b.derivative(b.gap(d)).abs() <= b.derivative_bound() * (1.0 + 1e-12));
        }
    }
}
