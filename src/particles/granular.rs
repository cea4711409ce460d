//! Granular particle material: dry and wet sand (He et al. 2017, section 7, eq. 25-28 as
//! corrected in DESIGN.md section 6).
//!
//! **Stiffness from density (eq. 25-27).** A granular body has no constant moduli: each
//! particle's `lam_i = k_f(rho_i) + k_c(rho_i)` (Pa) follows its density ratio `rho_i / rho_0`
//! (`rho_0` the body's `density`, the packing it was sampled at), and `mu = 0` (the pair
//! springs of `lam` resist shear too). A bond's isotropic spring uses the mean
//! `(lam_i + lam_j) / 2`.
//! - Density (departure): `rho_i / rho_0 = (W(0) + sum_j W(|y_j - y_i|)) / (W(0) + sum_j
//!   W(|X_ij|))`, the poly6 SPH sum ([`super::sph`]) over the particle's neighbours at their
//!   positions over the same sum at its reference vectors `X_ij` (as the return and eq. 20
//!   leave them). Inside the body as sampled that is the SPH density over `rho_0`, as the
//!   paper has it; at a free surface, whose particles miss part of the kernel, the plain SPH
//!   sum reads 0.78 `rho_0` on a flat face at rest, so `k_f = 0` there and a small body's
//!   surface layers (most of a pile a few spacings high) had no friction stiffness at all.
//! - Friction stiffness (eq. 25): `k_f = K_f exp(H_f (rho / rho_0 - 1))` for `rho >= rho_0`,
//!   else 0: grains push on each other only when packed.
//! - Cohesion stiffness (eq. 26, its falloff's sign corrected): `k_c = K_c` for
//!   `rho >= rho_0`, `K_c exp(-H_c (1 - rho / rho_0))` on `[rho_1, rho_0)`, else 0: the
//!   capillary bridges of wet sand hold grains a little apart and break at `rho_1`.
//! - Water saturation `theta` (eq. 27): `H_c = H_0 theta^(-1/2)`, `rho_1 = (1 - b theta)
//!   rho_0`. Dry sand (`theta = 0`) has `rho_1 = rho_0`: no cohesion below `rho_0`.
//!
//! **Friction angle and capillary cohesion (departure).** The yield test of
//! [`super::plasticity`] with the friction angle, the return of eq. 18-19 within the local
//! step ([`super::cone`]) and stored at each step's end, and the neighbours searched anew
//! each step (eq. 20). Dry sand's cone goes through the origin (no
//! tension). Wet sand's cone has the cohesion `c = sigma_t tan(phi)`, its apex at the mean
//! tension `sigma_t` that the cohesion stiffness of eq. 26-27 holds before the capillary
//! bridges break ([`Granular::capillary_strength`]): without it the return relaxes every
//! tension, the cohesion stiffness holds nothing, and wet sand slumped as far as dry (the
//! paper's wet sand has no stated yield law).
//!
//! **Static friction (eq. 28).** After the solve, a particle whose solved position `y'` went
//! back from the inertial target `y*` towards its start `y` by at least `eta` of the way,
//! `(y' - y*) . (y - y*) >= eta |y* - y|^2`, is held where it started (no move, no velocity):
//! the friction of its neighbours held it. Pinned particles are left as they are.
//!
//! **Defaults.** The paper gives no values for `K_f`, `H_f`, `K_c`, `H_0` (the authors' code
//! uses `H_f = 1` and no cohesion): the defaults here are chosen for sand at a few mm
//! spacing at time steps of a few ms, `K_f = 100 kPa` (a continuum Young's modulus
//! `K_f / 6`), `H_f = 10`, `K_c = 20 kPa`, `H_0 = 10`, `b = 1` and `eta = 0.8` (the
//! paper's); the capillary diffusivity of the held water `D = 1e-5 m^2/s`, fine sand's
//! ([`super::wicking`]).
//!
//! **Grains keep apart.** A granular body's particles repel each other as the particles of
//! different bodies do ([`crate::solve`]'s repulsion: balls of half a spacing): its bonds,
//! searched anew every step with reference vectors from the deformed positions, would let
//! grains pass through each other and the sand compact without end.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::error::{check_param, Result};
use crate::real::Real;

use super::plasticity::DruckerPrager;
use super::rest_bonds::RestBonds;
use super::sph::{Kernel, Sph};
use super::wicking::{DEFAULT_WICKING, MAX_WICKING};

