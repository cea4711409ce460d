//! The walls a fluid member slides on in the conjugate-gradient density solve
//! ([`super::density_system`]): per member up to three orthonormal outward normals of the
//! colliders it is pressed against (an edge or a corner of a tank holds a member by two or
//! three walls at once). Its linearised moves lose their parts along them, so that the colliders
//! do not take back part of every correction the coupled solve spreads.
//!
//! **Within one step, no state across steps.** At a step's start a member holds the walls it
//! touches ([`touching`]: the colliders within a probe depth of its margin); each collider that
//! pushes a move back adds its push's direction ([`add_wall`]); and a wall holds by an
//! inequality: it pushes and never pulls, so a member whose move points away from a wall drops
//! that wall's normal and leaves it ([`release`]).

use nalgebra::Vector3;

use crate::collider::ColliderModel;
use crate::real::Real;

/// Up to three orthonormal normals (unit, or zero when unused) of the walls a member is
/// pressed against.
pub(super) type Walls<T> = [Vector3<T>; 3];

/// No walls.
pub(super) fn none<T: Real>() -> Walls<T> {
    [Vector3::zeros(); 3]
}

/// `v` less its parts along the normals of `walls` (`(I - sum_n n n^T) v`: the normals are
/// orthonormal, so this projects onto the walls' common tangent space; `v` itself, to the bit,
/// for a finite `v` and no walls).
pub(super) fn slide<T: Real>(walls: &Walls<T>, v: Vector3<T>) -> Vector3<T> {
    walls.iter().fold(v, |v, n| v - n * n.dot(&v))
}

/// Adds the direction of a push `d` out of a wall to `walls` (Gram-Schmidt against the normals
/// there: nothing when `d` lies within their span, to a relative `1e-3`).
pub(super) fn add_wall<T: Real>(walls: &mut Walls<T>, d: Vector3<T>) {
    let free = slide(walls, d);
    let norm = free.norm();
    if norm.to_f64() <= 1e-3 * d.norm().to_f64() {
        return;
    }
    if let Some(slot) = walls.iter_mut().find(|n| **n == Vector3::zeros()) {
        *slot = free / norm;
    }
}

/// The walls of a member at `y` (m) at a step's start: the outward normal at `y` of each of
/// `colliders` whose signed distance is below `margin + depth` (m; the member's collider margin
/// and a probe depth), as the colliders' last push left a member resting on them.
pub(super) fn touching<T: Real>(
    colliders: &[ColliderModel<T>],
    y: &Vector3<T>,
    margin: T,
    depth: T,
) -> Walls<T> {
    let mut walls = none();
    for c in colliders {
        if c.signed_distance(y) < margin + depth {
            add_wall(&mut walls, c.normal(y));
        }
    }
    walls
}

/// Drops from `walls` each normal `n` that the move `dy` (m, before its slide) leaves,
/// `n . dy > 0`: a wall holds a member by the inequality `n . dy >= 0` and does not pull it
/// back.
pub(super) fn release<T: Real>(walls: &mut Walls<T>, dy: &Vector3<T>) {
    for n in walls.iter_mut() {
        if n.dot(dy) > T::zero() {
            *n = Vector3::zeros();
        }
    }
}

#[cfg(test)]
#[path = "density_walls_tests.rs"]
mod tests;
