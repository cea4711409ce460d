//! A liquid's surface tension (`ViscoelasticFluid::surface_tension`, sigma in N/m): the
//! cohesion force of Akinci, Akinci and Teschner 2013 ("Versatile surface tension and adhesion
//! for SPH fluids", eq. 1, 2 and 4; AAT13), an explicit force on the velocities at a
//! step's start, before the implicit viscosity and the inertial prediction (the order of
//! position-based fluids: forces on the velocity, then predict, then project), on the
//! positions and neighbour lists of the step's start.
//!
//! **The pair force** on particle `i` from its neighbour `j` (N), AAT13's cohesion with their
//! symmetric correction: `f_ij = -gamma_ij K_ij m_i m_j C(r) r_ij / r`, with
//! - `C` the cohesion spline of AAT13 eq. 2 (1/m^3), support `H` the fluid kernel's
//!   ([`crate::particles::FLUID_SUPPORT`] spacings): `32 / (pi H^9) (H - r)^3 r^3` for
//!   `H / 2 < r <= H`, `32 / (pi H^9) (2 (H - r)^3 r^3 - H^6 / 64)` for `0 < r <= H / 2`;
//!   attractive at every lattice distance of a 2.2-spacing support, repulsive only below
//!   0.26 `H`; `r_ij = y_i - y_j` (m);
//! - `K_ij = 2 rho0_ij / (rho_i + rho_j)` (AAT13 eq. 4, `rho0_ij` the mean rest density, `rho`
//!   the plain SPH density, kg/m^3): larger than 1 where the sums miss neighbours, so the
//!   surface, whose particles have fewer neighbours to pull them, is pulled as hard as the
//!   bulk;
//! - `gamma_ij` the mean of the two members' coefficients, 0 where either has none (a partner,
//!   a liquid without surface tension).
//!
//! **Departure: no curvature term.** AAT13's second term, `-gamma (n_i - n_j)` with the
//! surface normals `n_i = H sum_j V_j grad W_ij`, written as a force at the cohesion kernel's
//! peak (`C(H / 2) m_i m_j (n_i - n_j)`: their acceleration form's units differ from the
//! cohesion's by a density), drove a resting ball of water apart within 0.1 s at 0.25 N/m
//! with either sign of the normals, and at a twentieth of that weight (about AAT13's own for
//! water) its outermost particles crept out (docs/particles/fluids.md, round x); the cohesion
//! with `K_ij` alone holds the ball.
//!
//! `f_ji = -f_ij` exactly (every factor is symmetric in `i, j` or changes sign with the
//! exchange, in the same floating-point operations), so the forces conserve momentum; inside a
//! uniform lattice the cohesion sums cancel by symmetry.
//!
//! **Calibration (`gamma` from `sigma`).** Cutting the rest lattice along a plane and drawing
//! the halves apart takes the work `2 sigma` per unit area; the cohesion pairs across the cut
//! with lattice vector `p` (`p_z > 0`) number `p_z / d^3` per unit area, and each pair's force
//! does `gamma m^2 int_|p|^H C(r) dr` as it parts, so `gamma = 2 sigma / (m^2 S)`,
//! `S = sum_{p_z > 0} p_z / d^3 int_|p|^H C(r) dr` (1/m^5; [`gamma_per_tension`]), `K_ij = 1`
//! in the bulk. The tension this gives, measured on oscillating drops, is in
//! docs/particles/fluids.md (fluids, round x) and tests/test_surface_tension.py.
//!
//! Pinned particles (ghosts) pull and are pulled, but keep their velocity; partners (sand
//! grains, a mixed body's solid particles) take no part.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::particles::lattice_sum;
use crate::real::Real;
use crate::solve::points::Points;

use super::fluid_viscosity::Fluid;

/// AAT13's cohesion spline `C(r)` (1/m^3) of support `h` (m) at the distance `r` (m); 0 at
/// `r = 0` and beyond the support.
#[inline]
pub(crate) fn cohesion<T: Real>(h: T, r: T) -> T {
    if r >= h || r <= T::zero() {
        return T::zero();
    }
    let c = T::of(32.0 / std::f64::consts::PI) / h.powi(9);
    let q = (h - r).powi(3) * r.powi(3);
    if r + r > h {
        c * q
    } else {
        c * (q + q - h.powi(6) / T::of(64.0))
    }
}

