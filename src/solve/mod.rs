//! Time stepping: implicit Euler solved by the semi-implicit successive substitution method.

mod clock;
mod contact_step;
mod descent;
mod evaluate;
mod jacobi;
mod params;
mod reaction;
mod sissm;
mod stats;
pub(crate) mod system;

pub use clock::Clock;
pub use params::{Acceleration, Method, SolverParams};
pub use sissm::Solver;
pub use stats::{StepStats, Timings};

#[cfg(test)]
mod tests;
