//! Particles from triangle meshes: a solid's volume on a jittered cubic lattice
//! ([`sample_volume`], each particle standing for `spacing^3` of material) and a single layer on
//! a surface for shells ([`sample_surface`], Poisson-disk-like, at least `spacing` apart).
//! Both are deterministic for a seed and do not depend on the number of threads.

mod random;
mod surface;
mod volume;

pub use surface::{sample_surface, sample_surface_with_normals, MAX_SURFACE_CANDIDATES};
pub use volume::sample_volume;

use crate::error::{check_param, Result};

/// Most particles a sampler returns (24 bytes each as `f64` positions: 1.6 GB); a request
/// expected to give more is refused with an error naming the count.
pub const MAX_PARTICLES: usize = 1 << 26;

/// Checks a sampling `spacing` (m): finite and positive.
fn check_spacing(spacing: f64) -> Result<f64> {
    check_param("spacing", spacing, |s| s > 0.0, "a finite length > 0 m")
}

#[cfg(test)]
mod tests;
