//! The implicit viscosity of fluid particles (He et al. 2017, section 6, after Mueller et al.
//! 2003): backward Euler of `dv/dt = nu laplacian(v) + g`, `(I + h L) u = v_t + h g`, `nu` the
//! kinematic viscosity (m^2/s), `h` the step (s), `g` gravity (m/s^2), solved at the start of
//! a step on the positions `y_t`, before the inertial prediction `y* = y_t + h u` (the order
//! of position-based fluids: forces and viscosity on the velocity, then predict, then
//! project). The positions the step takes thus feel the viscosity: a liquid held only by its
//! viscosity (honey under a ceiling) moves by `h u`, which the viscosity has slowed; applied
//! after the positions instead, it crept by `g h^2` every step, whatever its viscosity, and
//! parted from its ceiling.
//!
//! The Laplacian is Brookshaw's SPH form (as in Monaghan 2005, eq. 3.77 without the
//! compressible term): `laplacian(v)_i = sum_j c_ij (v_j - v_i)` with
//! `c_ij = 2 V_j |r_ij . grad W_ij| / (|r_ij|^2 + 0.01 H^2)` (1/m^2; `V_j = m_j / rho0_j`,
//! `H` the support radius). It is solved in momentum form, `m_i u_i + h sum_j s_ij (u_i -
//! u_j) = m_i (v_i + h g)` with `s_ij = 2 mu_ij V_i V_j |r_ij . grad W_ij| / (|r_ij|^2 +
//! 0.01 H^2)` (kg/s), `mu_ij` the mean of the two particles' dynamic
//! viscosities `nu rho0` (Pa s): `s` is symmetric, so the forces between two particles are
//! equal and opposite and momentum is conserved whatever their masses (liquids of different
//! densities; a sand grain, a partner of viscosity 0, takes half the liquid's coefficient),
//! and the system matrix `M + h S` is symmetric positive definite. For particles of one
//! liquid it is the velocity form `(I + h L) u = v + h g` multiplied by their common mass.
//!
//! **Lattice normalisation (beyond the paper).** The continuous form is exact (for
//! `v = x^2` the integral of `(v(x + s) - v(x)) 2 |s . grad W| / |s|^2` is 2), but its sum over
//! the few lattice neighbours of a 2.2-spacing support gives 1.58: a liquid would be 21 % less
//! viscous than asked. As the density sums are normalised on the cubic lattice
//! ([`crate::particles::sph`]), the coefficients here are multiplied by
//! `2 / sum_{p in d Z^3} d^3 p_x^2 c(p)` ([`lattice_laplacian_scale`]), which makes the
//! Laplacian of a quadratic field on the rest lattice exact (the plane Poiseuille test checks
//! the viscosity it gives). It is solved by
//! conjugate gradients with a Jacobi preconditioner to a relative residual of the square root
//! of the precision's epsilon (at most [`MAX_CG`] iterations; sums in fixed chunks, the same
//! on any thread count). Pinned particles keep their velocity and drag their neighbours.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::parallel::chunked_sum;
use crate::real::Real;
use crate::solve::points::Points;

use crate::particles::brookshaw_scale;
use crate::particles::sph::Sph;

/// What the viscosity solve reads of the fluid particles (one entry per particle unless said):
/// the kernel, the CSR neighbour lists, positions (m), masses (kg), rest densities (kg/m^3),
/// kinematic viscosities (m^2/s), each particle's index in the family, and the step (s).
pub(crate) struct Fluid<'a, T: Real> {
    pub sph: &'a Sph,
    pub offsets: &'a [u32],
    pub indices: &'a [u32],
    pub y: &'a [Vector3<T>],
    pub mass: &'a [T],
    pub rest_density: &'a [T],
    pub nu: &'a [T],
    pub members: &'a [u32],
    /// Partners (`super::fluid::partners`): they keep their velocity, as pinned particles do.
    pub partner: &'a [bool],
    pub h: T,
}

