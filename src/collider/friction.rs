//! Keeping a move out of the colliders in the metric of the move's own linear system, with
//! Coulomb friction (the global step's collider handling, Lu et al. 2023 section 6.1, in the
//! system metric of eq. 25).

use nalgebra::Vector3;

use crate::real::Real;
use crate::symmetric::SymmetricMatrix3;

use super::ColliderModel;

/// Keeps a move from `from` (the iterate, outside the colliders) to `y` out of the colliders
/// in the metric of its system matrix `D`, with Coulomb friction.
///
/// A move that would cross a collider ends on the side it came from instead
/// ([`ColliderModel::keep_side`]). Where `y` would end inside a collider (closer than `margin`), it moves along `D^-1 n`
/// instead of `n` ([`ColliderModel::push_out`]): it solves `min 1/2 d^T D d - r^T d` on the
/// tangent plane of the contact, with the normal reaction `lambda = -gap / (n . D^-1 n)`
/// (N s^2). A Euclidean projection
/// with an anisotropic `D` would leave a tangential residual `lambda (D n)_t` at its fixed
/// point: frictionless contact would stick.
///
/// Friction: the slip `s_t` of the vertex relative to the collider over the whole step
/// (from `start`, the collider's material point under `y` moving by its displacement) is removed when the reaction that
/// takes, `k |s_t|` with `k = |s_t|^2 / (s_t . D^-1 s_t)` the stiffness along it, is within
/// the Coulomb cone `friction * lambda` (sticking), and shortened by `friction * lambda / k`
/// otherwise (sliding).
#[inline(always)]
pub fn push_out_with_friction<T: Real>(
    from: &Vector3<T>,
    mut y: Vector3<T>,
    start: &Vector3<T>,
    inverse: &SymmetricMatrix3<T>,
    margin: T,
    colliders: &[ColliderModel<T>],
) -> Vector3<T> {
    for c in colliders {
        let (end, distance) = c.keep_side(from, y);
        y = end;
        let Some((n, reaction)) = c.push_out(&mut y, distance, inverse, margin) else {
            continue;
        };
        if c.friction > T::zero() {
            let slip = (y - start) - c.displacement(&y);
            let slip_t = slip - n * n.dot(&slip);
            let compliance = slip_t.dot(&inverse.mul_vector(&slip_t));
            y -= slip_t * coulomb_share(&slip_t, compliance, c.friction * reaction);
        }
    }
    y
}

/// The share (in `[0, 1]`) of a tangential slip `slip_t` (m) that Coulomb friction removes:
/// removing all of it takes the reaction `k |slip_t|`, with `k = |slip_t|^2 / compliance` the
/// stiffness along it and `compliance = slip_t . C slip_t` (m^2 times the compliance `C`, the
/// inverse of the metric the move is taken in); 1 where that is within `budget` (the friction
/// coefficient times the normal reaction, in the units of `k |slip_t|`: sticking), else
/// `budget / (k |slip_t|)` (sliding, the slip shortened by the cone's reach); 0 where
/// `compliance` is not positive (no slip, or a vertex that cannot move).
#[inline]
pub fn coulomb_share<T: Real>(slip_t: &Vector3<T>, compliance: T, budget: T) -> T {
    if compliance <= T::zero() {
        return T::zero();
    }
    let needed = slip_t.norm_squared() * slip_t.norm() / compliance;
    if needed <= budget {
        T::one()
    } else {
        budget / needed
    }
}
