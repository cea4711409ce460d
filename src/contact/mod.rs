//! Contact handling (Lu et al. 2023, section 6): analytic colliders, primitive distances,
//! additive CCD, the barrier, the broad phase and the contact local step of Algorithm 2.

pub mod barrier;
pub mod broad_phase;
pub mod ccd;
mod collider;
pub mod distance;

pub use collider::{Collider, ColliderModel};
