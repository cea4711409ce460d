//! Particle bodies as a body family of the time step: what the shared step asks of them.

use nalgebra::Vector3;

use crate::collider::ColliderModel;
use crate::error::Result;
use crate::membrane::Preconditioner;
use crate::real::Real;
use crate::solve::energy::inertial_energy;
use crate::solve::family::Family;
use crate::solve::points::Points;
use crate::solve::update::{MoveOptions, Update};
use crate::solve::{Acceleration, GlobalSolver, ParticleTimings, SolverParams, StepStats, Timings};

use super::chebyshev::Chebyshev;
use super::directions::prepare_two_level;
use super::step::{global_move, prepare_direct};
use super::system::ParticleSystem;

impl<T: Real> Family<T> for ParticleSystem<T> {
    fn points(&self) -> &Points<T> {
        &self.points
    }
    fn points_mut(&mut self) -> &mut Points<T> {
        &mut self.points
    }
    /// The particle kernel at `y` (the membranes' preconditioner mode does not apply).
    fn evaluate(&mut self, _mode: Preconditioner) {
        ParticleSystem::evaluate(self);
    }
    /// The energies alone where the last initial guess's prediction was not kept
    /// ([`ParticleSystem::evaluate_energy`]).
    fn evaluate_energy(&mut self, _mode: Preconditioner) {
        ParticleSystem::evaluate_energy(self);
    }
    /// `sum_i m_i |y_i - y*_i|^2 / (2 h^2) + sum_i V_i Psi_i(y)` (J; eq. 8 for the elastic
    /// part, which the deviatoric force is not the gradient of: see
    /// [`super::step`] for the merit the line search uses instead).
    fn total_energy(&mut self, h: T) -> f64 {
        inertial_energy(&mut self.points, h, false) + self.current.elastic_energy(&mut self.chunks)
    }
    /// A body sliding on a collider starts from its coast ([`crate::solve::initial_guess`]).
    fn coasts(&self) -> bool {
        true
    }
    fn global_move(&mut self, h: T, options: &MoveOptions<'_, T>) -> Update {
        self.complete();
        global_move(self, h, options)
    }
    /// The line search's trials are the next iterates, kept out of the colliders there.
    fn keeps_out_of_colliders(&self) -> bool {
        true
    }
    /// `min(tol, particle_tol h^2)` ([`SolverParams::particle_threshold`]).
    fn threshold(&self, params: &SolverParams) -> f64 {
        params.particle_threshold()
    }
    /// Readies the direct solver or the two-level correction when it is asked for; the fluids' viscosity acts on the
    /// velocities before the prediction ([`super::fluid`]).
    fn start_step(&mut self, params: &SolverParams) -> Result<()> {
        self.timings = ParticleTimings::default();
        self.chebyshev = Chebyshev::start(params);
        self.exact.forget();
        self.current.forget_residual();
        self.trial.forget_residual();
        // Which particles a collider or the repulsion moved is the step's own: the coarse step
        // ([`super::coarse`]) must not read the last step's, which no state file holds (a run
        // continued from one would part from the run that went on).
        self.touched.fill(false);
        match params.global_solver {
            GlobalSolver::Direct => prepare_direct(self)?,
            GlobalSolver::Jacobi | GlobalSolver::Chebyshev if params.particle_two_level => {
                prepare_two_level(self)?
            }
            GlobalSolver::Jacobi | GlobalSolver::Chebyshev => self.two_level = None,
            GlobalSolver::Position => {}
        }
        if let Some(fluid) = &mut self.fluid {
            let gravity = Vector3::from(params.gravity).map(T::of);
            fluid.start_step(&mut self.points, T::of(params.dt), gravity)?;
        }
        if let Some(repulsion) = &mut self.repulsion {
            repulsion.start_step(&self.points, params.dt, params.gravity)?;
        }
        if let Some(friction) = &mut self.static_friction {
            friction.start_step(&self.points);
        }
        if let Some(plastic) = &mut self.plastic {
            plastic.start_step(params.dt);
            self.rest.set_step(params.dt);
        }
        Ok(())
    }
    fn start_millis_timed_elsewhere(&self) -> f64 {
        self.fluid
            .as_ref()
            .map_or(0.0, |fluid| fluid.start_millis())
    }
    /// The fluids' neighbour search and density projection ([`super::fluid`]).
    fn project(
        &mut self,
        h: T,
        colliders: &[ColliderModel<T>],
        timings: &mut Timings,
    ) -> Result<()> {
        if let Some(fluid) = &mut self.fluid {
            fluid.project(&mut self.points, h, colliders, timings)?;
            self.timings.density_passes = fluid.passes;
            self.timings.density_error = fluid.error;
        }
        Ok(())
    }
    /// A failure of the direct solver's factorisation during the step, else the fluids'
    /// redistribution taken out of their velocities and the wetting of sand they reach, then
    /// plasticity, static friction and changing neighbourhoods
    /// ([`super::fluid`], [`super::plastic`], [`super::static_friction`]).
    fn end_step(&mut self, timings: &mut Timings) -> Result<()> {
        if let Some(failure) = self.failure.take() {
            return Err(failure);
        }
        if let Some(fluid) = &mut self.fluid {
            fluid.end_step(&mut self.points);
            if let Some(plastic) = &mut self.plastic {
                plastic.wet(fluid.liquid_fractions());
            }
        }
        self.plastic_end_step(timings)
    }
    fn report(&mut self, stats: &mut StepStats) {
        self.count_factorizations();
        stats.particles = std::mem::take(&mut self.timings);
    }
    fn acceleration(&self, params: &SolverParams) -> Acceleration {
        params.global_solver.acceleration(params)
    }
}
