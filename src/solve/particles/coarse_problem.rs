//! The coarse problem of the particle bodies' affine fields (issue 38): each body `b` of mass
//! `M_b` (kg) and affine stiffness `K_b` (kg m^2, [`super::coarse_space`]) with net residual
//! `F_b` (kg m) and moment `R_b` (kg m^2) moves by the field `u_i = t_b + A_b l_i` (m, `l_i`
//! the lever of particle `i`) that solves
//!
//! `min  sum_b [1/2 M_b |t_b|^2 + 1/2 tr(A_b K_b A_b^T) - F_b . t_b - tr(R_b A_b^T)]`
//! subject to `n_c . (u_a(l_a) - u_b(l_b)) >= bound_c` (or `=`) for every contact `c`,
//!
//! with `u_b = 0` for a collider or a fixed body (inverse mass 0) and `A_b = 0` for a body
//! that takes the translation only (`K_b^+ = 0`). Where the contacts come from and why the
//! problem is the Galerkin projection of the Jacobi step's system is in [`super::coarse`];
//! this file holds the problem's buffers and its solver.
//!
//! It is solved through its dual by projected Gauss-Seidel on the contacts' multipliers
//! `lambda_c >= 0` (N s^2; an equality's unbounded), from the unconstrained `t0 = F / M`,
//! `A0 = R K^+`, in a fixed order (the same for any thread count): a contact's row is
//! `n^T [I, l^T (x) I]` on `(t, A)`, its effective inverse mass `1 / M + l^T K^+ l` per side,
//! and a change of its multiplier moves `t` by `n / M` and `A` by `n (K^+ l)^T` per unit.
//! It stops when no sweep moves a contact by more than [`TOLERANCE`] of the largest
//! unconstrained move `max_b (|t0_b| + |A0_b| r_b)` (`r_b` the largest lever) or after
//! [`MAX_SWEEPS`] sweeps.

use nalgebra::{Matrix3, Vector3};

/// The projected Gauss-Seidel stops when no contact moves by more than this fraction of the
/// largest unconstrained move (module doc).
pub const TOLERANCE: f64 = 1e-10;
/// Most projected Gauss-Seidel sweeps over the contacts in one coarse solve.
pub const MAX_SWEEPS: usize = 200;

/// One linearised contact: `n . (u_a(lever_a) - u_b(lever_b)) >= bound` (m; or `=` for an
/// equality), `b` `None` for a collider or a fixed body, the levers (m) those of the two
/// particles in their bodies (zero for a translation alone).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Contact {
    pub a: usize,
    pub b: Option<usize>,
    pub n: Vector3<f64>,
    pub bound: f64,
    pub equality: bool,
    pub lever_a: Vector3<f64>,
    pub lever_b: Vector3<f64>,
    lambda: f64,
    /// `K^+ l` of each side (m/(kg m^2)) and the effective inverse mass (1/kg), set when the
    /// solve starts.
    arm_a: Vector3<f64>,
    arm_b: Vector3<f64>,
    inverse_mass: f64,
}

impl Contact {
    pub fn new(a: usize, b: Option<usize>, n: Vector3<f64>, bound: f64, equality: bool) -> Self {
        Self {
            a,
            b,
            n,
            bound,
            equality,
            lever_a: Vector3::zeros(),
            lever_b: Vector3::zeros(),
            lambda: 0.0,
            arm_a: Vector3::zeros(),
            arm_b: Vector3::zeros(),
            inverse_mass: 0.0,
        }
    }

    /// The contact at the particles of levers `a` and `b` (m) in their bodies.
    pub fn at(mut self, a: Vector3<f64>, b: Vector3<f64>) -> Self {
        self.lever_a = a;
        self.lever_b = b;
        self
    }
}

