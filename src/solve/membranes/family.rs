//! Membranes as a body family of the time step: what the shared step asks of them.

use crate::membrane::Preconditioner;
use crate::real::Real;
use crate::solve::family::Family;
use crate::solve::points::Points;
use crate::solve::update::{MoveOptions, Update};

use super::evaluate::{evaluate, total_energy};
use super::jacobi::jacobi_update;
use super::system::MembraneSystem;

impl<T: Real> Family<T> for MembraneSystem<T> {
    fn points(&self) -> &Points<T> {
        &self.points
    }
    fn points_mut(&mut self) -> &mut Points<T> {
        &mut self.points
    }
    fn evaluate(&mut self, mode: Preconditioner) {
        evaluate(self, mode);
    }
    fn total_energy(&mut self, h: T) -> f64 {
        total_energy(self, h)
    }
    fn global_move(&mut self, h: T, options: &MoveOptions<'_, T>) -> Update {
        jacobi_update(self, h, options)
    }
}
