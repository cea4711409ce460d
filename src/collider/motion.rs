//! How a collider moves through a simulation: at time `tau` (s) its shape stands at the pose
//! `x = R b + t + v tau` (shape point `b`, constant velocity `v`), where the base pose
//! `(R, t)` starts as the identity (the geometry as given) and changes only when a target pose
//! is set: [`MovingCollider::set_target`] names the pose the collider reaches at the end of the
//! next step. During that step the collider moves rigidly from its pose at the start to the
//! target (friction sees each material point's own displacement, so a turning collider drags
//! a membrane around); afterwards the velocity carries it on from there.

use nalgebra::Vector3;

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

    /// [`Self::during_step`] in the frame whose origin is the world point `origin` (m,
    /// [`ColliderModel::in_frame`]).
    pub fn during_step_in_frame<T: Real>(
        &self,
        start: f64,
        end: f64,
        origin: &Vector3<f64>,
    ) -> ColliderModel<T> {
        let to = self.target.unwrap_or_else(|| self.pose(end));
        ColliderModel::in_frame(&self.collider, &self.pose(start), &to, origin)
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

    /// Each shape (a box mesh too), turning and moving, 1 km from the world origin: its model in the frame of
    /// an origin next to it gives, in f64, the world model's distance, normal, projection and
    /// material displacement at the world point `origin + x` (to 1e-10 m: only rounding
    /// differs), and in f32 resolves a point 1 mm from its surface to 3e-7 m, where the world
    /// model in f32 holds the point itself only to 6e-5 m (its ulp at 1 km).
    #[test]
    fn a_collider_in_a_frame_acts_where_it_is_in_the_world() {
        let origin = Vector3::new(1000.0, -500.0, 250.0);
        let at = |d: [f64; 3]| [1000.0 + d[0], -500.0 + d[1], 250.0 + d[2]];
        let (c, s) = (0.3f64.cos(), 0.3f64.sin());
        let tilt = [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]];
        let shapes = [
            Shape::plane(at([0.01, 0.0, -0.02]), [0.2, 0.1, 1.0]).unwrap(),
            Shape::sphere(at([0.0, 0.0, -0.5]), 0.45).unwrap(),
            Shape::cuboid(at([0.0, 0.0, -0.2]), [0.3, 0.2, 0.15], tilt).unwrap(),
            Shape::capsule(at([-0.3, 0.0, -0.1]), at([0.3, 0.05, -0.1]), 0.05).unwrap(),
            {
                let (v, t) = crate::collider::sdf::tests::box_mesh([0.3, 0.2, 0.15]);
                let v = v.iter().map(|p| at([p[0], p[1], p[2] - 0.2])).collect();
                Shape::mesh(v, t, 24, None).unwrap()
            },
        ];
        let turn = Pose::new([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], [0.0; 3]).unwrap();
        for shape in shapes {
            let mut moving =
                MovingCollider::new(Collider::new(shape.clone(), 0.2, [0.01, 0.0, 0.0]).unwrap());
            // A small turn about the world origin's z axis, carried back near its place.
            let back = turn.rotation.transpose() * origin;
            moving.set_target(Pose {
                rotation: turn.rotation.transpose(),
                translation: origin - back + Vector3::new(1e-3, 0.0, 0.0),
            });
            let world = moving.during_step::<f64>(0.0, 0.1);
            let framed = moving.during_step_in_frame::<f64>(0.0, 0.1, &origin);
            let narrow = moving.during_step_in_frame::<f32>(0.0, 0.1, &origin);
            let wide_world = moving.during_step::<f32>(0.0, 0.1);
            let mut worst_world = 0.0f64;
            for k in 0..27 {
                let x = Vector3::new((k % 3) as f64, ((k / 3) % 3) as f64, (k / 9) as f64) * 0.1
                    - Vector3::new(0.1, 0.1, 0.05);
                let d = world.signed_distance(&(x + origin));
                assert!((framed.signed_distance(&x) - d).abs() < 1e-10, "{shape:?}");
                assert!((framed.normal(&x) - world.normal(&(x + origin))).norm() < 1e-9);
                let moved = world.project(x + origin, 0.01) - origin;
                assert!(
                    (framed.project(x, 0.01) - moved).norm() < 1e-10,
                    "{shape:?}"
                );
                let carried = world.displacement(&(x + origin));
                assert!(
                    (framed.displacement(&x) - carried).norm() < 1e-10,
                    "{shape:?}"
                );
                // A point 1 mm off the surface, in f32.
                let near = x - world.normal(&(x + origin)) * (d - 1e-3);
                let exact = world.signed_distance(&(near + origin));
                let f32_frame = narrow.signed_distance(&near.map(|c| c as f32)) as f64;
                assert!(
                    (f32_frame - exact).abs() < 3e-7,
                    "{shape:?}: {f32_frame} vs {exact}"
                );
                let f32_world = wide_world.signed_distance(&(near + origin).map(|c| c as f32));
                worst_world = worst_world.max((f32_world as f64 - exact).abs());
            }
            assert!(worst_world > 1e-6, "{shape:?}: {worst_world}");
        }
    }
}
