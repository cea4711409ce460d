//! The GPU backend: the SISSM time step of [`crate::solve`] as wgpu compute kernels
//! (`shaders/*.wgsl`), in f32 on every adapter and in f64 where the adapter offers
//! SHADER_F64, with the bodies' rest data and iterates resident on the device.
//!
//! - [`gpu_info`] describes the adapter the backend would use (or says what is missing);
//! - [`GpuSolver`] mirrors [`crate::solve::Solver`] step for step: same predictor,
//!   initial guess, kernel, Jacobi update with step length, colliders, Chebyshev extrapolation
//!   and convergence test; the parity tests pin the two implementations together.
//!
//! Buffers are laid out per vertex and per bond (CSR with reverse bonds), so a contact local
//! step can later read and write the same position buffers.

mod device;
mod layout;
mod pass;
mod pipelines;
mod solver;
mod working_set;

pub use device::{gpu_info, GpuInfo};
pub use layout::GpuReal;
pub use solver::{GpuSolver, CHECK_EVERY};

#[cfg(test)]
mod tests;
