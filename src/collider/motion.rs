//! How a collider moves through a simulation: at time `tau` (s) its shape stands at the pose
//! `x = R b + t + v tau` (shape point `b`, constant velocity `v`), where the base pose
//! `(R, t)` starts as the identity (the geometry as given) and changes only when a target pose
//! is set: [`MovingCollider::set_target`] names the pose the collider reaches at the end of the
//! next step. During that step the collider moves rigidly from its pose at the start to the
//! target (friction sees each material point's own displacement, so a turning collider drags
//! a membrane around); afterwards the velocity carries it on from there.

use crate::collider::pose::Pose;
use crate::collider::{Collider, ColliderModel};
use crate::real::Real;

/// A collider and its pose over time.
#[derive(Debug, Clone)]
pub struct MovingCollider {
    pub collider: Collider,
    /// The pose at time 0 the velocity starts from.
    base: Pose,
    /// The pose at the end of the next step, when set.
    target: Option<Pose>,
}

impl MovingCollider {
    /// `collider` at the pose it was given, moving at its velocity.
    pub fn new(collider: Collider) -> Self {
        Self {
            collider,
            base: Pose::IDENTITY,
            target: None,
        }
    }

    /// The pose at time `time` (s).
    pub fn pose(&self, time: f64) -> Pose {
        self.base.shifted(&(self.collider.velocity * time))
    }

    /// Sets the pose the collider reaches at the end of the next step (replacing an earlier
    /// target not yet reached).
    pub fn set_target(&mut self, pose: Pose) {
        self.target = Some(pose);
    }

    /// The base pose and the pending target: with the collider and the clock, everything its
    /// motion depends on (for saving a simulation).
    pub fn motion(&self) -> (Pose, Option<Pose>) {
        (self.base, self.target)
    }

    /// Restores a motion read with [`Self::motion`].
    pub fn set_motion(&mut self, base: Pose, target: Option<Pose>) {
        self.base = base;
        self.target = target;
    }

    /// The collider during the step from `start` to `end` (s).
    pub fn during_step<T: Real>(&self, start: f64, end: f64) -> ColliderModel<T> {
        let to = self.target.unwrap_or_else(|| self.pose(end));
        ColliderModel::new(&self.collider, &self.pose(start), &to)
    }

    /// Records that a step ending at `end` (s) was taken: the target, if any, becomes the
    /// pose the velocity carries on from.
    pub fn finish_step(&mut self, end: f64) {
        if let Some(pose) = self.target.take() {
            self.base = pose.shifted(&(-self.collider.velocity * end));
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::*;
    use crate::collider::Shape;

    /// A collider turning about z by 0.1 rad in one step: a point at radius r on it moves by
    /// about `0.1 r` tangentially; with a velocity as well the target holds, and the velocity
    /// carries on from the target afterwards.
    #[test]
    fn a_target_pose_is_reached_and_the_velocity_carries_on() {
        let shape = Shape::sphere([0.0; 3], 0.5).unwrap();
        let mut c = MovingCollider::new(Collider::new(shape, 0.0, [0.0, 0.0, 1.0]).unwrap());
        let (c1, s1) = (0.1f64.cos(), 0.1f64.sin());
        let turn = Pose::new([[c1, -s1, 0.0], [s1, c1, 0.0], [0.0, 0.0, 1.0]], [0.0; 3]).unwrap();
        c.set_target(turn);
        let model = c.during_step::<f64>(1.0, 1.5);
        let x = Vector3::new(2.0, 0.0, 0.0);
        let d = model.displacement(&x);
        // Start pose: translated by (0, 0, 1); the material point now at x (turned, not
        // translated) was at R^T x + (0, 0, 1).
        let expected = x - (turn.rotation.transpose() * x + Vector3::new(0.0, 0.0, 1.0));
        assert!((d - expected).norm() < 1e-15);
        assert!((d.y - 2.0 * s1).abs() < 1e-15);
        c.finish_step(1.5);
        let later = c.pose(2.5);
        assert!((later.translation - Vector3::new(0.0, 0.0, 1.0)).norm() < 1e-15);
        assert_eq!(later.rotation, turn.rotation);
    }
}
