//! The clearance of points from the colliders within a step: what lets the collider passes
//! ([`super::collider_passes`]) leave alone a move that surely stays clear of every collider.

use nalgebra::Vector3;

use crate::collider::pose::ORTHONORMAL_TOLERANCE;
use crate::collider::{ColliderModel, ShapeModel};
use crate::real::Real;

/// Per point, the smallest signed distance from its colliders (m) measured at a position during
/// the step, so that the passes after it can leave alone a move that surely stays clear of
/// every collider: the analytic shapes' signed distances are exact Euclidean distances, which
/// change by at most the length moved, so a point `b` within `D - |b - p|` of the surface
/// (`D` measured at `p`) is at least that far out. Reset at each step's start
/// ([`super::collider_passes::push_iterate_out_of_colliders`]; the colliders move between steps), filled by
/// [`super::collider_passes::push_next_out_of_colliders`], read by it and by the global step's move.
#[derive(Debug, Clone, Default)]
pub(crate) struct Clearance<T: Real> {
    /// Where each point was measured (m).
    pub(super) at: Vec<Vector3<T>>,
    /// The smallest signed distance there (m; minus infinity: not measured this step).
    pub(super) distance: Vec<T>,
    /// The largest [`extent`] of the step's colliders (m; infinite with a mesh collider, whose
    /// interpolated distance is not exact: nothing is cleared).
    pub(super) extent: T,
}

impl<T: Real> Clearance<T> {
    /// Forgets every measure, for `n` points and the step's `colliders`.
    pub fn reset(&mut self, n: usize, colliders: &[ColliderModel<T>]) {
        self.at.resize(n, Vector3::zeros());
        self.distance.clear();
        self.distance.resize(n, T::of(f64::NEG_INFINITY));
        self.extent = colliders
            .iter()
            .map(extent)
            .fold(T::zero(), |a, b| if b > a { b } else { a });
    }

    /// Whether the move of point `k` from `from` (outside its colliders) to `to` surely stays
    /// at least `margin` (m) outside every collider and short of crossing one, so that
    /// [`crate::collider::push_out_of_colliders`] and [`crate::collider::push_out_with_friction`] return `to`
    /// itself (false for a point not measured this step).
    #[inline]
    pub fn clears(&self, k: usize, from: &Vector3<T>, to: &Vector3<T>, margin: T) -> bool {
        match (self.at.get(k), self.distance.get(k)) {
            (Some(at), Some(&distance)) => clears((at, distance), self.extent, from, to, margin),
            _ => false,
        }
    }
}

/// [`Clearance::clears`] for a point measured at `at` with the smallest signed distance
/// `distance` (m). At `to` every collider's distance is at least `distance - L |to - at|`, which
/// must be at least `margin` (no projection) and at least the move's length (the collider's
/// `keep_side` then sees a path that cannot cross it), less a guard for the round-off of the
/// distances and lengths (64 units in the last place of the coordinates' and colliders' scale).
///
/// `L` bounds how fast a collider's computed distance changes per metre moved. The shapes'
/// distances are exact in their frame, but the frame is reached through the pose's rotation
/// `R` and a box's axes `Q`, which [`crate::collider::rotation_matrix`] accepts with
/// `|R^T R - I| < eps` entry by entry (`eps` = [`ORTHONORMAL_TOLERANCE`]): then
/// `|R^T R - I|_2 <= |R^T R - I|_F < 3 eps`, so `|R|_2 <= sqrt(1 + 3 eps) <= 1 + 3 eps / 2`,
/// and a box's distance, through `Q^T R^T`, changes by at most `(1 + 3 eps / 2)^2 < 1 + 4 eps`
/// times the length moved. So `L = 1 + 4 eps`: a slack of `4 eps |to - at|` (5e-11 m for a
/// 0.1 m move, where the guard is ~1e-14 m). Conversion to f32 adds ulps to `R`, within the
/// guard.
#[inline(always)]
pub(super) fn clears<T: Real>(
    (at, distance): (&Vector3<T>, T),
    extent: T,
    from: &Vector3<T>,
    to: &Vector3<T>,
    margin: T,
) -> bool {
    let scale = from.norm() + to.norm() + at.norm() + extent;
    let guard = T::default_epsilon() * T::of(64.0) * scale;
    let left = distance - (to - at).norm() * T::of(1.0 + 4.0 * ORTHONORMAL_TOLERANCE) - guard;
    let needed = (to - from).norm();
    left >= margin && left >= needed
}

/// The smallest signed distance of `x` from `colliders` (m; infinite for none).
pub(super) fn smallest_distance<T: Real>(colliders: &[ColliderModel<T>], x: &Vector3<T>) -> T {
    colliders
        .iter()
        .map(|c| c.signed_distance(x))
        .fold(T::of(f64::INFINITY), |a, b| if b < a { b } else { a })
}

/// A bound on the size of the numbers a collider's signed distance is computed from (m): its
/// translation and its shape's offset, centre, half extents, ends and radius; infinite for a
/// mesh collider.
fn extent<T: Real>(collider: &ColliderModel<T>) -> T {
    let shape = match collider.shape() {
        ShapeModel::Plane { offset, .. } => offset.abs(),
        ShapeModel::Sphere { center, radius } => center.norm() + radius.abs(),
        ShapeModel::Box {
            center,
            half_extents,
            ..
        } => center.norm() + half_extents.norm(),
        ShapeModel::Capsule { a, b, radius } => a.norm() + b.norm() + radius.abs(),
        ShapeModel::Mesh(..) => T::of(f64::INFINITY),
    };
    collider.translation().norm() + shape
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collider::{
        push_out_of_colliders, push_out_with_friction, Collider, MoveStart, Pose, Shape,
    };
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
