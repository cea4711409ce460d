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
        ShapeModel::Mesh(_) => T::of(f64::INFINITY),
    };
    collider.translation().norm() + shape
}
