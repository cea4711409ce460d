//! The per-vertex kernel: deformation, energy, its exact gradient with respect to the vertex's
//! bonds, and the SISSM preconditioner block.
//!
//! ## Deformation (Lu et al. 2023, eq. 13-15, Kirchhoff-Love form)
//!
//! With the rest frame `(t1, t2, nc)` and bond weights `beta` of [`super::RestData`], the
//! deformed tangent vectors are `a_k = F t_k = sum_j beta_jk (y_j - y_i)` (eq. 15 restricted to
//! the tangent plane, where the virtual bond drops out) and the deformed director is the unit
//! normal `n = (a1 x a2) / |a1 x a2|`. The deformation gradient is
//! `F = a1 t1^T + a2 t2^T + n nc^T`: the normal stays normal and unstretched, so the principal
//! stretches are the two singular values of `T = [a1 a2]` and 1, and `det F >= 0`.
//!
//! Choosing the director orthogonal to `T` (rather than the angle-weighted normal of the
//! deformed mesh) keeps the energy an exact function of the positions: the stretch energy is
//! stationary with respect to the director (its stress along `nc` is parallel to `n`), so the
//! gradient below is exact, rotations give zero force, and forces and torques balance.
//!
//! ## Energy of vertex i
//!
//! `E_i = V_i Psi(sigma_1, sigma_2, 1) + E_bend + E_hourglass`, from the non-affine residuals
//! `q_j = F^-1 (y_j - y_i) - xi_j` (zero for every affine map of a flat sheet):
//!
//! - bending (eq. 42 made isotropic): the normal residuals of a bent sheet are
//!   `q_j . nc = 1/2 xi_j^T H xi_j` with H the curvature tensor, so H is fitted to them by least
//!   squares over the 1-ring and `E_bend = A_i D / 2 |H|_F^2 = 1/2 |sum_j c_j (q_j . nc)|^2`
//!   with per-bond vectors `c_j` (`BondRest::curvature`) computed at rest;
//! - hourglass: `E_hourglass = kappa_t / 2 sum_j |q_j - nc (q_j . nc)|^2`, a penalty on the
//!   in-plane zero-energy modes of the 1-ring deformation gradient (a checkerboard
//!   displacement leaves F unchanged).
//!
//! ## Gradient
//!
//! `dE_i/d(y_j - y_i) = beta_j1 g_1 + beta_j2 g_2 + d_j`, with `g_k = dE_i/da_k` and
//! `d_j = F^-T W_j q_j`, `W_j q = kappa_t (q - nc (q . nc)) + nc (c_j . h)` (the explicit bending
//! term of eq. 43 with `F^-T`, see DESIGN.md). The
//! stretch part is `g_k = V_i sum_m P_m u_m v_mk` (`T = U diag(sigma) V^T`, eq. 19); the
//! non-affine part adds `-(sum_j d_j (F^-1 e_j)^T) t_k` and the director term
//! `a2 x p`, `p x a1` with `p = (I - n n^T) h / |a1 x a2|`, `h = -(sum_j d_j (F^-1 e_j)^T) nc`.
//!
//! ## Preconditioner (eq. 24-26)
//!
//! `C_i = V_i k [w_1 u1 u1^T + w_2 u2 u2^T + w_n n n^T] + kappa_t sum_m u_m u_m^T / sigma_m^2
//! + kappa_n n n^T` with `kappa_n = lambda_max(sum_j c_j c_j^T)` bounding the bending term: the Hessian of the quadratic model `1/2 sum_j e_j^T C_i e_j` whose bond
//! Laplacian SISSM inverts approximately; see [`Preconditioner`] for the stretching weights.

use nalgebra::{Matrix3, Vector3};

use crate::real::Real;

use super::{Stencil, VertexConstants};

/// What the kernel reports for one vertex.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VertexResponse<T: Real> {
    /// Stretching energy `V_i Psi` (J).
    pub stretch: T,
    /// Bending energy (J).
    pub bending: T,
    /// Hourglass energy (J).
    pub hourglass: T,
    /// Preconditioner block `C_i` (N/m), symmetric positive semi-definite.
    pub precond: Matrix3<T>,
}

impl<T: Real> VertexResponse<T> {
    /// Total energy of the vertex (J).
    #[inline]
    pub fn energy(&self) -> T {
        self.stretch + self.bending + self.hourglass
    }
}

/// The local deformation of a vertex: `T = [a1 a2] = U diag(sigma) V^T`, director `n`.
#[derive(Debug, Clone, Copy)]
pub struct Deformation<T: Real> {
    pub a1: Vector3<T>,
    pub a2: Vector3<T>,
    /// `|a1 x a2| = sigma_1 sigma_2` (area ratio).
    pub area_ratio: T,
    /// Unit director, orthogonal to `a1` and `a2`.
    pub normal: Vector3<T>,
    /// Left singular vectors (deformed tangent plane); `(u1, u2, normal)` is right-handed.
    pub u: [Vector3<T>; 2],
    /// Right singular vectors in `(t1, t2)` coordinates, a rotation (det = +1).
    pub v: [[T; 2]; 2],
    /// Singular values, descending, clamped from below at [`Real::min_stretch`].
    pub sigma: [T; 2],
}

