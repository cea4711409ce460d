//! Elastic constants of the particle model from lattice sums (beyond the paper).
//!
//! Under an affine deformation `F = I + eps` (small, symmetric) every particle's `F_i` is `F`
//! exactly in the interior, `|F_i xi| = |Y|`, and both terms of eq. 8 are pair springs: the
//! energy density is `Psi = c sum_j V_j w_j (n_j . eps n_j)^2` to second order, with
//! `c = mu + lam / 2` and `n_j` the bond directions. So the stiffness tensor is
//! `C_abcd = 2 c S_abcd` with the lattice's fourth moment `S_abcd = sum_j V_j w_j n_a n_b n_c n_d`.
//! On a cubic lattice `S` has cubic symmetry: `C11 = 2 c S_1111`, `C12 = C44 = 2 c S_1122`
//! (the Cauchy relation of a bond-based model), so along a lattice axis
//! `E = (C11 - C12)(C11 + 2 C12) / (C11 + C12)` and `nu = C12 / (C11 + C12)`. In the continuum
//! limit (an isotropic `S`, `S_1111 = 3 S_1122 = A / 5`, `A = integral of w = 1`) these are
//! `E = (2 mu + lam) / 6` and `nu = 1/4`.

use crate::error::{invalid, Result};

use super::influence::influence;

/// The small-strain moduli of a cubic lattice for `c = mu + lam / 2 = 1` Pa.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LatticeModuli {
    /// `C11` and `C12` (Pa per Pa of `c`).
    pub c11: f64,
    pub c12: f64,
    /// Young's modulus along a lattice axis (Pa per Pa of `c`).
    pub young: f64,
    /// Poisson's ratio along a lattice axis.
    pub poisson: f64,
}

/// Largest horizon, in lattice spacings, that the lattice sums accept (about 1.1e6 terms).
pub const MAX_HORIZON_SPACINGS: f64 = 64.0;

/// The moduli of an infinite cubic lattice of `spacing` (m, particle volume `spacing^3`) with
/// the horizon `delta` (m), by summing over every lattice vector shorter than `delta`.
pub fn lattice_moduli(spacing: f64, delta: f64) -> Result<LatticeModuli> {
    let ratio = delta / spacing;
    if !(spacing.is_finite() && spacing > 0.0 && delta.is_finite()) {
        return Err(invalid!(
            "spacing ({spacing} m) and horizon ({delta} m) must be finite and positive"
        ));
    }
    if !(ratio > 1.0 && ratio <= MAX_HORIZON_SPACINGS) {
        return Err(invalid!(
            "the horizon must be between 1 and {MAX_HORIZON_SPACINGS} spacings, got {ratio} \
             ({delta} m for a spacing of {spacing} m)"
        ));
    }
    let reach = ratio.floor() as i64;
    let volume = spacing * spacing * spacing;
    let (mut s1111, mut s1122) = (0.0, 0.0);
    for a in -reach..=reach {
        for b in -reach..=reach {
            for c in -reach..=reach {
                let n2 = (a * a + b * b + c * c) as f64;
                if n2 == 0.0 {
                    continue;
                }
                let r = n2.sqrt() * spacing;
                let w = influence(r, delta) * volume;
                let (x, y) = (a as f64 * a as f64 / n2, b as f64 * b as f64 / n2);
                s1111 += w * x * x;
                s1122 += w * x * y;
            }
        }
    }
    let (c11, c12) = (2.0 * s1111, 2.0 * s1122);
    Ok(LatticeModuli {
        c11,
        c12,
        young: (c11 - c12) * (c11 + 2.0 * c12) / (c11 + c12),
        poisson: c12 / (c11 + c12),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With a horizon of many spacings the lattice is nearly isotropic: `E -> (2 mu + lam) / 6`,
    /// that is `c / 3`, and `nu -> 1/4` (1 % at 30 spacings).
    #[test]
    fn a_fine_lattice_has_the_continuum_moduli() {
        let m = lattice_moduli(1.0, 30.0).unwrap();
        assert!((m.young * 3.0 - 1.0).abs() < 0.01, "{m:?}");
        assert!((m.poisson - 0.25).abs() < 0.01, "{m:?}");
    }

    #[test]
    fn horizons_outside_the_lattice_range_are_refused() {
        assert!(lattice_moduli(1.0, 0.9).is_err());
        assert!(lattice_moduli(1.0, 100.0).is_err());
        assert!(lattice_moduli(0.0, 1.0).is_err());
    }
}
