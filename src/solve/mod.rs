//! Time stepping: implicit Euler solved by the semi-implicit successive substitution method.

pub(crate) mod body;
mod clock;
mod collider_passes;
pub(crate) mod energy;
pub(crate) mod families;
pub(crate) mod family;
pub(crate) mod membranes;
mod params;
pub(crate) mod point_system;
pub(crate) mod points;
mod sissm;
mod stats;
pub(crate) mod update;

pub use body::{Body, BodyMut};
pub use clock::Clock;
pub use params::{Acceleration, Method, SolverParams};
pub use sissm::Solver;
pub use stats::{StepStats, Timings};

#[cfg(test)]
mod tests;