impl<T: Real> Deformation<T> {
    /// Principal stretches (two in-plane, descending, then the unstretched normal).
    #[inline]
    pub fn stretches(&self) -> [T; 3] {
        [self.sigma[0], self.sigma[1], T::one()]
    }

    /// Computes the deformation of vertex `i` at `yi` from its neighbours' positions.
    #[inline]
    pub fn of(yi: Vector3<T>, y: &[Vector3<T>], stencil: &Stencil<'_, T>) -> Self {
        let (neighbors, bonds, frame) = (stencil.neighbors, stencil.bonds, stencil.frame);
        let (mut a1, mut a2) = (Vector3::zeros(), Vector3::zeros());
        for (&j, b) in neighbors.iter().zip(bonds) {
            let e = y[j as usize] - yi;
            a1 += e * b.beta[0];
            a2 += e * b.beta[1];
        }
        let (p, r, s) = (a1.dot(&a1), a1.dot(&a2), a2.dot(&a2));
        let [cos, sin] = leading_eigenvector(p, r, s);
        let v = [[cos, sin], [-sin, cos]];
        let t_v1 = a1 * cos + a2 * sin;
        let sigma1 = t_v1.norm();
        let cross = a1.cross(&a2);
        let area_ratio = cross.norm();
        let tiny = T::min_stretch() * T::min_stretch();
        let u1 = if sigma1 > tiny {
            t_v1 / sigma1
        } else {
            frame.t1
        };
        let normal = if area_ratio > tiny * (p + s) && area_ratio > T::zero() {
            cross / area_ratio
        } else {
            let n = u1.cross(&frame.nc);
            if n.norm() > T::of(1e-3) {
                n.normalize().cross(&u1)
            } else {
                any_orthogonal_unit(&u1)
            }
        };
        let u2 = normal.cross(&u1);
        let sigma2 = if sigma1 > tiny {
            area_ratio / sigma1
        } else {
            T::zero()
        };
        let lo = T::min_stretch();
        Self {
            a1,
            a2,
            area_ratio,
            normal,
            u: [u1, u2],
            v,
            sigma: [sigma1.max(lo), sigma2.max(lo)],
        }
    }
}

/// Unit eigenvector `(cos, sin)` of the larger eigenvalue of the symmetric 2x2 matrix
/// `[[p, r], [r, s]]`, from whichever of its two closed forms does not cancel.
#[inline]
fn leading_eigenvector<T: Real>(p: T, r: T, s: T) -> [T; 2] {
    let half_gap = (p - s) * T::of(0.5);
    let root = (half_gap * half_gap + r * r).sqrt();
    let (x, y) = if half_gap >= T::zero() {
        (half_gap + root, r) // (lambda_1 - s, r)
    } else {
        (r, root - half_gap) // (r, lambda_1 - p)
    };
    let norm = (x * x + y * y).sqrt();
    if norm > T::zero() {
        [x / norm, y / norm]
    } else {
        [T::one(), T::zero()]
    }
}

