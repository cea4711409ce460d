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
    let reach = (moved - z).norm() + margin;
    if colliders.iter().all(|c| c.signed_distance(z) > reach) {
        moved
    } else {
        *z
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collider::{push_out_with_friction, Collider, Pose, Shape};
    use crate::solve::clearance::Clearance;
    use crate::symmetric::SymmetricMatrix3;

    /// A deterministic uniform sample in `[-1, 1)` (a 64-bit LCG; the test needs no crate).
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        }
        fn vector(&mut self, scale: f64) -> Vector3<f64> {
            Vector3::new(self.next(), self.next(), self.next()) * scale
        }
    }

    /// How far from orthonormal the tests' turns may be: their rows are stretched by `1 +-`
    /// this, so that `R^T R` is off from `I` by up to 9e-10, just inside what the validator
    /// accepts ([`ORTHONORMAL_TOLERANCE`]).
    const SKEW: f64 = 4.5e-10;

    /// Every analytic shape, moving and turning during the step, with and without friction;
    /// the turns (the end pose's and the box's axes) have their rows stretched by
    /// `1 + skew`, 1 and `1 - skew`.
    fn colliders<T: Real>(skew: f64) -> Vec<ColliderModel<T>> {
        let (c, s) = (0.3f64.cos(), 0.3f64.sin());
        let turn = [
            [c * (1.0 + skew), -s * (1.0 + skew), 0.0],
            [s, c, 0.0],
            [0.0, 0.0, 1.0 - skew],
        ];
        let start = Pose::new(
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            [0.0; 3],
        )
        .unwrap();
        let end = Pose::new(turn, [0.01, -0.02, 0.005]).unwrap();
        let shapes = [
            Shape::sphere([0.3, -0.2, 0.1], 0.4).unwrap(),
            Shape::plane([0.0, 0.0, -0.5], [0.0, 0.6, 0.8]).unwrap(),
            Shape::cuboid([-0.6, 0.5, 0.2], [0.2, 0.1, 0.3], turn).unwrap(),
            Shape::capsule([0.5, 0.6, -0.1], [0.9, 0.2, 0.4], 0.15).unwrap(),
        ];
        shapes
            .into_iter()
            .enumerate()
            .map(|(k, shape)| {
                let collider = Collider::new(shape, 0.4 * (k % 2) as f64, [0.0; 3]).unwrap();
                ColliderModel::new(&collider, &start, &end)
            })
            .collect()
    }

    /// Wherever [`Clearance::clears`] a move, both pushes out of the colliders (the collider
    /// pass's and the global step's, with friction and a metric) return its end to the bit, in
    /// f32 and f64, for points measured near the surfaces and moves that reach the margin; and
    /// most short moves away from the surfaces are cleared (the skip is worth its test).
    fn cleared_moves_are_left_alone<T: Real>(skew: f64) {
        let colliders = colliders::<T>(skew);
        let mut clearance = Clearance::default();
        clearance.reset(1, &colliders);
        assert!(clearance.extent.is_finite());
        let inverse = SymmetricMatrix3 {
            diagonal: [T::of(2.0), T::of(0.5), T::of(1.0)],
            upper: [T::of(0.3), T::of(-0.2), T::of(0.1)],
        };
        let mut rng = Lcg(41);
        let (mut cleared, mut pushed, mut samples) = (0, 0, 0);
        for _ in 0..40_000 {
            let p = rng.vector(1.2).map(T::of);
            let distance = smallest_distance(&colliders, &p);
            if distance < T::zero() {
                continue;
            }
            samples += 1;
            // Moves of the order of the clearance, so that many end near the margin.
            let size = distance.to_f64() * (1.0 + rng.next());
            let from = p + rng.vector(size).map(T::of);
            let to = p + rng.vector(size).map(T::of);
            let margin = T::of(0.01 * (1.0 + rng.next()));
            let start = from + rng.vector(0.01).map(T::of);
            let plain = push_out_of_colliders(&colliders, MoveStart::Now(from), to, margin, None);
            let with_friction =
                push_out_with_friction(&from, to, &start, &inverse, margin, &colliders);
            if plain != to {
                pushed += 1;
            }
            clearance.at[0] = p;
            clearance.distance[0] = distance;
            if clearance.clears(0, &from, &to, margin) {
                cleared += 1;
                assert_eq!(plain, to, "cleared move from {from:?} to {to:?} was pushed");
                assert_eq!(
                    with_friction, to,
                    "cleared move from {from:?} to {to:?} was pushed"
                );
            }
        }
        assert!(
            cleared * 5 > samples,
            "{cleared} of {samples} moves cleared"
        );
        assert!(pushed * 20 > samples, "{pushed} of {samples} moves pushed");
    }

    #[test]
    fn cleared_moves_are_left_alone_f64() {
        cleared_moves_are_left_alone::<f64>(0.0);
        cleared_moves_are_left_alone::<f64>(SKEW);
    }

    #[test]
    fn cleared_moves_are_left_alone_f32() {
        cleared_moves_are_left_alone::<f32>(0.0);
        cleared_moves_are_left_alone::<f32>(SKEW);
    }

    /// The moves that [`Clearance::clears`] only just: straight towards the nearest collider
    /// (down its distance's gradient, where a turn stretched by [`SKEW`] makes the distance
    /// fall faster than the length moved, by up to 4.5e-10 of it) with the largest margin it
    /// clears (bisected), are returned to the bit by both pushes, for exact and for skewed
    /// turns. A bound that took the distance to change no faster than the length moved
    /// clears margins up to ~1e-10 m too deep here, and the pushes move those points.
    #[test]
    fn moves_cleared_at_the_bound_are_left_alone() {
        for skew in [0.0, SKEW] {
            let colliders = colliders::<f64>(skew);
            let mut clearance = Clearance::default();
            clearance.reset(1, &colliders);
            let inverse = SymmetricMatrix3 {
                diagonal: [2.0, 0.5, 1.0],
                upper: [0.3, -0.2, 0.1],
            };
            let mut rng = Lcg(7);
            let mut tested = 0;
            for _ in 0..4_000 {
                let p = rng.vector(1.2);
                let (nearest, distance) = colliders
                    .iter()
                    .map(|c| (c, c.signed_distance(&p)))
                    .min_by(|a, b| a.1.total_cmp(&b.1))
                    .unwrap();
                if distance < 1e-3 {
                    continue;
                }
                let to = p - nearest.normal(&p).normalize() * (distance * (0.6 + 0.3 * rng.next()));
                clearance.at[0] = p;
                clearance.distance[0] = distance;
                let (mut low, mut high) = (0.0, distance);
                if !clearance.clears(0, &p, &to, low) {
                    continue;
                }
                for _ in 0..80 {
                    let middle = 0.5 * (low + high);
                    if clearance.clears(0, &p, &to, middle) {
                        low = middle;
                    } else {
                        high = middle;
                    }
                }
                tested += 1;
                let plain = push_out_of_colliders(&colliders, MoveStart::Now(p), to, low, None);
                let with_friction = push_out_with_friction(&p, to, &p, &inverse, low, &colliders);
                assert_eq!(plain, to, "skew {skew}: move from {p:?} to {to:?} pushed");
                assert_eq!(
                    with_friction, to,
                    "skew {skew}: move from {p:?} to {to:?} pushed"
                );
            }
            assert!(tested > 500, "skew {skew}: {tested} moves at the bound");
        }
    }

    /// A small mesh collider (a cube of side 0.2 m at the origin, on a coarse grid).
    fn mesh_collider() -> ColliderModel<f64> {
        let (vertices, triangles) = crate::collider::sdf::tests::box_mesh([0.1; 3]);
        let shape = Shape::mesh(vertices, triangles, 8, None).unwrap();
        let collider = Collider::new(shape, 0.0, [0.0; 3]).unwrap();
        ColliderModel::new(&collider, &Pose::IDENTITY, &Pose::IDENTITY)
    }

    /// An unmeasured point, or any point after a reset, is never cleared; with a mesh
    /// collider among the step's colliders nothing is (its extent is infinite).
    #[test]
    fn nothing_is_cleared_unmeasured() {
        let mut colliders = colliders::<f64>(0.0);
        let mut clearance = Clearance::default();
        let (a, b) = (Vector3::new(5.0, 5.0, 5.0), Vector3::new(5.0, 5.0, 5.001));
        assert!(!clearance.clears(0, &a, &b, 0.0), "before any reset");
        clearance.reset(2, &colliders);
        clearance.at[0] = a;
        clearance.distance[0] = smallest_distance(&colliders, &a);
        assert!(clearance.clears(0, &a, &b, 0.0));
        assert!(!clearance.clears(1, &a, &b, 0.0), "a point not measured");
        clearance.reset(2, &colliders);
        assert!(!clearance.clears(0, &a, &b, 0.0), "after a reset");
        colliders.push(mesh_collider());
        clearance.reset(2, &colliders);
        assert_eq!(clearance.extent, f64::INFINITY);
        clearance.at[0] = a;
        clearance.distance[0] = smallest_distance(&colliders, &a);
        assert!(!clearance.clears(0, &a, &b, 0.0), "with a mesh collider");
    }
}
