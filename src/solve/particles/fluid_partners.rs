//! The solid particles a fluid's density constraints see (He et al. 2017, section 8): the
//! solid particles of a mixed body ([`crate::particles::RegionMaterial`], Fig. 19) and the
//! grains of sand bodies (Fig. 16, "incompressibility for both materials").
//!
//! **Partners.** They join the fluid stage ([`super`]) as members without a constraint of
//! their own: each counts in its fluid neighbours' density sums by its volume, as fluid of
//! the stage's rest density `rho0` (mass `rho0 V_j`, so that `C_i = rho_i / rho0 - 1` is the
//! volume fraction around `i` less 1, whatever the partner's own density), and each fluid
//! constraint moves it by its gradient as it moves a fluid neighbour (the constraints' Jacobi
//! move, equal for every member: the fluid pushes the solid, whose elasticity or friction
//! answers). A fluid particle is thus kept from the solid particles as from its own: it does
//! not pass through a solid half of its body or into a sand bed. Partners are not
//! redistributed and keep their velocity in the viscosity solve (they drag their fluid
//! neighbours as a wall does, with half the fluid's coefficient: the mean of the two
//! particles' `nu V`, the partner's 0). Sand must share the fluids' spacing (the density sums
//! are normalised on one lattice).
//!
//! **Wetting.** [`FluidStage::liquid_fractions`] gives each partner the liquid volume
//! fraction around it, `phi_i = sum_j V_j s W(|y_i - y_j|)` over its fluid neighbours
//! (dimensionless, the lattice-normalised kernel of the constraints: 1 inside a liquid), from
//! which a sand grain's saturation rises ([`crate::particles::wetted`]).

use nalgebra::Vector3;

use crate::error::{invalid, Result};
use crate::particles::Particles;
use crate::real::Real;

use super::FluidStage;

impl<T: Real> FluidStage<T> {
    /// Adds the partners among `bodies` (concatenated in this order in the family): the real
    /// solid particles of every mixed body and every sand body. Nothing when the stage has no
    /// fluid particle. `spacing` (m) is the fluids'; sand of another spacing is refused.
    pub(super) fn add_partners(&mut self, bodies: &[&mut Particles], spacing: f64) -> Result<()> {
        let Some(&rho0) = self.rest_density.first() else {
            return Ok(());
        };
        let mut start = 0u32;
        for body in bodies {
            let n = body.num_particles() as u32;
            let sand = body.granular().is_some();
            if sand && body.params().spacing != spacing {
                return Err(invalid!(
                    "sand and fluids in one solver must share a spacing (their density \
                     constraints see each other): {} m against {spacing} m",
                    body.params().spacing
                ));
            }
            if sand || body.fluid_mask().is_some() {
                let mass = T::of(rho0.to_f64() * body.volume());
                for i in (0..body.num_real()).filter(|&i| !body.is_fluid_particle(i)) {
                    self.members.push(start + i as u32);
                    self.mass.push(mass);
                    self.rest_density.push(rho0);
                    self.nu.push(T::zero());
                    self.eps.push(T::one());
                    self.partner.push(true);
                    self.share.push(T::of(body.particle_mass()));
                }
            }
            start += n;
        }
        Ok(())
    }

    /// Each partner's family index and the liquid volume fraction around it (see the
    /// module's doc) at the positions of the last projection, over that projection's
    /// neighbour lists.
    pub fn liquid_fractions(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        let (offsets, indices) = (&self.offsets, &self.indices);
        (0..self.members.len())
            .filter(|&i| self.partner[i])
            .map(move |i| {
                let y: &Vector3<T> = &self.y[i];
                let phi = indices[offsets[i] as usize..offsets[i + 1] as usize]
                    .iter()
                    .map(|&j| j as usize)
                    .filter(|&j| !self.partner[j])
                    .map(|j| {
                        let volume = self.mass[j] / self.rest_density[j];
                        (volume * self.sph.value((y - self.y[j]).norm())).to_f64()
                    })
                    .fold(0.0, |a, b| a + b);
                (self.members[i] as usize, phi)
            })
    }
}
