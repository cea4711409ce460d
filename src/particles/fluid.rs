//! The material of a fluid particle body (He et al. 2017, section 6): a liquid kept
//! incompressible by position-based density constraints (Macklin and Mueller 2013) with an
//! implicit viscosity. The solver's side is `crate::solve::particles::fluid`.
//!
//! Units: `viscosity` is the dynamic viscosity `mu` (Pa s); the solver uses the kinematic
//! viscosity `nu = mu / rho0` (m^2/s) with `rho0` the body's density (kg/m^3).
//!
//! **Viscoelastic fluids (section 6: "Lame parameters as constants and phi = 0").** With
//! `shear_modulus = G > 0` the body is also an elastoplastic particle body of the paper's
//! sections 4-5, on top of the fluid terms: the elastic kernel with the calibrated material
//! `E = 5 G / 2`, `nu = 1/4` (near the bond model's own Poisson ratio: on the default lattice
//! the calibration adds a small dilatation term, `kappa` about 0.05 of `c`; `G` is the
//! continuum shear modulus `E / (2 (1 + nu))` of the asked E and nu), and a Drucker-Prager law with
//! `phi = 0` (a von Mises cone: cohesion `c = yield_stress / 2`, so a bar in tension yields at
//! `yield_stress`) whose return moves the bonds' rest shape with the flow, and whose
//! neighbour rebuild on the deformed positions (eq. 20) gives a particle the neighbours it
//! flows next to. The strain up to yield springs back; beyond it, it is kept (the
//! plastic body's machinery, [`super::plasticity`], no second kernel).

use crate::error::{check_param, Result};

use super::elastic::{Elastic, POISSON_RANGE};
use super::plasticity::DruckerPrager;

/// SPH support radius of a fluid, in particle spacings: 32 neighbours on a cubic lattice
/// (distances 1, sqrt 2, sqrt 3 and 2 spacings), as the elastic horizon
/// ([`super::DEFAULT_HORIZON`]).
pub const FLUID_SUPPORT: f64 = 2.2;

/// The bulk moduli a viscoelastic fluid accepts, in shear moduli: those of the Poisson ratios
/// of [`POISSON_RANGE`] (2/3 to 29/3 for 0 to 0.45).
pub const BULK_RANGE: (f64, f64) = (
    bulk_over_shear(POISSON_RANGE.0),
    bulk_over_shear(POISSON_RANGE.1),
);

/// An isotropic solid's `K / G = 2 (1 + nu) / (3 (1 - 2 nu))` at Poisson ratio `nu`.
const fn bulk_over_shear(nu: f64) -> f64 {
    2.0 * (1.0 + nu) / (3.0 * (1.0 - 2.0 * nu))
}

/// How a fluid's density constraints are solved (`crate::solve::particles`' fluid stage).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DensitySolver {
    /// Macklin and Mueller's (2013) Jacobi projections: each pass relinearises and corrects
    /// every constraint by its own Newton step (eq. 11), so a correction travels one kernel
    /// support per pass.
    Jacobi,
    /// Per linearisation, the coupled system of the active constraints solved by conjugate
    /// gradients preconditioned by its diagonal (each iteration one pass), `relaxation`'s
    /// `eps` on that diagonal as Jacobi's.
    ConjugateGradients,
}

impl DensitySolver {
    /// The solver of a name: `"jacobi"` or `"cg"`.
    pub fn of_name(name: &str) -> Result<Self> {
        match name {
            "jacobi" => Ok(Self::Jacobi),
            "cg" => Ok(Self::ConjugateGradients),
            _ => Err(crate::error::invalid!(
                "density_solver must be \"jacobi\" or \"cg\", got {name:?}"
            )),
        }
    }

    /// The solver's name (see [`Self::of_name`]).
    pub fn name(self) -> &'static str {
        match self {
            Self::Jacobi => "jacobi",
            Self::ConjugateGradients => "cg",
        }
    }
}

