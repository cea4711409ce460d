//! The affine coarse space of the particle bodies (issue 38): each body `b` moves by the
//! field `u_i = t_b + A_b (x_i - c_b)` (m), `t_b` a translation, `A_b` a 3 x 3 matrix
//! (12 unknowns per body), `x_i` the step's start positions and `c_b` their mass centre. This
//! file assembles, once per step, the Galerkin operator of the global system
//! `(M + h^2 L) delta = r` of eq. 12 (He et al. 2017) on that space; the coarse step that
//! uses it is [`super::coarse`].
//!
//! **The operator.** `L` acts on each coordinate alike (`(L e)_i = sum_(b in row i) c_b
//! (e_i - e_j)`, `c_b` the bond's [`ParticleRest::coupling`], N/m), so the operator splits
//! into one 4 x 4 block per coordinate `k` on `(t_k, a_k)` (`a_k` the row `k` of `A`), the
//! same for the three. With the lever `l_i = x_i - c_b` (m) and `sum_i m_i l_i = 0`:
//!
//! - `t . t`: `sum_i m_i = M_b` (kg); `L` has no stiffness against a translation, so
//!   `t . a` is `sum_i m_i l_i = 0` and `L` adds nothing there;
//! - `a . a`: `K_b = J_b + h^2 S_b` (kg m^2), `J_b = sum_i m_i l_i l_i^T` and
//!   `S_b = sum_i l_i q_i^T` (N m) with `q_i = sum_(b in row i) c_b (x_i - x_j)` (N; `(L P)`
//!   on the row), which is `sum` over the bonds' pairs of `c_b d d^T`, `d = x_i - x_j`:
//!   symmetric, since `L` is.
//!
//! `P^T (M + h^2 L) P = blockdiag(M_b, K_b)` per coordinate, and the coarse right-hand side
//! `P^T (r - (M + h^2 L) delta)` is `F_b = sum_i (r_i - m_i delta_i)` for `t` and
//! `R_b = sum_i (r_i - m_i delta_i) l_i^T - h^2 sum_i delta_i q_i^T` (kg m^2) for `A`
//! (row `k` for `a_k`): one pass over the particles per iteration, the bonds' pass being
//! `q`'s, once per step. The unconstrained coarse move is `t = F / M`, `A = R K^-1`.
//!
//! **Exact while the bonds are.** `L` is constant within a step (the bonds change only at a
//! plastic body's end of the step, [`super::plastic`], after which the next step assembles
//! anew), so the operator is exact for elastic and plastic bodies. Granular bodies and bodies
//! with fluid particles are held by the repulsion and the density constraints, which `L` does
//! not hold: they take the translation only (`K^+ = 0`). Where a body's particles lie in a
//! plane or on a line `J` and `S` are singular along its normal: no particle moves along those
//! rows of `A`, so the pseudo-inverse `K^+` (eigenvalues below [`SINGULAR`] of the largest
//! left out) is the exact Galerkin solve on the space the body spans.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::particles::ParticleRest;
use crate::real::Real;
use crate::solve::points::Points;

/// The eigenvalues of `K_b` below this fraction of its largest are left out of its
/// pseudo-inverse (a flat or linear body, whose levers span less than three directions).
pub const SINGULAR: f64 = 1e-9;

/// The affine coarse space of a step (module doc), in f64.
#[derive(Debug, Default)]
pub(crate) struct AffineSpace {
    /// Per body: the mass centre `c_b` of the step's start positions (m), `K_b` (kg m^2), its
    /// pseudo-inverse (1/(kg m^2); zero for a body that takes the translation only) and the
    /// largest lever `max_i |l_i|` (m).
    pub centre: Vec<Vector3<f64>>,
    pub stiffness: Vec<Matrix3<f64>>,
    pub compliance: Vec<Matrix3<f64>>,
    pub radius: Vec<f64>,
    /// Per particle: the lever `l_i = x_i - c_b` (m) and `q_i` (N).
    pub lever: Vec<Vector3<f64>>,
    pub pull: Vec<Vector3<f64>>,
}

impl AffineSpace {
    /// Assembles the space at the step's start positions `points.y_start` for the global
    /// matrix of `rest` at the squared step `h2` (s^2); `affine[b]` says whether body `b`
    /// takes the affine field (else its translation only). Sums run in f64 in particle order
    /// (the same for any thread count).
    pub fn assemble<T: Real>(
        &mut self,
        points: &Points<T>,
        rest: &ParticleRest<T>,
        affine: &[bool],
        h2: f64,
    ) {
        let n = points.y_start.len();
        let bodies = points.ranges.len();
        self.centre.resize(bodies, Vector3::zeros());
        self.stiffness.resize(bodies, Matrix3::zeros());
        self.compliance.resize(bodies, Matrix3::zeros());
        self.radius.resize(bodies, 0.0);
        self.lever.resize(n, Vector3::zeros());
        self.pull.resize(n, Vector3::zeros());
        let x = |i: usize| points.y_start[i].map(|c| c.to_f64());
        for (b, range) in points.ranges.iter().enumerate() {
            let (mut total, mut moment) = (0.0, Vector3::zeros());
            for i in range.clone() {
                let m = points.mass[i].to_f64();
                total += m;
                moment += x(i) * m;
            }
            let centre = if total > 0.0 {
                moment / total
            } else {
                Vector3::zeros()
            };
            self.centre[b] = centre;
            self.lever[range.clone()]
                .par_iter_mut()
                .zip(range.clone())
                .for_each(|(l, i)| *l = x(i) - centre);
        }
        self.pull.par_iter_mut().enumerate().for_each(|(i, q)| {
            *q = Vector3::zeros();
            for b in rest.row(i) {
                let j = rest.indices[b] as usize;
                *q += (x(i) - x(j)) * rest.coupling[b].to_f64();
            }
        });
        for (b, range) in points.ranges.iter().enumerate() {
            let (mut inertia, mut spring) = (Matrix3::zeros(), Matrix3::zeros());
            let mut radius: f64 = 0.0;
            for i in range.clone() {
                let l = self.lever[i];
                inertia += l * l.transpose() * points.mass[i].to_f64();
                spring += l * self.pull[i].transpose();
                radius = radius.max(l.norm());
            }
            let stiffness = inertia + (spring + spring.transpose()) * (0.5 * h2);
            self.stiffness[b] = stiffness;
            self.radius[b] = radius;
            self.compliance[b] = if affine[b] {
                pseudo_inverse(&stiffness)
            } else {
                Matrix3::zeros()
            };
        }
    }
}

/// The pseudo-inverse of a symmetric positive semi-definite `k`: its eigenvalues below
/// [`SINGULAR`] of the largest taken as zero.
fn pseudo_inverse(k: &Matrix3<f64>) -> Matrix3<f64> {
    let eigen = k.symmetric_eigen();
    let largest = eigen.eigenvalues.max();
    if largest <= 0.0 {
        return Matrix3::zeros();
    }
    let inverted = eigen
        .eigenvalues
        .map(|e| if e > SINGULAR * largest { 1.0 / e } else { 0.0 });
    let v = &eigen.eigenvectors;
    v * Matrix3::from_diagonal(&inverted) * v.transpose()
}

#[cfg(test)]
#[path = "coarse_space_tests.rs"]
mod tests;
