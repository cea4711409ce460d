//! The Newton method's model of the elastic energy's Hessian: one positive semi-definite
//! quadratic form per vertex energy `E_i`, in the vertex's bond vectors `e_j = y_j - y_i`
//! (Lu et al. 2023, eq. 13-15 and the energy of [`crate::membrane::vertex_kernel`]), and its
//! matrix-free product with a displacement field.
//!
//! ## Stretching: the exact Hessian, projected
//!
//! `E_stretch = V_i Psi(sigma_1, sigma_2, 1)` depends on the bonds through
//! `T = [a1 a2] = sum_j e_j beta_j^T` (3 x 2, linear in `e`), so
//! `d^2 E / de_j de_l = beta_j^T S beta_l` with `S = d^2 E / dT^2` (6 x 6, J). With
//! `T = sigma_1 u1 v1^T + sigma_2 u2 v2^T` and unit normal `n`, `S` is diagonal in six
//! modes of `T` (the analytic eigensystem of an isotropic energy of a 3 x 2 map):
//!
//! - scaling, `u1 v1^T` and `u2 v2^T`: the 2 x 2 block `V_i [[h11, h12], [h12, h22]]`,
//!   `h = d^2 Psi / dsigma^2` ([`crate::material::MaterialModel::in_plane_hessian`], Pa);
//! - in-plane shear pair `(u1 v2^T +- u2 v1^T) / sqrt 2`: `V_i (P1 -+ P2) / (sigma_1 -+ sigma_2)`
//!   (`P = dPsi/dsigma`, eq. 35; the minus pair's limit at `sigma_1 = sigma_2` is `h11 - h12`);
//! - out of plane, `n v1^T` and `n v2^T`: `V_i P_m / sigma_m` (the tension stiffness).
//!
//! Every negative eigenvalue (compression, the non-convex part) is set to zero, so the model
//! is positive semi-definite; where all six are non-negative it is the exact Hessian. These
//! are the eigenvalues that the SISSM preconditioner bounds per direction
//! (`Preconditioner::Tangent` in `membrane/kernel.rs`); here they enter with their modes, so
//! the coupling between `a1` and `a2` is kept.
//!
//! ## Bending and hourglass: Gauss-Newton
//!
//! Both are `1/2 |W r|^2` of the non-affine residuals `q_j = F^-1 e_j - xi_j`: the hourglass
//! term weights their tangential components by `kappa_t` (N/m), the bending term is
//! `1/2 |sum_j c_j (q_j . nc)|^2`. Their Gauss-Newton matrix `J^T W J` is positive
//! semi-definite and equals the exact Hessian where the residuals vanish (any affine
//! deformation of a flat rest stencil). The Jacobian is taken at `F^-1 e_j = xi_j`:
//! `dq_j = F^-1 (de_j - da1 xi_j1 - da2 xi_j2)` (the director's variation enters through
//! `xi_j3`, which is zero for a flat rest stencil and dropped for a curved one).
//!
//! The model is only a metric for the Newton step: the line search evaluates the exact
//! energy, so an approximation slows the iteration but cannot make it increase the energy.

use nalgebra::{Matrix2, SMatrix, SVector, Vector3};

use crate::membrane::{Deformation, Stencil};
use crate::real::Real;

/// A 6-vector `(a1, a2)` stacked: a variation of the tangent map `T`.
type Vec6<T> = SVector<T, 6>;

/// One vertex's Hessian model at the current iterate.
#[derive(Debug, Clone, Copy)]
pub(crate) struct VertexModel<T: Real> {
    /// `S`, the projected `d^2 E_stretch / dT^2` in `(a1, a2)` coordinates (J).
    stretch: SMatrix<T, 6, 6>,
    /// The rows of `F^-1` (1/m... dimensionless per metre of bond: `F^-1 e` is in metres):
    /// `r1 = sum_m u_m v_m1 / sigma_m`, `r2 = sum_m u_m v_m2 / sigma_m`, and the director `n`.
    rows: [Vector3<T>; 3],
}

impl<T: Real> Default for VertexModel<T> {
    fn default() -> Self {
        Self {
            stretch: SMatrix::zeros(),
            rows: [Vector3::zeros(); 3],
        }
    }
}

