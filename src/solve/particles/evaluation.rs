//! One evaluation of the particle kernel: where it was taken, its bond forces, per-particle
//! energies and gathered forces, and the residual of eq. 12 with its merit.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::parallel::chunked_sum;
use crate::particles::{evaluate_energies, evaluate_particles, particle_force, ParticleRest};
use crate::real::Real;
use crate::solve::points::Points;

/// The kernel evaluated at the positions `at`.
pub(crate) struct Evaluation<T: Real> {
    /// The positions (m) of the evaluation; the key that lets a later call at the same
    /// positions skip the kernel.
    pub at: Vec<Vector3<T>>,
    pub valid: bool,
    /// Per bond its force on its particle (N, [`crate::particles::bond_force`]), unless the
    /// evaluation holds the energy alone (`forces` false, [`Self::run_energy`]).
    pub bond_force: Vec<Vector3<T>>,
    forces: bool,
    /// Per particle `V_i Psi_i` (J) and the internal force (N), the latter gathered from the
    /// bond forces only when a residual asks for it (`gathered`): the initial guess reads the
    /// energy alone of the evaluation it does not keep.
    pub energy: Vec<T>,
    force: Vec<Vector3<T>>,
    gathered: bool,
    /// Per particle the residual of eq. 12, `r = m (y* - y) + h^2 f` (kg m; zero at pins).
    pub residual: Vec<Vector3<T>>,
    /// The merit of `residual` (kg m^2) once [`Self::residual_merit`] formed it, until the
    /// kernel runs again or the step's inertial targets change ([`Self::forget_residual`]):
    /// an accepted line-search trial is the next iteration's iterate, whose residual is then
    /// not formed twice.
    merit: Option<f64>,
}

impl<T: Real> Evaluation<T> {
    pub fn new(particles: usize, bonds: usize) -> Self {
        Self {
            at: vec![Vector3::zeros(); particles],
            valid: false,
            bond_force: vec![Vector3::zeros(); bonds],
            forces: false,
            energy: vec![T::zero(); particles],
            force: vec![Vector3::zeros(); particles],
            gathered: false,
            residual: vec![Vector3::zeros(); particles],
            merit: None,
        }
    }

    /// Readies the evaluation for `bonds` bonds (their count changed with the neighbours), in
    /// the allocation at hand; it no longer holds a valid evaluation.
    pub fn resize_bonds(&mut self, bonds: usize) {
        self.bond_force.clear();
        self.bond_force.resize(bonds, Vector3::zeros());
        self.valid = false;
        self.merit = None;
    }

    /// Forgets the residual (at a step's start: its inertial targets `y*`, masses and pins
    /// are the new step's).
    pub fn forget_residual(&mut self) {
        self.merit = None;
    }

    /// Whether this evaluation was taken at `y`, bit for bit, forces and all.
    pub fn is_at(&self, y: &[Vector3<T>]) -> bool {
        self.forces && self.holds_energy_at(y)
    }

    /// Whether this evaluation holds at least the energies at `y`, bit for bit.
    pub fn holds_energy_at(&self, y: &[Vector3<T>]) -> bool {
        self.valid && self.at == y
    }

    /// Whether this evaluation holds its bond forces (not the energy alone).
    pub fn has_forces(&self) -> bool {
        self.valid && self.forces
    }

    /// Runs the kernel at `self.at`: the bond forces and energies (the particles' forces are
    /// gathered by the first [`Self::residual_merit`]).
    pub fn run(&mut self, rest: &ParticleRest<T>) {
        evaluate_particles(rest, &self.at, &mut self.bond_force, &mut self.energy);
        self.gathered = false;
        self.merit = None;
        self.forces = true;
        self.valid = true;
    }

    /// Runs the kernel's energies alone at `self.at` ([`evaluate_energies`]: the bits
    /// [`Self::run`] gives them, no bond force written); rest data without cones only.
    pub fn run_energy(&mut self, rest: &ParticleRest<T>) {
        evaluate_energies(rest, &self.at, &mut self.energy);
        self.gathered = false;
        self.merit = None;
        self.forces = false;
        self.valid = true;
    }

    /// The residual of eq. 12 at `self.at` for the points' inertial targets, `h2 = h^2`
    /// (s^2), into `self.residual`, the internal forces gathered first if they are not yet
    /// (eq. 12, [`particle_force`]); returns the merit `sum_i |r_i|^2 / m_i` (kg m^2) summed
    /// in fixed chunks (the same for any thread count). Formed once per kernel pass and step
    /// (`h2` is the step's): a second call returns the first's merit and leaves the residual.
    pub fn residual_merit(
        &mut self,
        rest: &ParticleRest<T>,
        points: &Points<T>,
        h2: T,
        chunks: &mut Vec<f64>,
    ) -> f64 {
        debug_assert!(self.forces, "a residual of an evaluation without forces");
        if let Some(merit) = self.merit {
            return merit;
        }
        if !self.gathered {
            let bond_force = &self.bond_force;
            self.force
                .par_iter_mut()
                .enumerate()
                .for_each(|(i, f)| *f = particle_force(i, rest, bond_force));
            self.gathered = true;
        }
        let (at, force) = (&self.at, &self.force);
        let (mass, star, pinned) = (&points.mass, &points.y_star, &points.pinned);
        self.residual.par_iter_mut().enumerate().for_each(|(i, r)| {
            *r = if pinned[i] {
                Vector3::zeros()
            } else {
                (star[i] - at[i]) * mass[i] + force[i] * h2
            };
        });
        let residual = &self.residual;
        let merit = chunked_sum(residual.len(), chunks, |i| {
            residual[i].norm_squared().to_f64() / mass[i].to_f64()
        });
        self.merit = Some(merit);
        merit
    }

    /// `sum_i V_i Psi_i` (J) summed in fixed chunks.
    pub fn elastic_energy(&self, chunks: &mut Vec<f64>) -> f64 {
        let energy = &self.energy;
        chunked_sum(energy.len(), chunks, |i| energy[i].to_f64())
    }
}
