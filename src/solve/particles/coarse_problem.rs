//! The coarse problem of the particle bodies' translations (issue 38): each body `b` of mass
//! `M_b` (kg) with net residual `F_b` (kg m) moves by the translation `t_b` (m) that solves
//!
//! `min_t  1/2 sum_b M_b |t_b|^2 - sum_b F_b . t_b`
//! subject to `n_c . (t_a - t_b) >= bound_c` for every contact `c`,
//!
//! with `t_b = 0` for a collider or a fixed body (inverse mass 0), and Coulomb friction at the
//! contacts with frictional colliders: the tangential reaction `phi_f` (N s^2, in the contact's
//! tangent plane) stays within the cone `|phi_f| <= mu_f lambda_c` of its normal contact `c`,
//! and holds the particle's slip over the step `s_f + t_a` (tangential, m) at zero where it
//! can (sticking); otherwise it is on the cone's edge against the slip (sliding, maximal
//! dissipation). Where the contacts come from and why the problem is the Galerkin projection
//! of the Jacobi step's system is in [`super::coarse`]; this file holds the problem's buffers
//! and its solver.
//!
//! It is solved through its dual by projected Gauss-Seidel on the contacts' multipliers
//! `lambda_c >= 0` (N s^2), each friction's `phi_f` projected onto its disk after each sweep
//! over the normal contacts, from the multipliers the contacts start with (the projection's
//! reactions, [`super::coarse`], "Fixed point") and the translation they give, in a fixed
//! order (the same for any thread count), until no sweep moves a translation by more than
//! [`TOLERANCE`] of `max |t0|` or [`MAX_SWEEPS`] sweeps.

use nalgebra::Vector3;

/// The projected Gauss-Seidel stops when no contact moves a translation by more than this
/// fraction of the largest unconstrained translation `max |t0_b|`.
pub const TOLERANCE: f64 = 1e-10;
/// Most projected Gauss-Seidel sweeps over the contacts in one coarse solve.
pub const MAX_SWEEPS: usize = 200;

/// One linearised contact: `n . (t_a - t_b) >= bound` (m), `b`
/// `None` for a collider or a fixed body, and its multiplier `lambda` (N s^2), which the solve
/// starts from ([`Contact::starting_from`]; 0 by default).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Contact {
    pub a: usize,
    pub b: Option<usize>,
    pub n: Vector3<f64>,
    pub bound: f64,
    lambda: f64,
}

impl Contact {
    pub fn new(a: usize, b: Option<usize>, n: Vector3<f64>, bound: f64) -> Self {
        Self {
            a,
            b,
            n,
            bound,
            lambda: 0.0,
        }
    }

    /// The contact with its multiplier to start from, `lambda >= 0` (N s^2): the reaction the
    /// projection gave it, with which the solve starts at the solution at the fixed point
    /// ([`super::coarse`], "Fixed point").
    pub fn starting_from(mut self, lambda: f64) -> Self {
        self.lambda = lambda;
        self
    }
}

/// Coulomb friction at a collider contact of body `a` (module doc): the tangential reaction
/// `phi = phi_0 u_0 + phi_1 u_1` (N s^2) on the orthonormal tangents `u` of the contact
/// `contacts[normal]`, within `|phi| <= coefficient * lambda_normal`, against the particle's
/// slip over the step `slip_k = u_k . s` (m, relative to the collider's material point,
/// before the body's translation).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Friction {
    pub a: usize,
    pub normal: usize,
    pub tangents: [Vector3<f64>; 2],
    pub slip: [f64; 2],
    pub coefficient: f64,
    phi: [f64; 2],
}

impl Friction {
    /// The friction of body `a` at the contact `contacts[normal]` (coefficient `coefficient`,
    /// dimensionless) with the particle's tangential slip `slip` (m, orthogonal to the
    /// contact's normal `n`), starting from the tangential reaction `reaction` (N s^2; the
    /// projection's, [`super::coarse`], "Fixed point").
    pub fn new(
        a: usize,
        normal: usize,
        n: &Vector3<f64>,
        slip: &Vector3<f64>,
        coefficient: f64,
        reaction: &Vector3<f64>,
    ) -> Self {
        let u = n
            .cross(&Vector3::x())
            .try_normalize(0.5)
            .unwrap_or_else(|| n.cross(&Vector3::y()).normalize());
        let tangents = [u, n.cross(&u)];
        Self {
            a,
            normal,
            tangents,
            slip: tangents.map(|u| u.dot(slip)),
            coefficient,
            phi: tangents.map(|u| u.dot(reaction)),
        }
    }

