//! What a body kind plugs into the time step: a family holds the points of every body of its
//! kind ([`Points`]) with their rest data, and computes what the shared step asks of it.
//!
//! The step ([`super::sissm`]) runs its phases over every family: predict and finish on the
//! points, the global step through [`Family::evaluate`] and [`Family::global_move`], colliders
//! on the points, then the kind's own end-of-step work ([`Family::end_step`]). Membranes are
//! the first family ([`MembraneSystem`](super::membranes::MembraneSystem)); a new kind
//! implements this trait and adds a field to [`Families`](super::families::Families).

use crate::error::Result;
use crate::membrane::Preconditioner;
use crate::real::Real;

use super::energy::inertial_energy;
use super::points::Points;
use super::update::{MoveOptions, Update};
use super::{Acceleration, SolverParams, Timings};

/// A body kind's part of the time step.
pub(crate) trait Family<T: Real>: Send {
    fn points(&self) -> &Points<T>;
    fn points_mut(&mut self) -> &mut Points<T>;
    /// The per-element kernel at the current iterate `y`: the forces, elastic energies and
    /// preconditioner blocks that the next [`Self::global_move`] and
    /// [`Self::total_energy`] read (`mode` picks the membrane kernel's preconditioner).
    fn evaluate(&mut self, mode: Preconditioner);
    /// [`Self::evaluate`] for a caller that reads [`Self::total_energy`] alone before it
    /// evaluates elsewhere or moves (the initial guess's prediction): a family may leave the
    /// rest to the next [`Self::evaluate`] or [`Self::global_move`], which completes it. The
    /// whole evaluation by default.
    fn evaluate_energy(&mut self, mode: Preconditioner) {
        self.evaluate(mode);
    }
    /// `E(y) = sum_i m_i |y_i - y*_i|^2 / (2 h^2) + U(y)` (J; Lu et al. 2023, eq. 2 without
    /// the barrier) from the last [`Self::evaluate`], `h` in s.
    fn total_energy(&mut self, h: T) -> f64;
    /// The inertial term of [`Self::total_energy`] at `y_t` (J).
    fn inertial_energy_at_start(&mut self, h: T) -> f64 {
        inertial_energy(self.points_mut(), h, true)
    }
    /// Whether the initial guess also weighs the coast `y_t + h v_t` where a collider pushed the
    /// prediction `y*` ([`super::initial_guess`]): the particles do; membranes, whose
    /// steps on colliders were not measured with it, do not.
    fn coasts(&self) -> bool {
        false
    }
    /// One preconditioned global move `y -> y_next` (eq. 25 in residual form, with the step
    /// length of eq. 31-33, colliders in the system metric and Chebyshev extrapolation as
    /// `options` ask), and its measures.
    fn global_move(&mut self, h: T, options: &MoveOptions<'_, T>) -> Update;
    /// Whether [`Self::global_move`] leaves `y_next` out of the colliders itself, so that the
    /// step's own collider pass leaves it alone (the particles evaluate their line search's
    /// trials at `y_next`: moving it again would cost them a kernel pass).
    fn keeps_out_of_colliders(&self) -> bool {
        false
    }
    /// The threshold (m) this family's convergence measure must fall below for the step to
    /// stop (both families' must): `tol` for membranes.
    fn threshold(&self, params: &SolverParams) -> f64 {
        params.tol
    }
    /// Work before the iterations of a step, once its state is loaded and predicted (the
    /// particles factor their direct solver's matrix here). Nothing for membranes.
    fn start_step(&mut self, _params: &SolverParams) -> Result<()> {
        Ok(())
    }
    /// The ms of [`Self::start_step`] that the family reports under other phases of the
    /// step's timings (the fluids' neighbour search and viscosity), so that the prediction's
    /// time leaves them out. None for membranes.
    fn start_millis_timed_elsewhere(&self) -> f64 {
        0.0
    }
    /// The acceleration this kind's moves use under `params` (see
    /// [`super::GlobalSolver::acceleration`] for the particles).
    fn acceleration(&self, params: &SolverParams) -> Acceleration {
        params.acceleration
    }
    /// Work after the iterations of a step and before its velocities are taken, `h` the
    /// step (s): position projections (the fluids' density constraints,
    /// [`super::particles`]). Nothing by default.
    fn project(
        &mut self,
        _h: T,
        _colliders: &[crate::collider::ColliderModel<T>],
        _timings: &mut Timings,
    ) -> Result<()> {
        Ok(())
    }
    /// Work at the end of a converged or finished step, after `finish` and before the state
    /// goes back to the bodies: where plasticity updates rest shapes and neighbourhoods are
    /// rebuilt. Nothing for membranes.
    fn end_step(&mut self, _timings: &mut Timings) -> Result<()> {
        Ok(())
    }
    /// Adds this kind's own figures of the step to `stats` (and starts them afresh). Nothing
    /// for membranes, whose figures the step measures itself.
    fn report(&mut self, _stats: &mut super::StepStats) {}
}
