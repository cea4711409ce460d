//! Evaluating an iterate: the vertex kernel at every vertex, and the variational energy.

use rayon::prelude::*;

use crate::membrane::{evaluate_vertices, Preconditioner};
use crate::real::Real;

use super::membrane_system::MembraneSystem;
use super::points::Points;

/// The vertex kernel at every vertex of the current iterate `y`: per-bond gradients and
/// per-vertex responses (energy, preconditioner block), a SIMD pack of vertices at a time.
pub(super) fn evaluate<T: Real>(sys: &mut MembraneSystem<T>, mode: Preconditioner) {
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
}

/// Vertices per partial sum of the energy reductions: fixed, so that the sums do not depend
/// on the number of threads.
const ENERGY_CHUNK: usize = 4096;

/// `sum_i term(i)` for `i < n`, summed in fixed chunks (the same for any thread count) whose
/// partial sums go to the reused `scratch`.
fn chunked_sum(n: usize, scratch: &mut Vec<f64>, term: impl Fn(usize) -> f64 + Sync) -> f64 {
    (0..n.div_ceil(ENERGY_CHUNK))
        .into_par_iter()
        .map(|c| {
            (c * ENERGY_CHUNK..((c + 1) * ENERGY_CHUNK).min(n))
                .map(&term)
                .sum::<f64>()
        })
        .collect_into_vec(scratch);
    scratch.iter().sum()
}

/// `sum_i m_i |x_i - y*_i|^2 / (2 h^2)` (J) over free points, for `x` = `y_start` when
/// `at_start`, else `y`.
pub(super) fn inertial_energy<T: Real>(points: &mut Points<T>, h: T, at_start: bool) -> f64 {
    let inv_2h2 = 0.5 / (h.to_f64() * h.to_f64());
    let Points {
        y,
        y_start,
        y_star,
        pinned,
        mass,
        energy_chunks,
        ..
    } = points;
    let x = if at_start { &*y_start } else { &*y };
    chunked_sum(x.len(), energy_chunks, |i| {
        if pinned[i] {
            0.0
        } else {
            (x[i] - y_star[i]).norm_squared().to_f64() * mass[i].to_f64() * inv_2h2
        }
    })
}

/// `E(y) = sum_i m_i |y_i - y*_i|^2 / (2 h^2) + sum_i E_i(y)` (eq. 2 without the barrier, J), from
/// the responses of the last [`evaluate`].
pub(super) fn total_energy<T: Real>(sys: &mut MembraneSystem<T>, h: T) -> f64 {
    let MembraneSystem {
        points, response, ..
    } = sys;
    let elastic = chunked_sum(response.len(), &mut points.energy_chunks, |i| {
        response[i].energy().to_f64()
    });
    inertial_energy(points, h, false) + elastic
}
