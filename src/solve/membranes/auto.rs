//! `Solver(method="auto")`: SISSM or Newton for each step, chosen from the tolerance, the mesh
//! and the stiffness (issue 44, scope item 3; the measured trade is in docs/performance.md,
//! "Newton: accuracy per millisecond").
//!
//! A SISSM iteration is a Jacobi sweep in the metric `D_k = m_k I + h^2 C_k` (eq. 25): it
//! removes the error that varies from vertex to vertex at once, but the error that is smooth
//! across the mesh falls by about `1 - 1/n_slow` per iteration, with
//! `n_slow = min(s, N / pi^2)`: `s = h^2 c / m` is the stiffness of a vertex against its mass
//! (its median over the free vertices of `tr(h^2 C_k) / (3 m_k)`, dimensionless) and `N / pi^2`
//! the ratio of the stiffness of a vertex-to-vertex mode to that of the smoothest mode of a
//! sheet of `N` vertices. A Newton iteration removes both; on the benchmark cloths it costs
//! about a hundred SISSM iterations to `eta <= 1e-3`. So Newton is chosen where SISSM would need
//! more than [`SLOW_ITERATIONS`] iterations and `tol` asks for an accurate step (at most
//! [`TIGHT_TOL`]; with a looser `tol` SISSM's first iterations usually meet it), on membranes
//! only (Newton steps no particle body).

use super::jacobi::jacobi_block;
use super::system::MembraneSystem;
use crate::real::Real;
use crate::solve::Method;

/// `n_slow` above which Newton is chosen (SISSM iterations).
pub(crate) const SLOW_ITERATIONS: f64 = 100.0;

/// The largest `tol` (m) for which Newton is chosen.
pub(crate) const TIGHT_TOL: f64 = 1e-5;

/// The median over the free vertices of `tr(D_k - m_k I) / (3 m_k) = h^2 tr(C_k) / (3 m_k)`
/// at the evaluated iterate of `sys` (`h2 = h^2`, s^2); 0 without a free vertex.
pub(crate) fn stiffness<T: Real>(sys: &MembraneSystem<T>, h2: T) -> f64 {
    let mut s: Vec<f64> = (0..sys.points.y.len())
        .filter(|&k| !sys.points.pinned[k])
        .map(|k| {
            let mass = sys.rest.vertices[k].mass.to_f64();
            let block = jacobi_block(sys, k, h2).to_matrix();
            (block.trace().to_f64() - 3.0 * mass) / (3.0 * mass)
        })
        .collect();
    if s.is_empty() {
        return 0.0;
    }
    let middle = s.len() / 2;
    *s.select_nth_unstable_by(middle, f64::total_cmp).1
}

/// The method of a step of membranes only: Newton where `0 < tol <= TIGHT_TOL` and
/// `min(s, N / pi^2) > SLOW_ITERATIONS` (see the module docs), else SISSM.
pub(crate) fn choose<T: Real>(sys: &MembraneSystem<T>, h2: T, tol: f64) -> Method {
    if tol <= 0.0 || tol > TIGHT_TOL {
        return Method::Sissm;
    }
    let vertices = sys.points.y.len() as f64;
    let slow = stiffness(sys, h2).min(vertices / std::f64::consts::PI.powi(2));
    if slow > SLOW_ITERATIONS {
        Method::Newton
    } else {
        Method::Sissm
    }
}
