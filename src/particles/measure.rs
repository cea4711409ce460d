//! What a particle body measures of itself at its current positions: elastic energy and
//! internal forces (He et al. 2017, eq. 8 and 12), in f64.

use nalgebra::Vector3;

use crate::error::Result;

use super::body::Particles;
use super::kernel::{evaluate_particles, particle_force};
use super::rest::ParticleRest;

/// The kernel's output at a body's current positions.
struct Evaluation {
    rest: ParticleRest<f64>,
    /// Per bond of `rest`, its force term (N).
    bonds: Vec<Vector3<f64>>,
    /// Per particle, `V_i Psi_i` (J).
    energy: Vec<f64>,
}

impl Particles {
    /// The kernel at the current positions: rest data, bond forces and energies per particle.
    fn evaluate_here(&self) -> Result<Evaluation> {
        let rest = ParticleRest::<f64>::of_bodies(&[self])?;
        let mut bonds = vec![Vector3::zeros(); rest.indices.len()];
        let mut energy = vec![0.0; self.num_particles()];
        evaluate_particles(&rest, self.positions(), &mut bonds, &mut energy);
        Ok(Evaluation {
            rest,
            bonds,
            energy,
        })
    }

    /// Elastic energy `sum_i V_i Psi_i` (J, eq. 8) at the current positions.
    pub fn elastic_energy(&self) -> Result<f64> {
        Ok(self.evaluate_here()?.energy.iter().sum())
    }

    /// `V_i Psi_i` of every particle (J).
    pub fn particle_energies(&self) -> Result<Vec<f64>> {
        Ok(self.evaluate_here()?.energy)
    }

    /// Internal force on every particle (N; eq. 12 times `V_i`) at the current positions.
    pub fn internal_forces(&self) -> Result<Vec<Vector3<f64>>> {
        let Evaluation { rest, bonds, .. } = self.evaluate_here()?;
        Ok((0..self.num_particles())
            .map(|i| particle_force(i, &rest, &bonds))
            .collect())
    }
}
