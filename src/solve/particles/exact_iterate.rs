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
/// (`y^k`), and the trial being formed (`y^{k+1}`). An entry counts only where it rounds to the
/// stored position bit for bit ([`Self::previous`]): anything that moved a particle since
/// (a collider, the coarse translation, another family) leaves the stored position, rounded.
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

    /// The previous iterate of particle `i` unrounded (m), if it rounds to `stored` (its
    /// stored position), else `stored`.
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

/// `exact` if it rounds to `stored`, else `stored` (m).
#[inline(always)]
pub(crate) fn known<T: Real>(exact: &Vector3<f64>, stored: &Vector3<T>) -> Vector3<f64> {
    if exact.map(T::of) == *stored {
        *exact
    } else {
        stored.map(|c| c.to_f64())
    }
}
