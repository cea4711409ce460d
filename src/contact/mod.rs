//! Contact handling (Lu et al. 2023, section 6): colliders (analytic shapes and meshes as signed
//! distance grids, with motion and friction), primitive distances, additive CCD, the barrier, the
//! broad phase and the contact local step of Algorithm 2.

pub mod barrier;
mod barrier_push;
mod bounds;
pub mod broad_phase;
pub mod ccd;
mod collider;
mod counting_sort;
pub mod distance;
mod distance_order;
pub mod local_step;
mod motion;
mod pair_cache;
mod parallel_fade;
mod patches;
mod pose;
mod primitive_pairs;
mod regions;
mod sdf;
mod sweep;
#[cfg(test)]
mod test_meshes;
mod vertex_index;

pub use broad_phase::{BroadPhase, ContactMesh};
pub use collider::{push_out_of_colliders, Collider, ColliderModel, MoveStart, Shape, ShapeModel};
pub(crate) use collider::{TOUCH_DISTANCE, TRACE_STEPS, TRACE_TOLERANCE};
pub use local_step::{
    resolve_contacts, ContactParams, ContactStats, DescentStep, ProximalMetric, ProximalWeights,
    PushOut, Workspace,
};
pub use motion::MovingCollider;
pub use parallel_fade::default_parallel_angle;
pub use pose::{rotation_matrix, Pose};
pub use primitive_pairs::closest_primitive_distance;
pub use sdf::SdfGrid;