/// A fluid material; the defaults make a Newtonian liquid (no elasticity).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViscoelasticFluid {
    /// Dynamic viscosity `mu` (Pa s, >= 0; water 1e-3, honey about 10).
    pub viscosity: f64,
    /// Most density projections per step (Macklin and Mueller 2013, Algorithm 1's solver
    /// iterations; a conjugate-gradient iteration counts as one), >= 1.
    pub density_iterations: usize,
    /// The solver of the density constraints (default the conjugate gradients: on a dam
    /// break 4 to 16 times less density time than Jacobi's, and to the tolerance on more
    /// steps; docs/particles/performance.md).
    pub density_solver: DensitySolver,
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
    /// Shear modulus `G` (Pa, >= 0) of the elasticity on top of the fluid terms (see the
    /// module's doc); 0: a Newtonian liquid.
    pub shear_modulus: f64,
    /// The von Mises yield stress (Pa, > 0) beyond which a viscoelastic fluid's strain
    /// flows away (uniaxial; the Drucker-Prager cohesion at `phi = 0` is half of it).
    /// `None`: equal to the shear modulus (a yield strain of 0.4 in tension). Unused at
    /// `shear_modulus = 0`.
    pub yield_stress: Option<f64>,
    /// The bulk modulus `K` (Pa) of a viscoelastic fluid's elasticity, in
    /// [[`BULK_RANGE`]`.0 G`, [`BULK_RANGE`]`.1 G`] (Poisson ratio 0 to 0.45): what holds its
    /// volume in tension, where the one-sided density constraints do not (a bar under the
    /// uniaxial stress `sigma` dilates by `sigma (1 - 2 nu) / E = sigma / (3 K)` elastically;
    /// its plastic flow keeps its bonds' mean strain). `None`: `5 G / 3` (`nu = 1/4`). Unused
    /// at `shear_modulus = 0`.
    pub bulk_modulus: Option<f64>,
    /// Adhesion to the body's ghost particles (its pinned particles: a wall or ceiling):
    /// each ghost with a free fluid neighbour holds a two-sided density constraint on its
    /// free-surface-corrected density, which pulls the liquid back when it draws away
    /// (`crate::solve::particles`' fluid stage). `false`: ghosts hold the one-sided
    /// constraint of every particle.
    pub adhesion: bool,
    /// The liquid's surface tension `sigma` (N/m, >= 0; water 0.072, honey about 0.05-0.07;
    /// 0: none): the cohesion force of Akinci, Akinci and Teschner 2013 (without their curvature
    /// term), its coefficient calibrated on the rest lattice (`crate::solve::particles`' surface
    /// tension).
    pub surface_tension: f64,
    /// The plastic (Bingham) viscosity `eta_p` (Pa s, >= 0) of a viscoelastic fluid's flow
    /// beyond yield: its return relaxes the stress beyond the cone over `tau = eta_p / G`
    /// (Duvaut and Lions' form of Perzyna's overstress law, [`super::cone`]), so a steady flow
    /// carries `sigma_y + 3 eta_p eps_dot` in tension. 0 (the default): rate-independent, the
    /// paper's. Not the Laplacian `viscosity`, which acts on the velocities at every strain,
    /// below yield too. Unused at `shear_modulus = 0`.
    pub plastic_viscosity: f64,
}

impl Default for ViscoelasticFluid {
    fn default() -> Self {
        Self {
            viscosity: 1e-3,
            density_iterations: 50,
            density_solver: DensitySolver::ConjugateGradients,
            density_tolerance: 1e-3,
            relaxation: 0.1,
            redistribution: 0.0,
            redistribution_iterations: 5,
            shear_modulus: 0.0,
            yield_stress: None,
            bulk_modulus: None,
            adhesion: false,
            surface_tension: 0.0,
            plastic_viscosity: 0.0,
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
        check_param(
            "shear_modulus",
            self.shear_modulus,
            |v| v >= 0.0 && (3.0 * v).is_finite(),
            "a finite shear modulus >= 0 Pa whose Young's modulus (up to 2.9 times it) is finite",
        )?;
        check_param(
            "surface_tension",
            self.surface_tension,
            |v| v >= 0.0,
            "a finite surface tension >= 0 N/m",
        )?;
        check_param(
            "plastic_viscosity",
            self.plastic_viscosity,
            |v| v >= 0.0,
            "a finite plastic viscosity >= 0 Pa s",
        )?;
        if let Some(y) = self.yield_stress {
            check_param("yield_stress", y, |v| v > 0.0, "a finite stress > 0 Pa")?;
        }
        if let Some(k) = self.bulk_modulus {
            let g = self.shear_modulus;
            let (lo, hi) = (BULK_RANGE.0 * g, BULK_RANGE.1 * g);
            check_param(
                "bulk_modulus",
                k,
                |v| v > 0.0 && (3.0 * v).is_finite() && (g == 0.0 || (lo..=hi).contains(&v)),
                &format!(
                    "a finite stress > 0 Pa within [{lo}, {hi}] Pa ({} to {} times the shear modulus)",
                    BULK_RANGE.0, BULK_RANGE.1
                ),
            )?;
        }
        Ok(())
    }

    /// The relaxation time `tau = eta_p / G` (s) of the return of a viscoelastic fluid
    /// ([`Self::plastic_viscosity`]); 0 for a Newtonian liquid or a rate-independent return.
    pub fn relaxation_time(&self) -> f64 {
        if self.shear_modulus > 0.0 {
            self.plastic_viscosity / self.shear_modulus
        } else {
            0.0
        }
    }

    /// The elastic material and plastic law of a viscoelastic fluid (see the module's doc),
    /// or `None` for a Newtonian liquid (`shear_modulus = 0`).
    pub fn elastoplastic(&self) -> Option<(Elastic, DruckerPrager)> {
        if self.shear_modulus == 0.0 {
            return None;
        }
        let g = self.shear_modulus;
        // The continuum's `nu = (3 K - 2 G) / (2 (3 K + G))`, `E = 2 G (1 + nu)`.
        let material = match self.bulk_modulus {
            None => Elastic::Young {
                e: 2.5 * g,
                nu: 0.25,
            },
            Some(k) => {
                let nu = (3.0 * k - 2.0 * g) / (2.0 * (3.0 * k + g));
                Elastic::Young {
                    e: 2.0 * g * (1.0 + nu),
                    nu: nu.clamp(POISSON_RANGE.0, POISSON_RANGE.1),
                }
            }
        };
        let law = DruckerPrager {
            friction_angle: 0.0,
            cohesion: 0.5 * self.yield_stress.unwrap_or(g),
            hardening: 0.0,
            rebuild_neighbours: true,
        };
        Some((material, law))
    }
}
