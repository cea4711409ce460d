//! The particle family of the time step (He et al. 2017, section 4): every particle body's
//! rest data beside its points ([`ParticleSystem`]), the kernel's evaluations, the global
//! solvers of Fig. 7 (Jacobi, Jacobi + Chebyshev, position-based averaging, direct sparse
//! Cholesky) and the Armijo line search of eq. 13 on the residual of eq. 12.

mod aggregate_matrix;
mod chebyshev;
mod coarse;
mod coarse_problem;
mod contact_gap;
mod density_rest;
mod density_system;
mod density_walls;
mod direct;
mod directions;
mod evaluation;
mod exact_iterate;
mod family;
mod fluid;
mod fluid_viscosity;
mod grain_contacts;
mod grain_friction;
mod grain_rolling;
mod plastic;
mod repulsion;
mod roundoff;
mod settled_move;
mod static_friction;
mod step;
mod surface_tension;
mod system;
mod two_level;

pub(crate) use system::ParticleSystem;

#[cfg(test)]
mod tests;

#[cfg(test)]
mod thin_tests;

#[cfg(test)]
mod repulsion_tests;

#[cfg(test)]
mod rolling_tests;
