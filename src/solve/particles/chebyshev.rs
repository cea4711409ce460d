//! The particle family's own Chebyshev sequence (Wang 2015; He et al. 2017 use it for the
//! Jacobi global step), so that its line search can restart it
//! ([`super::step`]): the extrapolation weights `omega_k` of [`Acceleration::omega`], counted
//! from the step's start or from the last restart, and the merit where the sequence started.
//!
//! The semi-iterative method bounds each eigencomponent of the error by its size where the
//! sequence started, times a factor that falls with `k`; the residual merit between two
//! iterates may grow on the way. So an extrapolated iterate is judged against the merit at the
//! sequence's start, not the previous iterate's: a growth beyond [`GROWTH`] times that merit is
//! a sign of divergence (a nonlinearity or a collider the linear theory does not see), and the
//! sequence restarts from the plain move.

use crate::real::Real;
use crate::solve::{Acceleration, SolverParams};

/// How far the merit of an extrapolated iterate may grow over the merit where the sequence
/// started (the merit weighs particles by `1 / m_i` where the Jacobi sweep weighs them by
/// `1 / D_i`, whose ratio varies some fourfold between a body's interior and its corners).
pub const GROWTH: f64 = 4.0;

/// The state of the sequence during a step.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Chebyshev {
    acceleration: Acceleration,
    /// False with membrane contact, whose extrapolation follows the local step (the shared
    /// loop's, [`crate::solve::collider_passes::extrapolate_local_step`]).
    allowed: bool,
    /// Iterations since the (re)start and the last weight (1 for a plain iteration).
    k: usize,
    previous: f64,
    /// The merit (kg m^2) at the iterate the sequence started from.
    pub start_merit: f64,
}

impl Default for Chebyshev {
    fn default() -> Self {
        Self {
            acceleration: Acceleration::None,
            allowed: false,
            k: 0,
            previous: 1.0,
            start_merit: f64::INFINITY,
        }
    }
}

impl Chebyshev {
    /// The sequence of a new step with the solver's parameters.
    pub fn start(params: &SolverParams) -> Self {
        Self {
            acceleration: params.global_solver.acceleration(params),
            allowed: params.contact.is_none(),
            ..Self::default()
        }
    }

    /// The weight of this iteration (`None`: plain), whose iterate has the merit `merit`
    /// (kg m^2), and advances the count.
    pub fn next<T: Real>(&mut self, merit: f64) -> Option<T> {
        if !self.allowed {
            return None;
        }
        if self.k == 0 {
            self.start_merit = merit;
        }
        let omega = self.acceleration.omega(self.k, self.previous);
        self.previous = omega.unwrap_or(1.0);
        self.k += 1;
        omega.map(T::of)
    }

    /// Restarts the sequence: the next iteration is its first (plain).
    pub fn restart(&mut self) {
        self.k = 0;
        self.previous = 1.0;
    }
}