/// `int_a^h C(r) dr` (1/m^2) by Simpson's rule on the spline's two polynomial pieces (exact for
/// their degree 6 up to round-off with 64 intervals each).
fn cohesion_integral(h: f64, a: f64) -> f64 {
    let simpson = |lo: f64, hi: f64| {
        if hi <= lo {
            return 0.0;
        }
        let n = 64;
        let dx = (hi - lo) / n as f64;
        let mut sum = cohesion(h, lo) + cohesion(h, hi);
        for k in 1..n {
            let weight = if k % 2 == 1 { 4.0 } else { 2.0 };
            sum += weight * cohesion(h, lo + k as f64 * dx);
        }
        sum * dx / 3.0
    };
    let mid = 0.5 * h;
    simpson(a.min(mid), mid) + simpson(a.max(mid), h)
}

/// `gamma / sigma` (m^2/kg^2) on the rest lattice of `spacing` (m) and particle `mass` (kg)
/// with the support `radius` (m): `2 / (m^2 S)` (see the module's doc).
pub(crate) fn gamma_per_tension(radius: f64, spacing: f64, mass: f64) -> f64 {
    let cut = lattice_sum(radius, spacing, |p| {
        if p.z > 0.0 {
            p.z / spacing.powi(3) * cohesion_integral(radius, p.norm())
        } else {
            0.0
        }
    });
    2.0 / (mass * mass * cut)
}

/// The surface tension's coefficients and buffers (one entry per member of the fluid stage).
pub(crate) struct SurfaceTension<T: Real> {
    /// Per member, `gamma` (N m^3/kg^2; 0: none).
    gamma: Vec<T>,
    /// Whether any member has a surface tension.
    any: bool,
    density: Vec<T>,
    force: Vec<Vector3<T>>,
}

impl<T: Real> SurfaceTension<T> {
    /// The coefficients `gamma` (N m^3/kg^2, one per member; 0 where none, as for partners).
    pub fn new(gamma: Vec<f64>) -> Self {
        let n = gamma.len();
        Self {
            any: gamma.iter().any(|&g| g > 0.0),
            gamma: gamma.into_iter().map(T::of).collect(),
            density: vec![T::zero(); n],
            force: vec![Vector3::zeros(); n],
        }
    }

    /// Whether any member has a surface tension (else [`Self::apply`] need not run).
    pub fn any(&self) -> bool {
        self.any
    }

    /// Each member's force (N) at the positions `stage.y` into `self.force` (see the module's
    /// doc): the densities, then the pair sums, each in neighbour order.
    pub fn forces(&mut self, stage: &Fluid<'_, T>) {
        let (sph, offsets, indices, y, mass) =
            (stage.sph, stage.offsets, stage.indices, stage.y, stage.mass);
        sph.densities(y, offsets, indices, mass, &mut self.density);
        let (gamma, density) = (&self.gamma, &self.density);
        self.force.par_iter_mut().enumerate().for_each(|(i, f)| {
            let mut sum = Vector3::zeros();
            if gamma[i] > T::zero() {
                for &j in &indices[offsets[i] as usize..offsets[i + 1] as usize] {
                    sum += pair(stage, (gamma, density), i, j as usize);
                }
            }
            *f = sum;
        });
    }

    /// Adds `h f_i / m_i` to the velocity of every free member (neither pinned nor a partner)
    /// after [`Self::forces`] (`stage.h` the step, s).
    pub fn apply(&mut self, stage: &Fluid<'_, T>, points: &mut Points<T>) {
        self.forces(stage);
        let h = stage.h;
        for (i, &k) in stage.members.iter().enumerate() {
            let k = k as usize;
            if !points.pinned[k] && !stage.partner[i] {
                points.velocity[k] += self.force[i] * (h / stage.mass[i]);
            }
        }
    }

    /// The last [`Self::forces`] (N, per member).
    #[cfg(test)]
    pub fn force(&self) -> &[Vector3<T>] {
        &self.force
    }
}

/// The force `f_ij` (N) on member `i` from member `j` (see the module's doc) with the members'
/// coefficients and densities; 0 where either has no surface tension.
#[inline]
fn pair<T: Real>(
    stage: &Fluid<'_, T>,
    (gamma, density): (&[T], &[T]),
    i: usize,
    j: usize,
) -> Vector3<T> {
    if gamma[i] <= T::zero() || gamma[j] <= T::zero() {
        return Vector3::zeros();
    }
    let h = T::of(stage.sph.radius);
    let d = stage.y[i] - stage.y[j];
    let r = d.norm();
    let pull = if r > T::zero() {
        d * (cohesion(h, r) / r)
    } else {
        Vector3::zeros()
    };
    let k = (stage.rest_density[i] + stage.rest_density[j]) / (density[i] + density[j]);
    let scale = (gamma[i] + gamma[j]) * T::of(0.5) * k * (stage.mass[i] * stage.mass[j]);
    -pull * scale
}

#[cfg(test)]
#[path = "surface_tension_tests.rs"]
mod tests;
