//! The passes of a step that keep points out of the colliders, shared by every body family
//! (each point keeps its own margin from a collider's surface, [`Points::margin`]).

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::collider::{push_out_of_colliders, ColliderModel, MoveStart};
use crate::real::Real;

use super::clearance::{clears, smallest_distance};
use super::points::Points;
use super::update::Update;

/// Projects the free points of the iterate `y` out of the colliders (a start outside every
/// collider, so that the residual there measures a feasible state), on the side of each that
/// the point was on at the start of the step (`y_t`, carried by the collider's motion).
pub(crate) fn push_iterate_out_of_colliders<T: Real>(
    points: &mut Points<T>,
    colliders: &[ColliderModel<T>],
) {
    points.clearance.reset(points.y.len(), colliders);
    if colliders.is_empty() {
        return;
    }
    let (pinned, margin, start) = (&points.pinned, &points.margin, &points.y_start);
    let collides = &points.collides;
    points.y.par_iter_mut().enumerate().for_each(|(k, y)| {
        if !pinned[k] {
            let from = MoveStart::OfStep(start[k]);
            let colliders = Points::colliders_of(collides, k, colliders);
            *y = push_out_of_colliders(colliders, from, *y, margin[k], None);
        }
    });
}

/// Projects the free points of `y_next` out of the colliders and measures the move from `y`.
/// A point whose move [`Clearance::clears`] is left alone (the projection would return it
/// unchanged); the others are projected, and those the projection left where they were are
/// measured for the next passes of the step.
pub(crate) fn push_next_out_of_colliders<T: Real>(
    points: &mut Points<T>,
    colliders: &[ColliderModel<T>],
) -> Update {
    let (y, pinned, margin) = (&points.y, &points.pinned, &points.margin);
    let collides = &points.collides;
    let clearance = &mut points.clearance;
    // One measure per point, so that the zip below covers every point: a clearance not reset
    // for this many points holds no measure of them.
    if clearance.distance.len() != points.y_next.len() {
        clearance.reset(points.y_next.len(), colliders);
    }
    let extent = clearance.extent;
    points
        .y_next
        .par_iter_mut()
        .zip(clearance.at.par_iter_mut().zip(&mut clearance.distance))
        .enumerate()
        .map(|(k, (next, (at, distance)))| {
            if !pinned[k] && !clears((at, *distance), extent, &y[k], next, margin[k]) {
                let from = MoveStart::Now(y[k]);
                let colliders = Points::colliders_of(collides, k, colliders);
                let projected = push_out_of_colliders(colliders, from, *next, margin[k], None);
                *distance = if projected == *next {
                    *at = projected;
                    smallest_distance(colliders, &projected)
                } else {
                    T::of(f64::NEG_INFINITY)
                };
                *next = projected;
            }
            Update::of(k, &y[k], next)
        })
        .reduce(|| Update::NONE, Update::merge)
}

/// Chebyshev's extrapolation with contact: `y^{k+1} = w (z - y^{k-1}) + y^{k-1}` on the local
/// step's result `z` (in `y_next`; `y^{k-1}` in `y_prev`), so that it extrapolates the whole
/// iteration, global and local step, as the semi-iterative method asks. The extrapolated
/// iterate is only where the next global step evaluates the forces: the local step keeps its
/// own safe positions (`z`, intersection-free) and runs its CCD from them, and the solver
/// does not extrapolate the iteration it stops at, so every step still ends on a local step's
/// result. A point that the extrapolation could take into a collider (its signed distance at
/// `z`, beyond its margin, no more than the extrapolation's move) keeps `z`: the global
/// step's collider projection starts from outside, and friction does not see an extrapolated
/// slide.
pub(crate) fn extrapolate_local_step<T: Real>(
    points: &mut Points<T>,
    w: T,
    colliders: &[ColliderModel<T>],
) {
    let (y_prev, pinned, margin) = (&points.y_prev, &points.pinned, &points.margin);
    let collides = &points.collides;
    points.y_next.par_iter_mut().enumerate().for_each(|(k, z)| {
        if !pinned[k] {
            let colliders = Points::colliders_of(collides, k, colliders);
            *z = extrapolated(z, &y_prev[k], w, margin[k], colliders);
        }
    });
}

/// One point of [`extrapolate_local_step`]: `w (z - previous) + previous`, or `z` where
/// that move could reach into a collider (within `margin`, m, of its surface).
pub(crate) fn extrapolated<T: Real>(
    z: &Vector3<T>,
    previous: &Vector3<T>,
    w: T,
    margin: T,
    colliders: &[ColliderModel<T>],
) -> Vector3<T> {
    let moved = (z - previous) * w + previous;
    if clear_of_colliders(z, &moved, margin, colliders) {
        moved
    } else {
        *z
    }
}

/// Whether the move from `z` to `moved` cannot reach into a collider: the signed distance of
/// `z` to each, beyond `margin` (m), exceeds the move's length.
#[inline(always)]
pub(crate) fn clear_of_colliders<T: Real>(
    z: &Vector3<T>,
    moved: &Vector3<T>,
    margin: T,
    colliders: &[ColliderModel<T>],
) -> bool {
    let reach = (moved - z).norm() + margin;
    colliders.iter().all(|c| c.signed_distance(z) > reach)
}
