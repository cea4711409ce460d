//! peridyn: projective peridynamics for thin hyperelastic membranes (Lu et al. 2023) and
//! elastoplastic particle materials (He et al. 2017).
//!
//! The core is plain Rust (testable with `cargo test`); the Python bindings live in
//! `src/python` behind the `python` feature, which maturin enables.

// The Rust documentation is for the engineers of the core and documents the private items
// (`.cargo/config.toml`), so a public item's doc may link to a private one.
#![allow(rustdoc::private_intra_doc_links)]

pub mod collider;
pub mod contact;
pub mod error;
pub mod geometry;
pub mod gpu;
pub mod isa;
pub mod material;
pub mod membrane;
pub mod mesh;
pub mod parallel;
pub mod particles;
pub mod point_state;
pub mod real;
pub mod solve;
mod sparse_llt;
pub mod symmetric;
#[cfg(test)]
mod test_rng;
mod timing;

#[cfg(feature = "python")]
mod python;

#[cfg(feature = "python")]
use pyo3::prelude::*;

/// The compiled module `peridyn._core`.
#[cfg(feature = "python")]
#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    python::register(m)
}