/// Computes vertex `i`'s energy and writes `dE_i / d(y_j - y_i)` into `bond_grad`, one entry per
/// neighbour of the stencil, in its order.
#[inline]
pub fn vertex_kernel<T: Real>(
    yi: Vector3<T>,
    y: &[Vector3<T>],
    stencil: &Stencil<'_, T>,
    mode: Preconditioner,
    bond_grad: &mut [Vector3<T>],
) -> VertexResponse<T> {
    let (neighbors, bonds, c) = (stencil.neighbors, stencil.bonds, stencil.constants);
    let def = Deformation::of(yi, y, stencil);
    let stretches = def.stretches();
    let [u1, u2] = def.u;
    let n = def.normal;
    let [v1, v2] = def.v;

    // Stretching: dPsi/dT = sum_m P_m u_m v_m^T.
    let stress = c.material.stress(stretches);
    let (p1, p2) = (stress[0] * c.volume, stress[1] * c.volume);
    let mut g1 = u1 * (p1 * v1[0]) + u2 * (p2 * v2[0]);
    let mut g2 = u1 * (p1 * v1[1]) + u2 * (p2 * v2[1]);
    let stretch_energy = c.volume * c.material.energy(stretches);

    let mut w = stretch_stiffness(mode, &c.material, stretches, stress, c);

    let (mut bending, mut hourglass) = (T::zero(), T::zero());
    let non_affine = c.kappa_t > T::zero() || c.kappa_n > T::zero();
    if non_affine {
        // F^-1 in rest-frame coordinates: rows g1, g2, n map a deformed vector e to the
        // (t1, t2, nc) coordinates of F^-1 e.
        let inv = [T::one() / def.sigma[0], T::one() / def.sigma[1]];
        let row1 = u1 * (v1[0] * inv[0]) + u2 * (v2[0] * inv[1]);
        let row2 = u1 * (v1[1] * inv[0]) + u2 * (v2[1] * inv[1]);
        // First pass: the rest images F^-1 e_j (kept in bond_grad for the second pass) and the
        // fitted curvature h = sum_j curvature_j (q_j . nc).
        let mut curvature = Vector3::zeros();
        for ((&j, b), out) in neighbors.iter().zip(bonds).zip(bond_grad.iter_mut()) {
            let e = y[j as usize] - yi;
            let image = Vector3::new(row1.dot(&e), row2.dot(&e), n.dot(&e));
            curvature += b.curvature * (image.z - b.xi.z);
            *out = image;
        }
        bending = T::of(0.5) * curvature.norm_squared();
        let (mut h1, mut h2, mut hn) = (Vector3::zeros(), Vector3::zeros(), Vector3::zeros());
        for (b, out) in bonds.iter().zip(bond_grad.iter_mut()) {
            let image = *out;
            let (q1, q2) = (image.x - b.xi.x, image.y - b.xi.y);
            hourglass += c.kappa_t * (q1 * q1 + q2 * q2);
            // d = F^-T W q with W q = (kappa_t q1, kappa_t q2, curvature_j . h) in the rest frame.
            let d =
                row1 * (c.kappa_t * q1) + row2 * (c.kappa_t * q2) + n * b.curvature.dot(&curvature);
            *out = d;
            h1 += d * image.x;
            h2 += d * image.y;
            hn += d * image.z;
        }
        hourglass *= T::of(0.5);
        g1 -= h1;
        g2 -= h2;
        let p = (-hn + n * n.dot(&hn)) / def.area_ratio.max(T::min_stretch() * T::min_stretch());
        g1 += def.a2.cross(&p);
        g2 += p.cross(&def.a1);
        w[0] += c.kappa_t * inv[0] * inv[0];
        w[1] += c.kappa_t * inv[1] * inv[1];
        w[2] += c.kappa_n;
        for (b, out) in bonds.iter().zip(bond_grad.iter_mut()) {
            *out += g1 * b.beta[0] + g2 * b.beta[1];
        }
    } else {
        for (b, out) in bonds.iter().zip(bond_grad.iter_mut()) {
            *out = g1 * b.beta[0] + g2 * b.beta[1];
        }
    }
    let precond =
        u1 * u1.transpose() * w[0] + u2 * u2.transpose() * w[1] + n * n.transpose() * w[2];
    VertexResponse {
        stretch: stretch_energy,
        bending,
        hourglass,
        precond,
    }
}

/// How the stretching stiffness enters the SISSM preconditioner `C_i`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Preconditioner {
    /// Curvature bounds: in-plane `max(d2Psi/dl_m^2 + |d2Psi/dl1 dl2|, (P1 -+ P2)/(l1 -+ l2))`,
    /// normal the tension stiffness `max(0, P_m / l_m)`, scaled by `V_i k_bound`. The quadratic
    /// model then bounds the energy's Hessian, so the Jacobi sweep cannot overshoot however
    /// stiff the material or long the step.
    #[default]
    Tangent,
    /// The paper's split (eq. 24-26): `U diag(P+ / lambda) U^T` scaled by `V_i k_iso`. Cheaper
    /// per iteration but the explicit part is stiffer than the implicit one, so stiff materials
    /// at large time steps can diverge.
    Paper,
}

/// Per-direction stiffness `(w_u1, w_u2, w_n)` (N/m) of the stretching part of `C_i`.
#[inline]
fn stretch_stiffness<T: Real>(
    mode: Preconditioner,
    material: &crate::material::MaterialModel<T>,
    stretches: [T; 3],
    stress: [T; 3],
    c: &VertexConstants<T>,
) -> [T; 3] {
    match mode {
        Preconditioner::Paper => {
            let scale = c.volume * c.k_iso;
            material.implicit_stiffness(stretches).map(|s| s * scale)
        }
        Preconditioner::Tangent => {
            let [l1, l2, _] = stretches;
            let [h11, h22, h12] = material.in_plane_hessian(stretches);
            let pair_plus = (stress[0] + stress[1]) / (l1 + l2);
            let gap = l1 - l2;
            let pair_minus = if gap > T::of(1e-6) * l1 {
                (stress[0] - stress[1]) / gap
            } else {
                T::zero()
            };
            let shear = pair_plus.max(pair_minus);
            let tension = (stress[0] / l1).max(stress[1] / l2).max(T::zero());
            let scale = c.volume * c.k_bound;
            [
                (h11 + h12.abs()).max(shear) * scale,
                (h22 + h12.abs()).max(shear) * scale,
                tension * scale,
            ]
        }
    }
}

/// A unit vector orthogonal to the unit vector `n`, chosen deterministically.
pub fn any_orthogonal_unit<T: Real>(n: &Vector3<T>) -> Vector3<T> {
    let (x, y, z) = (n.x.abs(), n.y.abs(), n.z.abs());
    let axis = if x <= y && x <= z {
        Vector3::x()
    } else if y <= z {
        Vector3::y()
    } else {
        Vector3::z()
    };
    n.cross(&axis).normalize()
}
