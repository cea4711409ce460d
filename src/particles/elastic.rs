//! The elastic material of a particle body (He et al. 2017, eq. 8): the paper's `mu` and
//! `lam`, or a Young's modulus and Poisson ratio resolved by a lattice-sum calibration.

use crate::error::{check_param, invalid, Result};

use super::calibration::lattice_moduli;

/// An elastic particle material.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Elastic {
    /// The paper's parameters of eq. 8 (Pa): `mu` weighs the deviatoric term `E_dev`, `lam`
    /// the isotropic term `E_iso`. They are not Lame parameters: under an affine deformation
    /// both terms are pair springs, the model is bond-based and its Poisson ratio is 1/4;
    /// only `2 mu + lam` sets the small-strain stiffness (continuum Young's modulus
    /// `(2 mu + lam) / 6`), and `mu` alone the resistance to non-affine deformation.
    Paper { mu: f64, lam: f64 },
    /// A Young's modulus `e` (Pa) and Poisson ratio `nu` to match in the interior of a body on
    /// a cubic lattice, resolved into `mu = lam` by [`Elastic::resolve`]. The paper's model
    /// has `nu = 1/4` only: any other value is refused.
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
                    return Err(invalid!("mu + lam must be > 0 Pa, got mu = {mu}, lam = {lam}"));
                }
            }
            Self::Young { e, nu } => {
                check_param("E", e, |v| v > 0.0, "a finite Young's modulus > 0 Pa")?;
                check_param("nu", nu, |v| v > -1.0 && v < 0.5, "a Poisson ratio in (-1, 0.5)")?;
                if nu != 0.25 {
                    return Err(invalid!(
                        "nu = {nu}: the particle model (He et al. 2017) is bond-based under \
                         affine deformation and has Poisson's ratio 0.25 whatever mu and lam; \
                         a dilatation term for other ratios is not implemented yet, so only \
                         nu = 0.25 is accepted"
                    ));
                }
            }
        }
        Ok(())
    }

    /// The paper's `(mu, lam)` (Pa) for a body sampled on a cubic lattice of `spacing` (m) with
    /// the horizon `delta` (m). For [`Elastic::Young`], `mu = lam` with `2 mu + lam` chosen so
    /// that the lattice's Young's modulus along a lattice axis is `e`
    /// ([`lattice_moduli`]).
    pub fn resolve(&self, spacing: f64, delta: f64) -> Result<(f64, f64)> {
        self.validate()?;
        match *self {
            Self::Paper { mu, lam } => Ok((mu, lam)),
            Self::Young { e, .. } => {
                let unit = lattice_moduli(spacing, delta)?;
                // E is linear in c = mu + lam / 2; mu = lam gives c = 3 mu / 2.
                let c = e / unit.young;
                let mu = c * 2.0 / 3.0;
                Ok((mu, mu))
            }
        }
    }
}
