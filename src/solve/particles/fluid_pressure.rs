//! A liquid's pressure field, read off the density projection of the last step (no pass of
//! its own): the moves `dy = W J^T lambda` of the step's passes (Macklin and Mueller 2013,
//! eq. 12, the multipliers `lambda` summed over the passes, [`FluidStage`]'s `impulse`) are
//! those of the constraint forces `F_k = m_k dy_k / h^2 = m_ref sum_i lambda_i grad_k C_i /
//! h^2` (N). An SPH pressure `q_i` (Pa) on the volume `V_i = m_i / rho*_i` of each
//! constraint `C_i = rho_i / rho*_i - 1` exerts `F_k = -sum_i q_i V_i grad_k C_i`, so `q_i =
//! -w_i rho*_i lambda_i / h^2` (`rho*_i` the constraint's rest density, kg/m^3: `rho0`, or
//! an adhered ghost's at rest; `w_i = m_ref / m_i` the member's share; `h` the step, s).
//!
//! **The pressure is `p_i = kappa q_i`.** For a pressure varying linearly in space that sum
//! is `F_k = -kappa V grad p` on the rest lattice, not the continuum's `-V grad p`: `kappa =
//! -sum_r V r . grad W(r) / 3` over the lattice's offsets `r` ([`gradient_scale`]; 1 for the
//! continuous kernel, by parts; 0.817 for the spiky kernel of 2.2 spacings normalised on the
//! lattice's density sum). So a liquid at rest under gravity balances its weight with `q =
//! rho g d / kappa`, and `kappa q` is the pressure whose gradient the forces are, the one
//! walls and a hydrostatic column read (docs/particles/fluids.md, round y2).
//!
//! Jacobi's one-sided passes only push, so its pressure is never negative but at an adhered
//! ghost, whose constraint also pulls; the conjugate gradients hold their active set as
//! equalities, so a row's multiplier may pull within a linearisation. The pressure is zero
//! where no constraint acted (a particle lighter than its rest density, such as most of a
//! free surface's, and partners).

use std::ops::Range;

use crate::particles::sph::Sph;
use crate::particles::{lattice_sum, Particles};
use crate::real::Real;

use super::FluidStage;

/// `kappa = -sum_r V r . grad W(r) / 3` (dimensionless) over the offsets `r` (m) of the
/// simple cubic lattice of `spacing` (m) within the support of `sph`, `V = spacing^3`: the
/// factor by which the SPH gradient of a linear field on the rest lattice falls short of the
/// field's gradient (see the module's doc).
pub(super) fn gradient_scale(sph: &Sph, spacing: f64) -> f64 {
    let volume = spacing.powi(3);
    -lattice_sum(sph.radius, spacing, |r| r.dot(&sph.gradient(&r))) * volume / 3.0
}

impl<T: Real> FluidStage<T> {
    /// Per fluid member (partners aside), its family index and the pressure of its density
    /// constraint over the last step (Pa; see the module's doc).
    pub fn pressures(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        let inv_h2 = if self.h > T::zero() {
            self.pressure_scale / (self.h * self.h).to_f64()
        } else {
            0.0
        };
        (self.members.iter().zip(&self.impulse))
            .zip(self.target.iter().zip(&self.share))
            .zip(&self.partner)
            .filter(|(_, &partner)| !partner)
            .map(move |(((&k, &sum), (&rest, &share)), _)| {
                (k as usize, -(share * rest * sum).to_f64() * inv_h2)
            })
    }

    /// Writes the pressures of the last step into the bodies holding fluid members (into
    /// their own allocations; `ranges`: each body's family indices), after zeroing every
    /// field a body of the family holds (a region no longer fluid holds no pressure).
    pub fn store_pressures(&self, ranges: &[Range<usize>], bodies: &mut [&mut Particles]) {
        for body in bodies.iter_mut() {
            body.clear_pressure();
        }
        for (k, p) in self.pressures() {
            if let Some(b) = ranges.iter().position(|r| r.contains(&k)) {
                bodies[b].pressure_mut()[k - ranges[b].start] = p;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::gradient_scale;
    use crate::particles::sph::{Kernel, Sph};
    use crate::particles::FLUID_SUPPORT;

    /// The fluids' kernel falls 18 % short of the continuum's gradient on the lattice, and
    /// a kernel wide in spacings comes within 1 % of it (`kappa -> 1`: by parts, `-int r .
    /// grad W dV = 3 int W dV`, and the normalisation makes the lattice's `sum V W` one).
    #[test]
    fn the_gradient_scale_is_the_fluid_kernels_and_tends_to_one() {
        let s = 0.01;
        let fluid = Sph::on_lattice(Kernel::Spiky, FLUID_SUPPORT * s, s).unwrap();
        let kappa = gradient_scale(&fluid, s);
        assert!((kappa - 0.8169).abs() < 1e-4, "{kappa}");
        let wide = Sph::on_lattice(Kernel::Spiky, 8.0 * s, s).unwrap();
        let kappa = gradient_scale(&wide, s);
        assert!((kappa - 1.0).abs() < 0.01, "{kappa}");
    }
}