/// A granular particle material (see the module's doc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Granular {
    /// Internal friction angle `phi` (degrees, in (0, 90)).
    pub friction_angle: f64,
    /// Water saturation `theta` (dimensionless, in [0, 1]; 0 is dry sand).
    pub saturation: f64,
    /// Reference friction stiffness `K_f` (Pa, > 0) of eq. 25.
    pub friction_stiffness: f64,
    /// Hardening coefficient `H_f` (dimensionless, >= 0) of eq. 25.
    pub friction_hardening: f64,
    /// Reference cohesion stiffness `K_c` (Pa, >= 0) of eq. 26.
    pub cohesion_stiffness: f64,
    /// Reference falloff coefficient `H_0` (dimensionless, > 0) of eq. 27.
    pub cohesion_falloff: f64,
    /// Debonding scale `b` (dimensionless, in [0, 1]) of eq. 27.
    pub debonding: f64,
    /// Static friction coefficient `eta` of eq. 28 (dimensionless, in (0, 1]), or `None`
    /// for none.
    pub static_friction: Option<f64>,
    /// Coulomb friction coefficient `mu_c` (dimensionless, >= 0) at the contacts of touching
    /// grains (`crate::solve`'s grain friction; 0: frictionless balls, the default).
    pub contact_friction: f64,
    /// Rolling resistance `mu_r` (dimensionless, >= 0) of the grains, which then turn within
    /// each step until their contacts' friction torque lies within `mu_r` times their radius
    /// times their contacts' normal loads (`crate::solve`'s grain rolling; 0: they roll
    /// freely), or `None` (the default): the grains do not turn, and resist rolling without
    /// bound. Needs `contact_friction > 0` (a `ValueError` without: nothing to turn against).
    pub rolling_resistance: Option<f64>,
    /// Capillary diffusivity `D` (m^2/s, in [0, [`MAX_WICKING`]]) of the water the grains
    /// hold, which wicks from grain to grain ([`super::wicking`]; 0: none).
    pub wicking: f64,
}

impl Granular {
    /// Dry or wet sand with the friction angle `phi` (degrees) and the water saturation
    /// `theta`, every other parameter at its default (see the module's doc).
    pub fn new(friction_angle: f64, saturation: f64) -> Self {
        Self {
            friction_angle,
            saturation,
            friction_stiffness: 1e5,
            friction_hardening: 10.0,
            cohesion_stiffness: 2e4,
            cohesion_falloff: 10.0,
            debonding: 1.0,
            static_friction: Some(0.8),
            contact_friction: 0.0,
            rolling_resistance: None,
            wicking: DEFAULT_WICKING,
        }
    }

    /// Checks the parameters, naming the bad one.
    pub fn validate(&self) -> Result<()> {
        check_param(
            "friction_angle",
            self.friction_angle,
            |v| v > 0.0 && v < 90.0,
            "an angle in (0, 90) degrees",
        )?;
        check_param(
            "saturation",
            self.saturation,
            |v| (0.0..=1.0).contains(&v),
            "a water saturation in [0, 1]",
        )?;
        check_param(
            "friction_stiffness",
            self.friction_stiffness,
            |v| v > 0.0,
            "a finite stiffness > 0 Pa",
        )?;
        check_param(
            "friction_hardening",
            self.friction_hardening,
            |v| v >= 0.0,
            "a finite coefficient >= 0",
        )?;
        check_param(
            "cohesion_stiffness",
            self.cohesion_stiffness,
            |v| v >= 0.0,
            "a finite stiffness >= 0 Pa",
        )?;
        check_param(
            "cohesion_falloff",
            self.cohesion_falloff,
            |v| v > 0.0,
            "a finite coefficient > 0",
        )?;
        check_param(
            "debonding",
            self.debonding,
            |v| (0.0..=1.0).contains(&v),
            "a scale in [0, 1]",
        )?;
        check_param(
            "contact_friction",
            self.contact_friction,
            |v| v >= 0.0,
            "a finite coefficient >= 0",
        )?;
        check_param(
            "wicking",
            self.wicking,
            |v| (0.0..=MAX_WICKING).contains(&v),
            "a capillary diffusivity in [0, 0.01] m^2/s",
        )?;
        if let Some(mu_r) = self.rolling_resistance {
            check_param(
                "rolling_resistance",
                mu_r,
                |v| v >= 0.0,
                "a finite coefficient >= 0 (or None for none)",
            )?;
            if self.contact_friction == 0.0 {
                return Err(crate::error::invalid!(
                    "rolling_resistance {mu_r} needs contact_friction > 0: the grains turn \
                     against their contacts' friction, which frictionless grains have none of"
                ));
            }
        }
        if let Some(eta) = self.static_friction {
            check_param(
                "static_friction",
                eta,
                |v| v > 0.0 && v <= 1.0,
                "a coefficient in (0, 1] (or None for none)",
            )?;
        }
        Ok(())
    }

    /// The yield law of the material: the friction angle, the capillary cohesion
    /// `c = sigma_t tan(phi)` of wet sand (the cone's apex at the mean tension `sigma_t` =
    /// [`Self::capillary_strength`]; 0 for dry sand), no hardening, the neighbours searched
    /// anew every step.
    pub fn yield_law(&self) -> DruckerPrager {
        DruckerPrager {
            friction_angle: self.friction_angle,
            cohesion: self.capillary_strength() * self.friction_angle.to_radians().tan(),
            hardening: 0.0,
            rebuild_neighbours: true,
        }
    }

