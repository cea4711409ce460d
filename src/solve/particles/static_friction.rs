//! Static friction of granular particle bodies (He et al. 2017, eq. 28): at the end of a
//! step, a particle that the solve pushed back from its inertial target towards its start by
//! at least `eta` of the way is held where it started, with no velocity
//! ([`crate::particles::holds`]). Without it a pile of sand, solved by a few iterations each
//! step, creeps down under its own weight.
//!
//! **Departure: only where the sand did not yield, or its contacts can hold it.** The paper
//! holds every particle that passes eq. 28. A particle of a stiff column then passes it every
//! step (the elastic response holds it up within the step), is put back where it started,
//! never strains and never yields: a column of dry sand would stand for ever. Here a particle
//! that yielded in the step's return (its friction cone exceeded: it slides) is not held;
//! static friction holds what the friction cone holds. A yielded particle is held all the
//! same when it touches grains with contact friction (`Granular::contact_friction`) and at
//! every such contact the sideways part of its move in the step, the move the hold takes
//! back, lies within the contact's Coulomb limit with the grain's own normal load,
//! `|(I - n n^T) (y - y^t)| <= mu_c min(g, |y* - y^t|)`
//! ([`super::grain_friction::GrainFriction::sticks`]): the contact's static friction can take
//! it back. Without this, a resting packing with contact friction never came to rest, its
//! bonds on their cone yielding again each step as contacts at their Coulomb limit slipped a
//! micrometre; a grain held whenever its contacts did not slip relative to its partners
//! (round t) held a perfect-lattice column whose stacked grains move together
//! (docs/particles/granular.md, round u).

use std::ops::Range;

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::particles::{holds, Particles};
use crate::real::Real;
use crate::solve::points::Points;

/// The granular bodies of a family with static friction, and the step's start positions.
pub(crate) struct StaticFriction<T: Real> {
    /// Per body with static friction its particles in the family and its `eta`.
    bodies: Vec<(Range<usize>, f64)>,
    /// Every particle's position at the start of the step (m).
    starts: Vec<Vector3<T>>,
}

impl<T: Real> StaticFriction<T> {
    /// The static friction of `bodies`, or `None` when no body has any.
    pub fn of(bodies: &[&mut Particles]) -> Option<Self> {
        let mut start = 0;
        let mut with = Vec::new();
        for body in bodies {
            let range = start..start + body.num_particles();
            start = range.end;
            if let Some(eta) = body.granular().and_then(|g| g.static_friction) {
                with.push((range, eta));
            }
        }
        (!with.is_empty()).then(|| Self {
            bodies: with,
            starts: vec![Vector3::zeros(); start],
        })
    }

    /// Keeps the positions the step starts from.
    pub fn start_step(&mut self, points: &Points<T>) {
        self.starts.copy_from_slice(&points.y_start);
    }

    /// Eq. 28 once the step's velocities are set ([`Points::finish`]): a particle held goes
    /// back to its start with no velocity. Pinned particles are left as they are, and so are
    /// those marked in `yielded` unless `sticks(margin, i, d, |y* - y^t|)` says particle
    /// `i`'s grain contacts can take back its move `d` (m) in the step, `margin` the
    /// particles' collider margins (m) ([`super::grain_friction::GrainFriction::sticks`]),
    /// asked last (the costliest test). Returns how many were held.
    pub fn apply(
        &self,
        points: &mut Points<T>,
        yielded: &[bool],
        sticks: &(impl Fn(&[T], usize, &Vector3<T>, T) -> bool + Sync),
    ) -> usize {
        let mut held = 0;
        for (range, eta) in &self.bodies {
            let (starts, star, pinned, yielded, margin) = (
                &self.starts[range.clone()],
                &points.y_star[range.clone()],
                &points.pinned[range.clone()],
                &yielded[range.clone()],
                &points.margin,
            );
            let r = range.clone();
            held += points.y[r.clone()]
                .par_iter_mut()
                .zip(points.y_start[r.clone()].par_iter_mut())
                .zip(points.velocity[r].par_iter_mut())
                .enumerate()
                .map(|(k, ((y, start), velocity))| {
                    let slides = || {
                        let inertial = (star[k] - starts[k]).norm();
                        !sticks(margin, range.start + k, &(*y - starts[k]), inertial)
                    };
                    if pinned[k]
                        || !holds(*eta, y, &starts[k], &star[k])
                        || (yielded[k] && slides())
                    {
                        return 0;
                    }
                    *y = starts[k];
                    *start = starts[k];
                    *velocity = Vector3::zeros();
                    1
                })
                .sum::<usize>();
        }
        held
    }
}