/// The mode `u v^T` of `T`, stacked by columns.
#[inline]
fn mode<T: Real>(u: &Vector3<T>, v: [T; 2]) -> Vec6<T> {
    let (c1, c2) = (u * v[0], u * v[1]);
    Vec6::new(c1.x, c1.y, c1.z, c2.x, c2.y, c2.z)
}

impl<T: Real> VertexModel<T> {
    /// The model of vertex `i` from its deformed bond vectors `edges` (m, stencil order).
    pub fn of(stencil: &Stencil<'_, T>, edges: &[Vector3<T>]) -> Self {
        let def = Deformation::of(edges, stencil);
        let c = stencil.constants;
        let stretches = def.stretches();
        let [p1, p2, _] = c.material.stress(stretches);
        let [h11, h22, h12] = c.material.in_plane_hessian(stretches);
        let [s1, s2] = def.sigma;
        let [u1, u2] = def.u;
        let n = def.normal;
        let [v1, v2] = def.v;
        let mut stretch = SMatrix::<T, 6, 6>::zeros();
        let mut add = |w: Vec6<T>, lambda: T| {
            if lambda > T::zero() {
                stretch += w * w.transpose() * (lambda * c.volume);
            }
        };
        let (e11, e22) = (mode(&u1, v1), mode(&u2, v2));
        let scaling = Matrix2::new(h11, h12, h12, h22).symmetric_eigen();
        for k in 0..2 {
            let w = scaling.eigenvectors.column(k);
            add(e11 * w[0] + e22 * w[1], scaling.eigenvalues[k]);
        }
        let half = T::of(std::f64::consts::FRAC_1_SQRT_2);
        let (e12, e21) = (mode(&u1, v2), mode(&u2, v1));
        let minus = if s1 - s2 > T::of(1e-6) * s1 {
            (p1 - p2) / (s1 - s2)
        } else {
            h11 - h12
        };
        add((e12 + e21) * half, minus);
        add((e12 - e21) * half, (p1 + p2) / (s1 + s2));
        add(mode(&n, v1), p1 / s1);
        add(mode(&n, v2), p2 / s2);
        let row = |k: usize| u1 * (v1[k] / s1) + u2 * (v2[k] / s2);
        Self {
            stretch,
            rows: [row(0), row(1), n],
        }
    }

    /// The product of the model with bond displacements: on entry `bonds[j]` holds
    /// `dx_j = p_j - p_i` (m), on return `sum_l d^2 E_i / de_j de_l dx_l` (N).
    #[inline]
    pub fn apply(&self, stencil: &Stencil<'_, T>, bonds: &mut [Vector3<T>]) {
        let rest = stencil.bonds;
        let kappa_t = stencil.constants.kappa_t;
        let (mut d1, mut d2) = (Vector3::zeros(), Vector3::zeros());
        for (x, b) in bonds.iter().zip(rest) {
            d1 += x * b.beta[0];
            d2 += x * b.beta[1];
        }
        let sd = self.stretch * Vec6::new(d1.x, d1.y, d1.z, d2.x, d2.y, d2.z);
        let mut s1 = Vector3::new(sd[0], sd[1], sd[2]);
        let mut s2 = Vector3::new(sd[3], sd[4], sd[5]);
        let [r1, r2, n] = self.rows;
        // The non-affine parts delta_j = dx_j - da1 xi_j1 - da2 xi_j2, and the bending
        // residual's variation sum_j c_j (n . delta_j).
        let mut bend = Vector3::zeros();
        for (x, b) in bonds.iter_mut().zip(rest) {
            *x -= d1 * b.xi.x + d2 * b.xi.y;
            bend += b.curvature * n.dot(x);
        }
        // z_j = dQ/d delta_j; the affine fit passes -sum_j z_j xi_j back to (a1, a2).
        for (x, b) in bonds.iter_mut().zip(rest) {
            let z = (r1 * r1.dot(x) + r2 * r2.dot(x)) * kappa_t + n * b.curvature.dot(&bend);
            s1 -= z * b.xi.x;
            s2 -= z * b.xi.y;
            *x = z;
        }
        for (x, b) in bonds.iter_mut().zip(rest) {
            *x += s1 * b.beta[0] + s2 * b.beta[1];
        }
    }
}