    /// The debonding density ratio `rho_1 / rho_0 = 1 - b theta` (eq. 27).
    pub fn debonding_ratio(&self) -> f64 {
        1.0 - self.debonding * self.saturation
    }

    /// Friction stiffness `k_f` (Pa) at the density ratio `r = rho / rho_0` (eq. 25).
    pub fn friction(&self, r: f64) -> f64 {
        if r >= 1.0 {
            self.friction_stiffness * (self.friction_hardening * (r - 1.0)).exp()
        } else {
            0.0
        }
    }

    /// Cohesion stiffness `k_c` (Pa) at the density ratio `r = rho / rho_0` (eq. 26-27, the
    /// falloff's sign corrected).
    pub fn cohesion(&self, r: f64) -> f64 {
        if r >= 1.0 {
            self.cohesion_stiffness
        } else if r >= self.debonding_ratio() && self.saturation > 0.0 {
            let falloff = self.cohesion_falloff / self.saturation.sqrt();
            self.cohesion_stiffness * (-falloff * (1.0 - r)).exp()
        } else {
            0.0
        }
    }

    /// The tensile strength of wet sand's capillary bonds (Pa): the largest mean tension
    /// `k_c(r) (1 - r) / 9` the cohesion stiffness holds as the density ratio `r` falls from
    /// 1 to the debonding ratio (a dilatation `1 - r` under the bulk modulus `k_c / 9` of the
    /// pair springs, [`super::plasticity`]), at `1 - r = min(1 / H_c, b theta)`; 0 for dry
    /// sand.
    pub fn capillary_strength(&self) -> f64 {
        if self.saturation == 0.0 || self.debonding == 0.0 {
            return 0.0;
        }
        let falloff = self.cohesion_falloff / self.saturation.sqrt();
        let x = (1.0 / falloff).min(1.0 - self.debonding_ratio());
        self.cohesion(1.0 - x) * x / 9.0
    }

    /// `lam = k_f + k_c` (Pa) at the density ratio `r`.
    pub fn stiffness(&self, r: f64) -> f64 {
        self.friction(r) + self.cohesion(r)
    }
}

/// Eq. 28 for one particle: whether its solved position `y` (m) went back from the inertial
/// target `star` towards its start `start` by at least `eta` of the way (then static
/// friction holds it at `start`). A particle whose target is its start (no motion to stop)
/// is not held.
#[inline]
pub fn holds<T: Real>(eta: f64, y: &Vector3<T>, start: &Vector3<T>, star: &Vector3<T>) -> bool {
    let back = start - star;
    let reach = back.norm_squared();
    reach > T::zero() && (y - star).dot(&back) >= T::of(eta) * reach
}

/// Every particle's density over the reference density, `rho_i / rho_0` (dimensionless), at
/// the positions `y` (m) with the neighbours and reference vectors of `bonds`: the poly6 SPH
/// sum over the horizon `delta` (m) at `y`, over the same sum at the particle's reference
/// vectors `X` (both with the self term; see the module's doc, "Density"). `volume` is the
/// particle volume (m^3).
pub(crate) fn density_ratios(
    bonds: &RestBonds,
    y: &[Vector3<f64>],
    delta: f64,
    volume: f64,
) -> Result<Vec<f64>> {
    let sph = Sph::new(Kernel::Poly6, delta)?;
    // Volumes as masses (the scale cancels in the ratio).
    let volumes = vec![volume; y.len()];
    let mut out = vec![0.0; y.len()];
    sph.densities(y, &bonds.offsets, &bonds.indices, &volumes, &mut out);
    out.par_iter_mut().enumerate().for_each(|(i, ratio)| {
        let packed = sph.value(0.0)
            + bonds
                .row(i)
                .map(|b| sph.value(bonds.xi[b].norm()))
                .sum::<f64>();
        *ratio /= volume * packed;
    });
    Ok(out)
}

impl Granular {
    /// `lam_i` (Pa) of every particle at the density ratios `ratios`.
    pub(crate) fn stiffness_of(&self, ratios: &[f64]) -> Vec<f64> {
        ratios.iter().map(|&r| self.stiffness(r)).collect()
    }

    /// `lam_i` (Pa) of every particle at the positions `y` (m) with the neighbours of
    /// `bonds`, the horizon `delta` (m) and the particle volume `volume` (m^3).
    pub(crate) fn particle_stiffness(
        &self,
        bonds: &RestBonds,
        y: &[Vector3<f64>],
        delta: f64,
        volume: f64,
    ) -> Result<Vec<f64>> {
        Ok(self.stiffness_of(&density_ratios(bonds, y, delta, volume)?))
    }
}

#[cfg(test)]
#[path = "granular_tests.rs"]
mod tests;
