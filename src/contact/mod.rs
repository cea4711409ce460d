//! Contact between membranes (Lu et al. 2023, section 6): the broad phase, additive CCD, the
//! barrier and the contact local step of Algorithm 2. Colliders are in [`crate::collider`],
//! primitive distances and bounds in [`crate::geometry`].

pub mod barrier;
mod barrier_push;
pub mod broad_phase;
pub mod ccd;
mod distance_order;
pub mod local_step;
mod pair_cache;
mod parallel_fade;
mod patches;
mod primitive_pairs;
mod regions;
mod sweep;
#[cfg(test)]
mod test_meshes;

pub use broad_phase::{BroadPhase, ContactMesh};
pub use local_step::{
    resolve_contacts, ContactParams, ContactStats, DescentStep, ProximalMetric, ProximalWeights,
    PushOut, SavedRestGap, SavedRestGaps, Workspace, D_HAT_PER_THICKNESS,
};
pub use parallel_fade::default_parallel_angle;
pub use primitive_pairs::closest_primitive_distance;