/// Most conjugate-gradient iterations of one viscosity solve.
pub const MAX_CG: usize = 200;

/// The factor that makes the Brookshaw Laplacian of the kernel `sph` exact for quadratic
/// fields on the cubic lattice of `spacing` (m): `2 / sum_p d^3 p_x^2 2 |p . grad W(p)| /
/// (|p|^2 + 0.01 H^2)` over the lattice vectors `p` (see the module's doc; dimensionless).
pub(crate) fn lattice_laplacian_scale(sph: &Sph, spacing: f64) -> f64 {
    let support2 = 0.01 * sph.radius * sph.radius;
    brookshaw_scale(sph.radius, spacing, spacing.powi(3), |p| {
        2.0 * p.dot(&sph.gradient(p)).abs() / (p.norm_squared() + support2)
    })
}

/// The viscosity solve's buffers (one entry per fluid particle, one coefficient per bond).
pub(crate) struct Viscosity<T: Real> {
    /// [`lattice_laplacian_scale`] of the family's kernel.
    scale: T,
    coefficient: Vec<T>,
    diagonal: Vec<T>,
    x: Vec<Vector3<T>>,
    r: Vec<Vector3<T>>,
    p: Vec<Vector3<T>>,
    ap: Vec<Vector3<T>>,
    free: Vec<bool>,
    chunks: Vec<f64>,
    /// Conjugate-gradient iterations of the last solve.
    pub iterations: usize,
}

impl<T: Real> Viscosity<T> {
    /// Buffers for `n` particles, the Laplacian multiplied by `scale`.
    pub fn new(n: usize, scale: f64) -> Self {
        Self {
            scale: T::of(scale),
            coefficient: Vec::new(),
            diagonal: vec![T::zero(); n],
            x: vec![Vector3::zeros(); n],
            r: vec![Vector3::zeros(); n],
            p: vec![Vector3::zeros(); n],
            ap: vec![Vector3::zeros(); n],
            free: vec![false; n],
            chunks: Vec::new(),
            iterations: 0,
        }
    }

    /// `(A v)_i = m_i v_i + sum_j k_ij (v_i - v_j)` (`k = h s`, `m` the masses, kg) for the
    /// free particles, 0 for the pinned ones.
    fn apply_matrix(&mut self, offsets: &[u32], indices: &[u32], mass: &[T]) {
        let (k, p, free) = (&self.coefficient, &self.p, &self.free);
        self.ap.par_iter_mut().enumerate().for_each(|(i, out)| {
            if !free[i] {
                *out = Vector3::zeros();
                return;
            }
            let mut sum = p[i] * mass[i];
            for b in offsets[i] as usize..offsets[i + 1] as usize {
                sum += (p[i] - p[indices[b] as usize]) * k[b];
            }
            *out = sum;
        });
    }

    fn dot(chunks: &mut Vec<f64>, a: &[Vector3<T>], b: &[Vector3<T>]) -> f64 {
        chunked_sum(a.len(), chunks, |i| a[i].dot(&b[i]).to_f64())
    }