    /// Unbounded friction at the contact `contacts[normal]` of body `a` with normal `n` that
    /// holds the particle's slip at its settled position (`coefficient` infinite): the body's
    /// tangential translation is held at zero.
    pub fn sticking(a: usize, normal: usize, n: &Vector3<f64>) -> Self {
        let zero = Vector3::zeros();
        Self::new(a, normal, n, &zero, f64::INFINITY, &zero)
    }

    /// The radius of the Coulomb disk (N s^2) at the normal multiplier `lambda` (N s^2).
    fn bound(&self, lambda: f64) -> f64 {
        if self.coefficient.is_finite() {
            self.coefficient * lambda
        } else {
            f64::INFINITY
        }
    }

    /// The tangential reaction (N s^2).
    pub fn reaction(&self) -> Vector3<f64> {
        self.tangents[0] * self.phi[0] + self.tangents[1] * self.phi[1]
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
    pub contacts: Vec<Contact>,
    pub frictions: Vec<Friction>,
    /// Per particle: its smallest gap to a collider less its margin (m; infinite with none or
    /// in a fixed body), the parallel first pass of the contacts' gathering.
    pub collider_gap: Vec<f64>,
    /// Per particle: its settled move (m; [`super::coarse`], "Fixed point") and the move it
    /// was settled from (m; the sweep's with the repulsion's answer), from which the
    /// gathering recomputes each collider's friction reaction.
    pub settled: Vec<Vector3<f64>>,
    pub swept: Vec<Vector3<f64>>,
    /// The projection's normal and friction reactions (N s^2) at each collider of the
    /// particle being gathered.
    pub collider_reaction: Vec<(f64, Vector3<f64>)>,
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
            contacts: Vec::new(),
            frictions: Vec::new(),
            collider_gap: Vec::new(),
            settled: Vec::new(),
            swept: Vec::new(),
            collider_reaction: Vec::new(),
        }
    }

    /// Projected Gauss-Seidel on the contacts' multipliers from their starting multipliers and
    /// `t = t0 + W G^T lambda` (module doc), `t0` held by `translation` on entry.
    pub fn solve(&mut self) {
        let Self {
            inverse_mass: w,
            translation: t,
            contacts,
            frictions,
            ..
        } = self;
        if contacts.is_empty() {
            return;
        }
        let scale = t.iter().map(|t| t.norm()).fold(0.0, f64::max);
        for c in contacts.iter() {
            t[c.a] += c.n * (w[c.a] * c.lambda);
            if let Some(b) = c.b {
                t[b] -= c.n * (w[b] * c.lambda);
            }
        }
        for f in frictions.iter() {
            t[f.a] += f.reaction() * w[f.a];
        }
        for _ in 0..MAX_SWEEPS {
            let mut largest: f64 = 0.0;
            for c in contacts.iter_mut() {
                let w_b = c.b.map_or(0.0, |b| w[b]);
                let relative = t[c.a] - c.b.map_or(Vector3::zeros(), |b| t[b]);
                let k = w[c.a] + w_b;
                let lambda = (c.lambda + (c.bound - c.n.dot(&relative)) / k).max(0.0);
                let change = lambda - c.lambda;
                c.lambda = lambda;
                t[c.a] += c.n * (w[c.a] * change);
                if let Some(b) = c.b {
                    t[b] -= c.n * (w_b * change);
                }
                largest = largest.max(change.abs() * k);
            }
            for f in frictions.iter_mut() {
                let w_a = w[f.a];
                let before = f.reaction();
                // The reaction that stops the slip, projected onto the Coulomb disk.
                let mut phi =
                    [0, 1].map(|k| f.phi[k] - (f.slip[k] + f.tangents[k].dot(&t[f.a])) / w_a);
                let bound = f.bound(contacts[f.normal].lambda);
                let size = phi[0].hypot(phi[1]);
                if size > bound {
                    phi = phi.map(|p| p * bound / size);
                }
                f.phi = phi;
                let change = f.reaction() - before;
                t[f.a] += change * w_a;
                largest = largest.max(change.norm() * w_a);
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
