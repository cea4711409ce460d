//! A membrane body: its validated mesh, parameters, rest data and state, and the per-vertex
//! kernel that turns positions into energy, forces and the SISSM preconditioner.

mod body;
mod device_copy;
mod hessian;
mod kernel;
mod packed;
mod rest;

pub use body::{internal_force, EnergyTerms, Membrane, MembraneParams};
pub use device_copy::{DeviceCopy, Fetch};
pub use hessian::{hessian_diagonal_block, vertex_hessian_blocks};
pub use kernel::{
    bond_vectors, vertex_kernel, Deformation, GatheredResponse, Preconditioner, VertexResponse,
};
pub use packed::{evaluate_vertices, PackedRest};
pub use rest::{BondRest, Frame, RestData, RestSource, Stencil, VertexConstants, VertexRest};

#[cfg(test)]
mod tests;
