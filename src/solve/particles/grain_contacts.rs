//! What the grains' contact friction ([`super::grain_friction`]) and their rolling
//! ([`super::grain_rolling`]) both read: the pairs of touching particles at an iteration's
//! proposed positions, and one touching frictional pair.

use nalgebra::Vector3;

use crate::real::Real;

/// The pairs of touching particles at the proposed positions, as the repulsion found them.
pub(crate) struct Pairs<'a, T: Real> {
    /// The proposed positions `p` (m) and the step's start `y^t` (m).
    pub proposed: &'a [Vector3<T>],
    pub start: &'a [Vector3<T>],
    /// Each particle's collider margin (m) and whether it is pinned.
    pub margin: &'a [T],
    pub pinned: &'a [bool],
    /// The candidate partners of each particle, in compressed rows.
    pub offsets: &'a [u32],
    pub indices: &'a [u32],
}

impl<T: Real> Pairs<'_, T> {
    /// The candidate entries of particle `i`'s row.
    pub fn row(&self, i: usize) -> std::ops::Range<usize> {
        self.offsets[i] as usize..self.offsets[i + 1] as usize
    }
}

/// A touching frictional pair at an iteration's proposed positions.
pub(super) struct Contact<T: Real> {
    /// The pair's unit normal, from the partner to the particle.
    pub normal: Vector3<T>,
    /// Its overlap `g` (m) and coefficient `mu_c` (dimensionless).
    pub overlap: T,
    pub mu: T,
}
