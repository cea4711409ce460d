//! When a particle counts as touching a collider for the solvers that hold the contacts in
//! their linear systems: the direct solver's held set ([`super::direct`]) and the two-level
//! correction's held particles ([`super::two_level`]).

use crate::real::Real;

/// How close to its margin (a fraction of the margin) a particle counts as touching a
/// collider.
pub const CONTACT_GAP: f64 = 1e-3;

/// The signed distance (m) from a collider under which a particle of margin `margin` (m)
/// counts as touching it: `margin (1 + CONTACT_GAP)`.
#[inline(always)]
pub(crate) fn contact_reach<T: Real>(margin: T) -> T {
    margin * (T::one() + T::of(CONTACT_GAP))
}
