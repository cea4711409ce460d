//! Evaluating a membrane iterate: the vertex kernel at every vertex, and the variational
//! energy.

use crate::membrane::{evaluate_vertices, Preconditioner};
use crate::real::Real;

use super::system::MembraneSystem;
use crate::parallel::chunked_sum;
use crate::solve::energy::inertial_energy;

/// The vertex kernel at every vertex of the current iterate `y`: per-bond gradients and
/// per-vertex responses (energy, preconditioner block), a SIMD pack of vertices at a time.
pub(crate) fn evaluate<T: Real>(sys: &mut MembraneSystem<T>, mode: Preconditioner) {
    let MembraneSystem {
        nb,
        rest,
        packed,
        points,
        bond_grad,
        response,
        ..
    } = sys;
    evaluate_vertices(
        nb,
        rest,
        packed.as_ref(),
        &points.y,
        mode,
        bond_grad,
        response,
    );
    sys.blocks_fresh = false;
}

/// `E(y) = sum_i m_i |y_i - y*_i|^2 / (2 h^2) + sum_i E_i(y)` (eq. 2 without the barrier, J), from
/// the responses of the last [`evaluate`].
pub(crate) fn total_energy<T: Real>(sys: &mut MembraneSystem<T>, h: T) -> f64 {
    let MembraneSystem {
        points, response, ..
    } = sys;
    let elastic = chunked_sum(response.len(), &mut points.energy_chunks, |i| {
        response[i].energy().to_f64()
    });
    inertial_energy(points, h, false) + elastic
}
