//! Time stepping: implicit Euler solved by the semi-implicit successive substitution method.

pub(crate) mod body;
mod clock;
mod collider_passes;
mod contact_step;
mod descent;
mod evaluate;
mod family;
mod jacobi;
pub(crate) mod membrane_system;
mod params;
mod point_system;
mod points;
mod reaction;
mod sissm;
mod stats;
mod update;

pub use body::{Body, BodyMut};
pub use clock::Clock;
pub use params::{Acceleration, Method, SolverParams};
pub use sissm::Solver;
pub use stats::{StepStats, Timings};

#[cfg(test)]
mod tests;
