//! Contact handling. For now: analytic colliders projected in the local step.

mod collider;

pub use collider::{Collider, ColliderModel};
