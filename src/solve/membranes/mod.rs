//! The membrane family of the time step (Lu et al. 2023): every membrane's rest data and
//! kernel scratch beside its points ([`MembraneSystem`]), the vertex kernel's evaluation and
//! energy, the SISSM Jacobi move (eq. 25-33), the descent baseline of Wang and Yang 2016, Newton's
//! method with its Hessian model (issue 44), and
//! the solver's side of membrane contact (the call of Algorithm 2 after each global step, and
//! the contact reaction it realised).

pub(crate) mod auto;
mod coarse;
pub(crate) mod contact_step;
pub(crate) mod descent;
pub(crate) mod evaluate;
mod family;
pub(crate) mod hessian_model;
pub(crate) mod jacobi;
pub(crate) mod newton;
mod reaction;
mod system;

pub(crate) use system::MembraneSystem;

#[cfg(test)]
mod newton_tests;
