//! The particles' iterates before their rounding to the body's precision, so that the
//! Chebyshev extrapolation (Wang 2015; He et al. 2017, section 4.3)
//! `y^{k+1} = w (z^k - y^{k-1}) + y^{k-1}` rounds once per iteration and reads `y^{k-1}`
//! unrounded.
//!
//! **Why (issue 38).** A position stored in `f32` is rounded by up to half an ulp, about
//! `eps |y| / 2` (m). With `w` near 2 the recurrence above damps an eigencomponent of its error
//! by only `sqrt(w - 1)` per iteration, so the rounding it meets at every iteration adds up to
//! several ulps; the residual changes by `D_i` per metre a particle moves, so those ulps leave
//! `|r_i| / m_i` at several times its round-off floor `eps |y_i| D_i / m_i`
//! ([`super::roundoff::residual_floor`]) all over the body, and the step never converges. Kept here
//! in `f64`, the sequence's own iterates carry no rounding: the kernel sees `y^k` rounded, and
//! the Jacobi move from it, `z = y^k + D^-1 r(y^k)`, is the move from the unrounded iterate but
//! for the off-diagonal couplings of the rounding (the diagonal part of `A (y - y_rounded)` is
//! `D (y - y_rounded)`, which `z` absorbs), a fraction of it.
//!
//! In `f64` an iterate's rounding is itself, and the sequence is the same operation for
//! operation as with the rounded iterates.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::real::Real;

/// The unrounded iterates (m) of one step: the one before the current (`y^{k-1}`), the current
/// (`y^k`), and the trial being formed (`y^{k+1}`). An entry counts only in the coordinates
/// where it rounds to the stored position bit for bit ([`known`]): a coordinate that anything
/// moved since (a collider, the coarse translation, another family) is the stored one.
pub(crate) struct ExactIterates {
    previous: Vec<Vector3<f64>>,
    current: Vec<Vector3<f64>>,
    pub next: Vec<Vector3<f64>>,
}

impl ExactIterates {
    /// For `n` particles, none known.
    pub fn new(n: usize) -> Self {
        let unknown = vec![Vector3::repeat(f64::NAN); n];
        Self {
            previous: unknown.clone(),
            current: unknown.clone(),
            next: unknown,
        }
    }

    /// Forgets every iterate (at a step's start: a step must not depend on the last step's).
    pub fn forget(&mut self) {
        self.current.fill(Vector3::repeat(f64::NAN));
        self.next.fill(Vector3::repeat(f64::NAN));
    }

    /// Moves on by one iteration: the trial becomes the current iterate, the current the
    /// previous (the solver's loop does the same with the stored positions).
    pub fn advance(&mut self) {
        std::mem::swap(&mut self.previous, &mut self.current);
        std::mem::swap(&mut self.current, &mut self.next);
    }

    /// The previous iterate of particle `i` unrounded (m) in the coordinates that round to
    /// `stored`'s (its stored position), else `stored`'s ([`known`]).
    #[inline(always)]
    pub fn previous<T: Real>(&self, i: usize, stored: &Vector3<T>) -> Vector3<f64> {
        known(&self.previous[i], stored)
    }

    /// Moves the previous iterates of the particles `range` by `t` (m), and their stored
    /// positions `stored` with them, rounded once.
    pub fn shift_previous<T: Real>(
        &mut self,
        range: std::ops::Range<usize>,
        stored: &mut [Vector3<T>],
        t: &Vector3<f64>,
    ) {
        self.previous[range.clone()]
            .par_iter_mut()
            .zip(&mut stored[range])
            .for_each(|(exact, stored)| {
                *exact = known(exact, stored) + t;
                *stored = exact.map(T::of);
            });
    }
}

/// `exact` (m) in each coordinate that rounds to `stored`'s, else `stored`'s: a collider that
/// moved a particle along its normal alone (a frictionless plane's push of the contact layer)
/// leaves the other coordinates unrounded.
#[inline(always)]
pub(crate) fn known<T: Real>(exact: &Vector3<f64>, stored: &Vector3<T>) -> Vector3<f64> {
    exact.zip_map(stored, |e, s| if T::of(e) == s { e } else { s.to_f64() })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A contact particle 1 m from the origin pushed up to a frictionless floor along `z` keeps
    /// its unrounded `x` and `y` (the coordinates the push left alone round to the stored
    /// ones) and takes the stored `z`; in f64 the stored position comes back bit for bit.
    #[test]
    fn a_push_along_the_normal_keeps_the_other_coordinates_unrounded() {
        let exact = Vector3::new(1.0 + 1e-9, 0.25 + 3e-10, -1e-4);
        let stored = Vector3::new(exact.x as f32, exact.y as f32, 1.7e-3_f32);
        assert_ne!(f64::from(stored.x), exact.x);
        let kept = known(&exact, &stored);
        assert_eq!((kept.x, kept.y), (exact.x, exact.y));
        assert_eq!(kept.z, f64::from(stored.z));
        let stored64 = Vector3::new(exact.x, exact.y, 1.7e-3);
        assert_eq!(known(&exact, &stored64), stored64);
    }
}
