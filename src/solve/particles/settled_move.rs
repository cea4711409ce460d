//! Where the collider projection that ends an iteration will put a particle, for the coarse
//! corrections that restrict the residual at the settled moves (the bodies' translations,
//! [`super::coarse`], and the two-level correction's held particles, [`super::two_level`]):
//! at the fixed point the projection takes back the sweep's move, so a correction taken at
//! the settled moves leaves the fixed point alone.

use nalgebra::Vector3;

use crate::collider::{coulomb_share, ColliderModel};
use crate::real::Real;

/// Particle `i`'s move `moved` (m; the sweep's, with the repulsion's or a coupling's answer)
/// from `y` carried out of `colliders` (margin `margin`, m) with Coulomb friction, collider
/// by collider as the projection takes them ([`crate::collider::push_out_with_friction`]
/// for the isotropic Jacobi metric `d`, kg): each collider measures its gap and normal where
/// the colliders before it left the particle, `y + moved`, and pushes it out along that
/// normal; a frictional one then shortens the slip over the step from `start` (m, relative
/// to the collider's material point) while its reaction `d |removed|` stays within
/// `friction * d * push`. Measured at the sweep's end for every collider instead, a
/// particle in a corner of two frictional colliders was pushed out of the second by the
/// depth the first one's friction had already taken back, and its settled move stayed away
/// from zero at the fixed point. Returns the settled move (m); `each(k, push, phi)` receives,
/// for every collider `colliders[k]` the particle is within, its push along the normal
/// `push = margin - gap` (m; the normal reaction is `d push`, N s^2) and its friction's
/// reaction, `d` times its tangential correction (N s^2; zero without friction).
#[inline]
pub(crate) fn out_of_colliders<T: Real>(
    y: &Vector3<T>,
    start: &Vector3<T>,
    mut moved: Vector3<T>,
    margin: T,
    d: T,
    colliders: &[ColliderModel<T>],
    mut each: impl FnMut(usize, T, Vector3<T>),
) -> Vector3<T> {
    for (k, c) in colliders.iter().enumerate() {
        let at = y + moved;
        let gap = c.signed_distance(&at);
        if gap >= margin {
            continue;
        }
        let n = c.normal(&at);
        let push = margin - gap;
        moved += n * push;
        let mut phi = Vector3::zeros();
        if c.friction > T::zero() {
            let at = y + moved;
            let slip = (at - start) - c.displacement(&at);
            let slip_t = slip - n * n.dot(&slip);
            let budget = c.friction * d * push;
            let share = coulomb_share(&slip_t, slip_t.norm_squared() / d, budget);
            moved -= slip_t * share;
            phi = -slip_t * (share * d);
        }
        each(k, push, phi);
    }
    moved
}

#[cfg(test)]
#[path = "settled_move_tests.rs"]
mod tests;
