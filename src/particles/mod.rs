//! Particle bodies (He, Wang and Wu 2017, "Projective Peridynamics for Modeling Versatile
//! Elastoplastic Materials"): so far the sampling of particles from meshes, a volume on a
//! regular lattice ([`sample_volume`]) and a single layer on a surface ([`sample_surface`]).
//! Their horizons come from [`crate::geometry::find_horizons`].

mod sampling;

pub use sampling::{sample_surface, sample_volume, MAX_PARTICLES, MAX_SURFACE_CANDIDATES};
