//! Colliders, shared by every body family, the contact local step and the GPU: analytic shapes
//! and closed meshes as signed distance grids ([`Shape`], [`sdf::SdfGrid`]), their poses and
//! motion through a simulation ([`Pose`], [`MovingCollider`]), and the passes that keep a point
//! out of them: along the shape's normal ([`push_out_of_colliders`]), or in a move's own
//! metric with Coulomb friction ([`push_out_with_friction`]).

mod crossing;
mod friction;
pub(crate) mod motion;
pub(crate) mod pose;
pub(crate) mod sdf;
mod shape;

pub(crate) use crossing::{TOUCH_DISTANCE, TRACE_STEPS, TRACE_TOLERANCE};
pub use friction::{coulomb_share, push_out_with_friction};
pub use motion::MovingCollider;
pub use pose::{rotation_matrix, Pose};
pub use sdf::{MeshDistance, SdfGrid};
pub use shape::{push_out_of_colliders, Collider, ColliderModel, MoveStart, Shape, ShapeModel};
pub(crate) use shape::{PUSH_ROUNDS, PUSH_SETTLE_ULPS};
