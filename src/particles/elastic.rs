//! The elastic material of a particle body (He et al. 2017, eq. 8): the paper's `mu` and
//! `lam`, or a Young's modulus and Poisson ratio resolved by a lattice-sum calibration with a
//! dilatation term beyond the paper.

use crate::error::{check_param, invalid, Result};

use super::calibration::{calibrate, Moduli};

/// Poisson ratios [`Elastic::Young`] accepts.
pub const POISSON_RANGE: (f64, f64) = (0.0, 0.45);

/// An elastic particle material.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Elastic {
    /// The paper's parameters of eq. 8 (Pa): `mu` weighs the deviatoric term `E_dev`, `lam`
    /// the isotropic term `E_iso`. They are not Lame parameters: under an affine deformation
    /// both terms are pair springs, the model is bond-based and its Poisson ratio is 1/4;
    /// only `2 mu + lam` sets the small-strain stiffness (continuum Young's modulus
    /// `(2 mu + lam) / 6`), and `mu` alone the resistance to non-affine deformation. No
    /// dilatation term, no surface correction: the paper's model as printed.
    Paper { mu: f64, lam: f64 },
    /// A Young's modulus `e` (Pa) and Poisson ratio `nu` (in [`POISSON_RANGE`]) to match along
    /// the axes of a body on a cubic lattice: resolved by [`calibrate`] into `mu`, `lam` and a
    /// dilatation modulus `kappa`, with the bonds near free surfaces stiffened.
    Young { e: f64, nu: f64 },
}

impl Elastic {
    /// Checks the parameters, naming the bad one.
    pub fn validate(&self) -> Result<()> {
        match *self {
            Self::Paper { mu, lam } => {
                check_param("mu", mu, |v| v >= 0.0, "a finite stiffness >= 0 Pa")?;
                check_param("lam", lam, |v| v >= 0.0, "a finite stiffness >= 0 Pa")?;
                if mu + lam <= 0.0 {
                    return Err(invalid!(
                        "mu + lam must be > 0 Pa, got mu = {mu}, lam = {lam}"
                    ));
                }
            }
            Self::Young { e, nu } => {
                check_param("E", e, |v| v > 0.0, "a finite Young's modulus > 0 Pa")?;
                let (lo, hi) = POISSON_RANGE;
                check_param(
                    "nu",
                    nu,
                    |v| (lo..=hi).contains(&v),
                    &format!("a Poisson ratio in [{lo}, {hi}]"),
                )?;
            }
        }
        Ok(())
    }

    /// The moduli for a body sampled on a cubic lattice of `spacing` (m) with the horizon
    /// `delta` (m).
    pub fn resolve(&self, spacing: f64, delta: f64) -> Result<Moduli> {
        self.validate()?;
        match *self {
            Self::Paper { mu, lam } => Ok(Moduli {
                mu,
                lam,
                kappa: 0.0,
                bulk_moment: None,
                bulk_weight: None,
            }),
            Self::Young { e, nu } => calibrate(e, nu, spacing, delta),
        }
    }
}
