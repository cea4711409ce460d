//! Particle bodies (He, Wang and Wu 2017, "Projective Peridynamics for Modeling Versatile
//! Elastoplastic Materials"): the body ([`Particles`]) with its horizons
//! ([`crate::geometry::find_horizons`]) and elastic material ([`Elastic`]), the influence
//! function, the deformation gradient with inversion handling, the per-bond local step and
//! forces, the rest data the solver steps with, the lattice-sum calibration, and the sampling
//! of particles from meshes ([`sample_volume`], [`sample_surface`]); shells and rods with their
//! ghost particles ([`Particles::shell`], [`Particles::rod`]).

mod body;
mod bond;
pub mod calibration;
mod cone;
mod deformation;
mod elastic;
mod fluid;
mod granular;
mod influence;
mod kernel;
mod lattice;
mod measure;
mod neighbour_rebuild;
mod plasticity;
pub mod redistribution;
mod rest;
mod rest_bonds;
mod sampling;
pub mod sph;
pub mod sph_deficiency;
pub mod surface;
mod thin;
mod wet_sand;
mod wicking;

pub use body::{
    MaterialState, ParticleParams, Particles, RegionMaterial, DEFAULT_HORIZON, FLUID_PLACEHOLDER,
};
pub use bond::{bond_force, BondRest};
pub use calibration::{calibrate, lattice_moduli, LatticeModuli, Moduli};
pub use cone::{Cone, Factors};
pub use deformation::{deformation_gradient, uninverted};
pub use elastic::{Elastic, POISSON_RANGE};
pub use fluid::{DensitySolver, ViscoelasticFluid, FLUID_SUPPORT};
pub(crate) use granular::density_ratios;
pub use granular::{holds, Granular};
pub use influence::influence;
pub use kernel::{evaluate_energies, evaluate_particles, particle_force, particle_kernel};
pub(crate) use lattice::{brookshaw_scale, lattice_sum};
pub use neighbour_rebuild::{rebuild as rebuild_neighbours, MIN_STRETCH};
pub(crate) use plasticity::PlasticLaw;
pub use plasticity::{shear_and_bulk, DruckerPrager, YieldState};
pub use rest::ParticleRest;
pub(crate) use rest::RestConstants;
pub use rest_bonds::RestBonds;
pub use sampling::{sample_surface, sample_volume, MAX_PARTICLES, MAX_SURFACE_CANDIDATES};
pub use thin::MAX_SECTION;
pub use wet_sand::{wetted, WETTING_FRACTION};
pub(crate) use wicking::Wicking;
pub use wicking::{DEFAULT_WICKING, MAX_WICKING, MAX_WICKING_SUBSTEPS};

#[cfg(test)]
mod plasticity_tests;
#[cfg(test)]
mod tests;