    /// Solves `(M + h S) u = M (v + kick)` (see the module's doc) for the free fluid particles (`v` their velocities in
    /// `points`, m/s; `kick` a velocity change every free particle receives first, m/s; the
    /// pinned ones keep their velocity, a Dirichlet condition) and stores `u - kick` as their
    /// velocity; positions are not touched.
    pub fn apply(&mut self, stage: &Fluid<'_, T>, points: &mut Points<T>, kick: Vector3<T>) {
        let n = stage.members.len();
        let h = stage.h;
        let (offsets, indices) = (stage.offsets, stage.indices);
        let (y, mass, rho0, nu) = (stage.y, stage.mass, stage.rest_density, stage.nu);
        let support2 = T::of(0.01 * stage.sph.radius * stage.sph.radius);
        self.coefficient.resize(indices.len(), T::zero());
        let (sph, scale) = (stage.sph, self.scale);
        self.coefficient
            .par_iter_mut()
            .enumerate()
            .for_each(|(b, k)| {
                let i = offsets.partition_point(|&o| o as usize <= b) - 1;
                let j = indices[b] as usize;
                let d = y[i] - y[j];
                let mu = (nu[i] * rho0[i] + nu[j] * rho0[j]) * T::of(0.5);
                let volumes = mass[i] / rho0[i] * (mass[j] / rho0[j]);
                let s = T::of(2.0) * scale * mu * volumes * d.dot(&sph.gradient(&d)).abs()
                    / (d.norm_squared() + support2);
                *k = h * s;
            });
        let (members, pinned) = (stage.members, &points.pinned);
        for (i, free) in self.free.iter_mut().enumerate() {
            *free = !pinned[members[i] as usize] && !stage.partner[i];
        }
        let k = &self.coefficient;
        self.diagonal.par_iter_mut().enumerate().for_each(|(i, d)| {
            let mut sum = mass[i];
            for &kb in &k[offsets[i] as usize..offsets[i + 1] as usize] {
                sum += kb;
            }
            *d = sum;
        });
        for ((x, &m), &free) in self.x.iter_mut().zip(members).zip(&self.free) {
            *x = points.velocity[m as usize] + if free { kick } else { Vector3::zeros() };
        }
        // r = b - A x with b = M x (the momenta), so r = sum_j k_ij (x_j - x_i).
        std::mem::swap(&mut self.p, &mut self.x);
        self.apply_matrix(offsets, indices, mass);
        std::mem::swap(&mut self.p, &mut self.x);
        {
            let (x, ap, free) = (&self.x, &self.ap, &self.free);
            self.r.par_iter_mut().enumerate().for_each(|(i, r)| {
                *r = if free[i] {
                    x[i] * mass[i] - ap[i]
                } else {
                    Vector3::zeros()
                };
            });
        }
        let x = &self.x;
        let scale = chunked_sum(n, &mut self.chunks, |i| {
            (x[i] * mass[i]).norm_squared().to_f64()
        });
        let tol2 = T::default_epsilon().to_f64() * scale.max(f64::MIN_POSITIVE);
        let (r, diagonal) = (&self.r, &self.diagonal);
        self.p
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, p)| *p = r[i] / diagonal[i]);
        let mut rz = Self::dot(&mut self.chunks, &self.r, &self.p);
        self.iterations = 0;
        while self.iterations < MAX_CG && Self::dot(&mut self.chunks, &self.r, &self.r) > tol2 {
            self.apply_matrix(offsets, indices, mass);
            let pap = Self::dot(&mut self.chunks, &self.p, &self.ap);
            if pap <= 0.0 || pap.is_nan() {
                break;
            }
            let alpha = T::of(rz / pap);
            {
                let (p, ap) = (&self.p, &self.ap);
                self.x
                    .par_iter_mut()
                    .zip(self.r.par_iter_mut())
                    .enumerate()
                    .for_each(|(i, (x, r))| {
                        *x += p[i] * alpha;
                        *r -= ap[i] * alpha;
                    });
            }
            let (r, diagonal) = (&self.r, &self.diagonal);
            let rz_next = chunked_sum(n, &mut self.chunks, |i| {
                (r[i].dot(&r[i]) / diagonal[i]).to_f64()
            });
            let beta = T::of(rz_next / rz);
            rz = rz_next;
            self.p
                .par_iter_mut()
                .enumerate()
                .for_each(|(i, p)| *p = r[i] / diagonal[i] + *p * beta);
            self.iterations += 1;
        }
        for ((x, &m), &free) in self.x.iter().zip(members).zip(&self.free) {
            if free {
                points.velocity[m as usize] = x - kick;
            }
        }
    }
}
