//! Contact handling. For now: analytic colliders (with motion and friction) in the local step.

mod collider;

pub use collider::{Collider, ColliderModel, Shape, ShapeModel};
