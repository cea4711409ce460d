//! Time stepping: implicit Euler solved by the semi-implicit successive substitution method.

pub(crate) mod body;
mod clearance;
mod clock;
mod collider_passes;
mod coupling;
pub(crate) mod energy;
pub(crate) mod families;
pub(crate) mod family;
pub(crate) mod frame;
mod initial_guess;
pub(crate) mod membranes;
mod params;
pub(crate) mod particles;
pub(crate) mod point_system;
pub(crate) mod points;
mod sissm;
mod state;
mod stats;
pub(crate) mod update;

pub use body::{Body, BodyMut};
pub use clock::Clock;
pub use params::{Acceleration, GlobalSolver, Method, SolverParams};
#[cfg(test)]
pub(crate) use sissm::Forget;
pub use sissm::Solver;
pub use state::{SavedGrainContact, SolverState};
pub use stats::{NewtonTimings, ParticleTimings, StepStats, Timings};

#[cfg(test)]
mod restore_tests;
#[cfg(test)]
mod tests;
