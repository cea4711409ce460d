//! The material of a fluid particle body (He et al. 2017, section 6): a liquid kept
//! incompressible by position-based density constraints (Macklin and Mueller 2013) with an
//! implicit viscosity. The solver's side is `crate::solve::particles::fluid`.
//!
//! Units: `viscosity` is the dynamic viscosity `mu` (Pa s); the solver uses the kinematic
//! viscosity `nu = mu / rho0` (m^2/s) with `rho0` the body's density (kg/m^3).

use crate::error::{check_param, Result};

/// SPH support radius of a fluid, in particle spacings: 32 neighbours on a cubic lattice
/// (distances 1, sqrt 2, sqrt 3 and 2 spacings), as the elastic horizon
/// ([`super::DEFAULT_HORIZON`]).
pub const FLUID_SUPPORT: f64 = 2.2;

/// A fluid material; the defaults make a Newtonian liquid (no elasticity).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViscoelasticFluid {
    /// Dynamic viscosity `mu` (Pa s, >= 0; water 1e-3, honey about 10).
    pub viscosity: f64,
    /// Most density projections per step (Macklin and Mueller 2013, Algorithm 1's solver
    /// iterations), >= 1.
    pub density_iterations: usize,
    /// The projections stop once no particle is denser than `rho0 (1 + density_tolerance)`
    /// (relative, in (0, 0.1]).
    pub density_tolerance: f64,
    /// Relaxation `eps` of the constraints' denominator (Macklin and Mueller 2013, eq. 11), as
    /// a fraction of that denominator at an interior particle of the rest lattice (> 0): the
    /// default 0.1 shortens a lone constraint's Newton step by 1/11, damping the Jacobi
    /// overshoot of neighbouring constraints corrected at once (1 halves it and converges
    /// more slowly: a 16-layer column then sank 2 % where 0.1 keeps it within 0.5 %).
    pub relaxation: f64,
    /// Strength `delta` of the particle redistribution (He et al. 2017, eq. 21-24 corrected,
    /// [`super::redistribution`]), in [0, 1]; 0: none.
    pub redistribution: f64,
    /// Redistribution passes per step (the paper: 3 to 10), in [1, 100].
    pub redistribution_iterations: usize,
}

impl Default for ViscoelasticFluid {
    fn default() -> Self {
        Self {
            viscosity: 1e-3,
            density_iterations: 50,
            density_tolerance: 1e-3,
            relaxation: 0.1,
            redistribution: 0.0,
            redistribution_iterations: 5,
        }
    }
}

impl ViscoelasticFluid {
    /// Checks every parameter, naming the first bad one.
    pub fn validate(&self) -> Result<()> {
        check_param(
            "viscosity",
            self.viscosity,
            |v| v >= 0.0,
            "a finite dynamic viscosity >= 0 Pa s",
        )?;
        check_param(
            "density_iterations",
            self.density_iterations as f64,
            |v| v >= 1.0,
            "at least 1",
        )?;
        check_param(
            "density_tolerance",
            self.density_tolerance,
            |v| v > 0.0 && v <= 0.1,
            "a relative density error in (0, 0.1]",
        )?;
        check_param(
            "relaxation",
            self.relaxation,
            |v| v > 0.0,
            "a finite fraction > 0",
        )?;
        check_param(
            "redistribution",
            self.redistribution,
            |v| (0.0..=1.0).contains(&v),
            "a strength in [0, 1]",
        )?;
        check_param(
            "redistribution_iterations",
            self.redistribution_iterations as f64,
            |v| (1.0..=100.0).contains(&v),
            "in [1, 100]",
        )?;
        Ok(())
    }
}
