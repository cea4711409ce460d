//! Coulomb friction at the contacts of touching grains ([`super::repulsion`]; beyond the 2017
//! paper, whose grains have none: docs/model.md, granular section). A granular body's
//! particles keep apart as balls of half a spacing; frictionless (the default), those balls
//! carry a pile's weight while sliding freely over each other. With the material's contact
//! friction `mu_c` (`Granular::contact_friction`, dimensionless) a touching pair's relative
//! tangential move within the step is limited, in the position-based style of the repulsion
//! (a constraint projected in the local step), by `mu_c` times the pair's normal correction:
//!
//! `t = (I - n n^T) ((p_i - y_i^t) - (p_j - y_j^t))`, `c_i^f = -s_i t min(1, mu_c g / |t|)`
//!
//! with `p` the proposed positions (m), `y^t` the step's start (m), `n` the pair's unit
//! normal, `g = d_ij - |p_i - p_j| > 0` the pair's overlap (m, the repulsion's normal move of
//! the pair), `s_i = m_j / (m_i + m_j)` particle `i`'s share, and `mu_c` the smaller of the
//! two particles' coefficients. A contact that slips less than `mu_c g` in the step sticks
//! (its relative tangential move is taken away); one that slips more keeps all but `mu_c g`
//! of it. At the iteration's fixed point the repulsion's normal and tangential reactions are
//! its moves in the same (Jacobi) metric, so the tangential reaction is at most `mu_c` times
//! the normal one: Coulomb's law, one coefficient for sticking and sliding. The pair's two
//! moves are equal and opposite in momentum (`m_i s_i = m_j s_j`), and each particle's sum
//! runs over its partners in a fixed order, so the result is the same for any thread count.

use nalgebra::Vector3;

use crate::real::Real;

/// Particle `i`'s friction move `c_i^f` (m; see the module's doc) in its pair with `j`: the
/// pair's unit normal `normal` (from `j` to `i`), its overlap `overlap` (m, > 0), the
/// relative move within the step `slip = (p_i - y_i^t) - (p_j - y_j^t)` (m), `i`'s share
/// `share` and the pair's coefficient `mu` (dimensionless).
#[inline(always)]
pub(crate) fn friction_move<T: Real>(
    normal: &Vector3<T>,
    overlap: T,
    slip: &Vector3<T>,
    share: T,
    mu: T,
) -> Vector3<T> {
    let tangential = slip - normal * normal.dot(slip);
    let length = tangential.norm();
    let limit = mu * overlap;
    if length <= limit {
        -tangential * share
    } else {
        -tangential * (share * limit / length)
    }
}
