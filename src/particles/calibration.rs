//! Elastic constants of the particle model from lattice sums (beyond the paper), and the
//! calibration of [`super::Elastic::Young`] to them.
//!
//! Under an affine deformation `F = I + eps` (small, symmetric) every interior particle's `F_i`
//! is `F` exactly, `|F_i xi| = |Y|`, and both terms of eq. 8 are pair springs: their energy
//! density is `c sum_j V_j w_j (n_j . eps n_j)^2` to second order, with `c = mu + lam / 2` and
//! `n_j` the bond directions. So their stiffness tensor is `C_abcd = 2 c S_abcd` with the
//! lattice's fourth moment `S_abcd = sum_j V_j w_j n_a n_b n_c n_d`. On a cubic lattice `S` has
//! cubic symmetry: `C11 = 2 c S_1111`, `C12 = C44 = 2 c S_1122` (the Cauchy relation of a
//! bond-based model: Poisson's ratio 1/4 in the isotropic limit, `S_1111 = 3 S_1122 = A / 5`
//! with `A = sum_j V_j w_j`, where `E = (2 mu + lam) A / 6`).
//!
//! The dilatation term ([`super::bond`]) adds `kappa / 2 (tr eps)^2` to the energy density
//! (the bonds' weighted mean strain is `tr eps / 3` exactly on a cubic lattice, whose second
//! moment `sum_j V_j w_j n n^T = A I / 3` is isotropic): `kappa` (Pa) to `C11` and `C12`, not
//! to `C44`. Along a lattice axis `E = (C11 - C12)(C11 + 2 C12) / (C11 + C12)` and
//! `nu = C12 / (C11 + C12)`; for a target `(E, nu)` that is `C11 - C12 = E / (1 + nu)` and
//! `C11 = (C11 - C12)(1 - nu) / (1 - 2 nu)`, so `c = E / (2 (1 + nu)(S_1111 - S_1122))` and
//! `kappa = C11 - 2 c S_1111` (negative below about nu = 1/4).
//!
//! **The split of `c` into `mu` and `lam`** changes nothing under an affine deformation; only
//! `mu` resists non-affine motion within a horizon ([`DEVIATORIC_SHARE`]). A negative `kappa`
//! leaves each particle's energy non-negative as long as `lam A + 9 kappa >= 0` (Jensen:
//! `sum_j p_j s_j^2 >= (sum_j p_j s_j)^2` for the bonds' strains `s_j` and weights
//! `p_j = V_j w_j / A`): where the share would not keep `lam A + 9 kappa >= LAM_MARGIN lam A`,
//! `lam` takes the least share that does.

use crate::error::{invalid, Result};

use super::influence::influence;

/// The lattice sums of a cubic lattice of spacing `h` with the horizon `delta`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LatticeModuli {
    /// `A = sum_j V_j w_j`, `S_1111` and `S_1122` (dimensionless).
    pub weight: f64,
    pub s1111: f64,
    pub s1122: f64,
    /// `C11` and `C12` of the pair springs for `c = mu + lam / 2 = 1` Pa (Pa per Pa of `c`).
    pub c11: f64,
    pub c12: f64,
    /// Young's modulus along a lattice axis (Pa per Pa of `c`) and Poisson's ratio of the pair
    /// springs alone.
    pub young: f64,
    pub poisson: f64,
}

/// The paper's `mu`, `lam` and the dilatation modulus `kappa` (Pa) a material resolves to, and
/// whether the bonds near free surfaces are stiffened (see [`super::surface`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Moduli {
    pub mu: f64,
    pub lam: f64,
    pub kappa: f64,
    /// `S_1111` of the bulk lattice (dimensionless, the same along each axis) for the
    /// surface correction ([`super::surface`]), or `None` (the paper's model).
    pub bulk_moment: Option<f64>,
    /// `A` of the bulk lattice (dimensionless) for the surface correction of plastic bodies
    /// ([`super::rest`]), or `None`.
    pub bulk_weight: Option<f64>,
}

/// Largest horizon, in lattice spacings, that the lattice sums accept (about 1.1e6 terms).
pub const MAX_HORIZON_SPACINGS: f64 = 64.0;

/// The share of `lam A` that must stay after a negative dilatation modulus takes its part (see
/// the module's doc).
pub const LAM_MARGIN: f64 = 0.4;

/// The share of the pair springs' stiffness `c = mu + lam / 2` that [`calibrate`] gives the
/// deviatoric term: `mu = DEVIATORIC_SHARE c`, `lam = 2 (1 - DEVIATORIC_SHARE) c` (unless a
/// negative `kappa` asks `lam` for more). `mu` alone resists motion within a horizon that is not
/// affine, for two effects that pull apart: it turns an inverted neighbourhood back (the paper's
/// Fig. 3: pair springs see lengths only, so an inverted body is their equilibrium; a 5^3 block
/// squashed to a fifth and turned inside out recovers at shares of 0.2 and above at nu 0.25 and
/// 0.3, and not at 0.15 or 0.1), and it stiffens bending, a curvature being non-affine within a
/// horizon, with a stiffness set by the spacing, not the section: a cantilever four particles
/// thick sags 0.89 of Euler-Bernoulli at this share, 0.73 at the 2/3 of `mu = lam`. Below about
/// nu = 0.05 the negative `kappa` leaves the deviatoric term less (0.16 of `c` at nu = 0, where
/// the block recovers as well).
pub const DEVIATORIC_SHARE: f64 = 0.3;