/// The coarse problem's data, kept between iterations so that the loop allocates nothing once
/// the buffers have grown to the scene's contacts.
#[derive(Debug, Default)]
pub(crate) struct Coarse {
    /// Per body: whether it takes part while in contact (not granular, no fluid particle).
    pub solid: Vec<bool>,
    /// Per body: the inverse mass (1/kg; 0 for a fixed body), the net residual `F_b` (kg m)
    /// and the translation (m).
    pub inverse_mass: Vec<f64>,
    pub force: Vec<Vector3<f64>>,
    pub translation: Vec<Vector3<f64>>,
    /// Per body: `K_b^+` (1/(kg m^2); 0 for a fixed body or one that takes the translation
    /// only), the moment `R_b` (kg m^2), the affine matrix `A_b` (1) and the largest lever (m).
    pub compliance: Vec<Matrix3<f64>>,
    pub moment: Vec<Matrix3<f64>>,
    pub affine: Vec<Matrix3<f64>>,
    pub radius: Vec<f64>,
    pub contacts: Vec<Contact>,
    /// Per particle: its smallest gap to a collider less its margin (m; infinite with none or
    /// in a fixed body), the parallel first pass of the contacts' gathering.
    pub collider_gap: Vec<f64>,
}

impl Coarse {
    /// The coarse problem of bodies of which `solid` says which take part while in contact.
    pub fn new(solid: Vec<bool>) -> Self {
        let n = solid.len();
        Self {
            solid,
            inverse_mass: vec![0.0; n],
            force: vec![Vector3::zeros(); n],
            translation: vec![Vector3::zeros(); n],
            compliance: vec![Matrix3::zeros(); n],
            moment: vec![Matrix3::zeros(); n],
            affine: vec![Matrix3::zeros(); n],
            radius: vec![0.0; n],
            contacts: Vec::new(),
            collider_gap: Vec::new(),
        }
    }

    /// Projected Gauss-Seidel on the contacts' multipliers from `t = t0`, `A = A0` (module
    /// doc), which `translation` and `affine` hold on entry.
    pub fn solve(&mut self) {
        let Self {
            inverse_mass: w,
            translation: t,
            compliance,
            affine,
            radius,
            contacts,
            ..
        } = self;
        if contacts.is_empty() {
            return;
        }
        let scale = (0..t.len())
            .map(|b| t[b].norm() + affine[b].norm() * radius[b])
            .fold(0.0, f64::max);
        for c in contacts.iter_mut() {
            c.arm_a = compliance[c.a] * c.lever_a;
            c.arm_b = c.b.map_or(Vector3::zeros(), |b| compliance[b] * c.lever_b);
            let w_b = c.b.map_or(0.0, |b| w[b]);
            c.inverse_mass = w[c.a] + c.lever_a.dot(&c.arm_a) + w_b + c.lever_b.dot(&c.arm_b);
        }
        let moved = |t: &Vector3<f64>, a: &Matrix3<f64>, l: &Vector3<f64>| t + a * l;
        for _ in 0..MAX_SWEEPS {
            let mut largest: f64 = 0.0;
            for c in contacts.iter_mut() {
                let mut relative = moved(&t[c.a], &affine[c.a], &c.lever_a);
                if let Some(b) = c.b {
                    relative -= moved(&t[b], &affine[b], &c.lever_b);
                }
                let k = c.inverse_mass;
                let mut lambda = c.lambda + (c.bound - c.n.dot(&relative)) / k;
                if !c.equality {
                    lambda = lambda.max(0.0);
                }
                let change = lambda - c.lambda;
                c.lambda = lambda;
                t[c.a] += c.n * (w[c.a] * change);
                affine[c.a] += c.n * (c.arm_a * change).transpose();
                if let Some(b) = c.b {
                    t[b] -= c.n * (w[b] * change);
                    affine[b] -= c.n * (c.arm_b * change).transpose();
                }
                largest = largest.max(change.abs() * k);
            }
            if largest <= TOLERANCE * scale {
                break;
            }
        }
    }
}

#[cfg(test)]
#[path = "coarse_problem_tests.rs"]
mod tests;
