//! Sand wetted by a liquid (He et al. 2017, section 8, Fig. 16: "the interaction between a
//! viscous liquid and wet sands"). The paper keeps the water saturation `theta` of eq. 27 a
//! constant of the material; here (a departure: the paper gives no rule) each grain's
//! saturation rises where liquid reaches it, and with it the grain's cohesion.
//!
//! **Rule.** After each step, a grain with the liquid volume fraction `phi` around it (the
//! lattice-normalised SPH sum of the liquid particles' volumes, dimensionless: 1 inside a
//! liquid; `crate::solve::particles::fluid::partners`) takes the saturation
//! `theta <- max(theta, min(1, phi / WETTING_FRACTION))`. The kernel (spiky, 2.2 spacings)
//! is peaked: under liquid standing on a flat sand face, the face's grains see
//! `phi = 0.1475`, the layer below `0.0003`, so the liquid saturates the layer of grains it
//! touches, which it keeps saturated while it stays (a ponded face); from there the held
//! water wicks into the sand by capillary diffusion ([`super::wicking`]), which conserves
//! it. **Departure: no absorption.** The water the face's grains take is not taken from the
//! liquid, which keeps its particles and their volume: a body's particle count and its
//! particles' mass (`density spacing^3`, one per body) are fixed for the life of the body
//! (the working sets, the global matrix and the state files are built on them), so a
//! liquid particle can neither be removed nor shrink.
//!
//! **Cohesion.** A grain's saturation enters its own stiffness (eq. 26-27: `H_c = H_0
//! theta^-1/2`, `rho_1 = (1 - b theta) rho_0`) and its yield law's capillary cohesion
//! ([`Granular::yield_law`]), as the body's saturation does for uniformly wet sand.

use nalgebra::Vector3;

use crate::error::Result;

use super::granular::{density_ratios, Granular};
use super::rest_bonds::RestBonds;

/// The liquid volume fraction around a grain at which it is saturated (dimensionless): a
/// grain of a flat sand face with liquid on the lattice sites above it sees 0.1475 (the
/// lattice sum of the normalised spiky kernel of support 2.2 spacings over the half space
/// one spacing up), so such a grain is saturated.
pub const WETTING_FRACTION: f64 = 0.14;

/// A grain's saturation after the liquid volume fraction `phi` around it, from `theta` (see
/// the module's doc).
pub fn wetted(theta: f64, phi: f64) -> f64 {
    theta.max((phi / WETTING_FRACTION).min(1.0))
}

impl Granular {
    /// The material at the saturation `theta` (dimensionless, in [0, 1]).
    pub fn at_saturation(&self, theta: f64) -> Self {
        Self {
            saturation: theta,
            ..*self
        }
    }

    /// `lam_i` (Pa) of every particle at the density ratios `ratios` and the saturations
    /// `theta` (one per particle).
    pub(crate) fn wet_stiffness_of(&self, ratios: &[f64], theta: &[f64]) -> Vec<f64> {
        ratios
            .iter()
            .zip(theta)
            .map(|(&r, &t)| self.at_saturation(t).stiffness(r))
            .collect()
    }

    /// [`Self::wet_stiffness_of`] at the positions `y` (m) with the neighbours of `bonds`, the
    /// horizon `delta` (m) and the particle volume `volume` (m^3).
    pub(crate) fn wet_particle_stiffness(
        &self,
        bonds: &RestBonds,
        y: &[Vector3<f64>],
        delta: f64,
        volume: f64,
        theta: &[f64],
    ) -> Result<Vec<f64>> {
        Ok(self.wet_stiffness_of(&density_ratios(bonds, y, delta, volume)?, theta))
    }

    /// The yield law's cohesion (Pa) of each particle at the saturations `theta`.
    pub(crate) fn cohesions(&self, theta: &[f64]) -> Vec<f64> {
        theta
            .iter()
            .map(|&t| self.at_saturation(t).yield_law().cohesion)
            .collect()
    }
}