/// The lattice sums of an infinite cubic lattice of `spacing` (m, particle volume `spacing^3`)
/// with the horizon `delta` (m), over every lattice vector shorter than `delta`.
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
    let (mut weight, mut s1111, mut s1122) = (0.0, 0.0, 0.0);
    for a in -reach..=reach {
        for b in -reach..=reach {
            for c in -reach..=reach {
                let n2 = (a * a + b * b + c * c) as f64;
                if n2 == 0.0 {
                    continue;
                }
                let w = influence(n2.sqrt() * spacing, delta) * volume;
                let (x, y) = (a as f64 * a as f64 / n2, b as f64 * b as f64 / n2);
                weight += w;
                s1111 += w * x * x;
                s1122 += w * x * y;
            }
        }
    }
    let (c11, c12) = (2.0 * s1111, 2.0 * s1122);
    Ok(LatticeModuli {
        weight,
        s1111,
        s1122,
        c11,
        c12,
        young: (c11 - c12) * (c11 + 2.0 * c12) / (c11 + c12),
        poisson: c12 / (c11 + c12),
    })
}

/// `(mu, lam, kappa)` (Pa) that give a cubic lattice of `spacing` (m) with the horizon `delta`
/// (m) the Young's modulus `e` (Pa) and Poisson ratio `nu` along its axes (see the module's
/// doc). Fails when `nu` is too small for the margin `LAM_MARGIN` on this lattice.
pub fn calibrate(e: f64, nu: f64, spacing: f64, delta: f64) -> Result<Moduli> {
    let s = lattice_moduli(spacing, delta)?;
    let c = e / (2.0 * (1.0 + nu) * (s.s1111 - s.s1122));
    let c11 = e / (1.0 + nu) * (1.0 - nu) / (1.0 - 2.0 * nu);
    let kappa = c11 - 2.0 * c * s.s1111;
    let lam_min = -9.0 * kappa / ((1.0 - LAM_MARGIN) * s.weight);
    let lam = (2.0 * (1.0 - DEVIATORIC_SHARE) * c).max(lam_min);
    if lam > 2.0 * c {
        return Err(invalid!(
            "nu = {nu} is too small for this lattice (horizon {} spacings): the dilatation \
             term would make the energy indefinite",
            delta / spacing
        ));
    }
    Ok(Moduli {
        mu: c - lam / 2.0,
        lam,
        kappa,
        bulk_moment: Some(s.s1111),
        bulk_weight: Some(s.weight),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With a horizon of many spacings the lattice is nearly isotropic: `E -> (2 mu + lam) A / 6`,
    /// that is `c A / 3`, and `nu -> 1/4` (1 % at 30 spacings), with `A -> 1` (the influence
    /// function integrates to one).
    #[test]
    fn a_fine_lattice_has_the_continuum_moduli() {
        let m = lattice_moduli(1.0, 30.0).unwrap();
        assert!((m.weight - 1.0).abs() < 0.01, "{m:?}");
        assert!((m.young * 3.0 - 1.0).abs() < 0.01, "{m:?}");
        assert!((m.poisson - 0.25).abs() < 0.01, "{m:?}");
    }

    /// The calibrated constants put the asked `E` and `nu` back through the lattice formulas
    /// (1e-12), and keep `lam A + 9 kappa >= LAM_MARGIN lam A`, for nu from 0 to 0.45.
    #[test]
    fn calibration_inverts_the_lattice_formulas() {
        let (spacing, delta) = (0.01, 0.022);
        let s = lattice_moduli(spacing, delta).unwrap();
        for nu in [0.0, 0.1, 0.25, 0.3, 0.4, 0.45] {
            let m = calibrate(2e5, nu, spacing, delta).unwrap();
            let c = m.mu + m.lam / 2.0;
            let (c11, c12) = (2.0 * c * s.s1111 + m.kappa, 2.0 * c * s.s1122 + m.kappa);
            let e = (c11 - c12) * (c11 + 2.0 * c12) / (c11 + c12);
            assert!((e / 2e5 - 1.0).abs() < 1e-12, "nu {nu}: E {e}");
            assert!((c12 / (c11 + c12) - nu).abs() < 1e-12, "nu {nu}");
            assert!(m.mu >= 0.0 && m.lam > 0.0, "{m:?}");
            let lam_min = -9.0 * m.kappa / ((1.0 - LAM_MARGIN) * s.weight);
            let lam = (2.0 * (1.0 - DEVIATORIC_SHARE) * c).max(lam_min);
            assert!((m.lam / lam - 1.0).abs() < 1e-12, "nu {nu}: {m:?}");
            let floor = (LAM_MARGIN - 1e-9) * m.lam * s.weight;
            assert!(m.lam * s.weight + 9.0 * m.kappa >= floor, "nu {nu}: {m:?}");
        }
    }

    #[test]
    fn horizons_outside_the_lattice_range_are_refused() {
        assert!(lattice_moduli(1.0, 0.9).is_err());
        assert!(lattice_moduli(1.0, 100.0).is_err());
        assert!(lattice_moduli(0.0, 1.0).is_err());
    }
}
