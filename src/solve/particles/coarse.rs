//! The coarse correction of the Jacobi global step: a two-level method whose coarse space is
//! the affine field of each particle body ([`super::coarse_space`]), with the contacts between
//! bodies and with the colliders as linearised one-sided constraints (beyond the 2017 paper,
//! issue 38).
//!
//! **Why.** One Jacobi sweep on `(M + h^2 L) delta = r` ([`super::directions::jacobi`]) moves
//! a body's translation by only `m_i / D_i` of what its residual asks (`L` holds no stiffness
//! against a translation: an error `e` of the whole body leaves `r_i = -m_i e`, and the sweep
//! moves `m_i e / D_i`). At `h = 1/30` s a 25K-particle cube of E 2e5 Pa has `D_i / m_i` about
//! 5e4: after an impact the body hovers above the floor for hundreds of iterations. A body in
//! free flight beside one in contact starts from the step's start positions (the family's
//! initial guess, [`crate::solve::sissm`], is chosen for all its bodies at once), a
//! translation error of `h v + h^2 g`. And bodies in contact keep such modes too: two blocks
//! stacked on a frictionless plane slide together along it, held by nothing but their masses
//! in the sweep (their error decays by `1 - m / D` per iteration). The smooth deformations
//! fare little better: a body compressing against the floor, or spinning, is a field that
//! varies over the whole body, which the sweep propagates by one bond per iteration. The
//! affine field holds the uniform ones (compression, shear, a linearised rotation). A rotation
//! enters as the antisymmetric part of `A` with the stiffness `L` gives it (the global matrix
//! is not rotation-invariant: the local step's projections carry the rotations), so it is the
//! linear system's own answer to the residual's torque, not a rigid rotation fitted to it
//! (which the non-central deviatoric forces of eq. 10 would spin).
//!
//! **What.** After the sweep every body `b` that takes part (below) moves by the field
//! `u_i = t_b + A_b l_i` (m, `l_i = x_i - c_b` the particle's lever from the mass centre of
//! the step's start positions), the solution of the Galerkin coarse problem of eq. 12's linear
//! system on the bodies' affine fields `P` (`delta += P (t, A)`), with the contacts as
//! constraints ([`super::coarse_problem`]):
//!
//! `min  sum_b [1/2 M_b |t_b|^2 + 1/2 tr(A_b K_b A_b^T) - F_b . t_b - tr(R_b A_b^T)]`
//! subject to `n_c . (u_a(l_i) - u_b(l_j)) >= -max(g_c, 0)` for every contact `c`,
//!
//! `P^T (M + h^2 L) P = blockdiag(M_b, K_b)` and `(F_b, R_b) = P^T (r - (M + h^2 L) delta)`,
//! the net residual and moment the sweep leaves ([`super::coarse_space`]). A contact `c` is a
//! particle `i` of body `a` at `p_i = y_i + delta_i` (where the sweep put it) and either a
//! collider (`g_c` its signed distance less the margin, `n_c` its normal; `u_b = 0`) or a
//! particle `j` of another body `b` among the repulsion's candidates (`g_c = |p_i - p_j| -
//! margin_i - margin_j`, `n_c = (p_i - p_j) / |p_i - p_j|`): the coarse move may close a gap,
//! but carries no particle deeper than the sweep put it. The constraints are the
//! linearisation of the distance, which underestimates it for a pair and for a convex
//! collider, so a feasible move keeps the contacts; the collider projection and the repulsion
//! that follow ([`super::step`]) correct the rest. A contact with a frictional collider that
//! the sweep put within the margin (`g_c <= 0`) holds the particle's tangential move too (two
//! equality constraints: the Coulomb cone is the fine iteration's), so the coarse step slides
//! no body a collider sticks. Only the contacts that the coarse move can reach enter: the
//! solution is the projection, in the operator's norm, of the unconstrained move onto a convex
//! set that holds 0, so its energy is at most the unconstrained move's ([`gather_contacts`]).
//!
//! The problem is solved by projected Gauss-Seidel on its dual ([`super::coarse_problem`]).
//! Its inexactness only slows the outer iteration: the fixed point is left alone, since at
//! the solution every body's net residual is balanced by its contacts (`F_b = sum_c lambda_c
//! n_c`, the KKT condition, holds with `t = 0`). So is the momentum: `sum_i m_i A l_i = 0`, and a
//! pair's multiplier moves its two bodies' translations by equal and opposite momenta.
//!
//! **Not with contacts.** A body that a gathered contact reaches takes the translation alone
//! (`A_b = 0`; [`translate_only_in_contact`]); a body no contact reaches takes the exact,
//! unconstrained affine move. With contacts the affine part broke the outer iteration (the
//! 15^3 benchmark cube resting on its floor: the residual grew to 8e-2 m instead of
//! converging). The likely cause (estimated, not measured): a contact's effective inverse
//! mass `1 / M_b + l^T K_b^+ l` is almost all translation, `l^T K_b^+ l` being of the order
//! of `(m_i / D_i) / M_b` (`K_b` holds the bonds' stiffness), so that the projected
//! Gauss-Seidel resolves the affine part of the multipliers by about `m_i / D_i` per sweep
//! and its truncated solve leaves an affine move that is no descent direction; nor is the
//! fixed point kept exactly, as the sweep's move at a contact
//! particle, which the contact takes back, enters `R_b` through `L` and no contact balances
//! it. The contacts' generalised rows are in place ([`Contact::at`]) for a solver that can.
//!
//! **Who takes part.** A body with a pinned particle, or with a particle that another family
//! holds (`coupled`, a membrane's reaction on it, [`crate::solve::coupling`]), is fixed (as a
//! collider is). So is a granular body or one with fluid particles that a collider or another
//! body touched in the step's last trial (`touched`): their grains and fluid particles are
//! held by the repulsion within and the density constraints, not as one body; they take the
//! coarse translation in free flight only, and never the affine part, which `L` does not
//! describe for them ([`super::coarse_space`]). `touched` starts empty at each step (at its
//! first iteration their contacts enter as constraints, as a solid body's), since no state
//! file holds the last step's; the affine space is assembled from the step's start positions
//! and bonds, so no state crosses the steps.
//!
//! The Chebyshev history `y_prev` moves with the body, so that the extrapolation acts on the
//! fine iteration's error and does not repeat the coarse move.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::collider::ColliderModel;
use crate::real::Real;
use crate::solve::points::Points;

use super::coarse_problem::{Coarse, Contact};
use super::system::ParticleSystem;

/// Adds every body's coarse move (module doc) to `sys.delta`, the fine sweep's move from the
/// residual `sys.current.residual` at the squared step `h2` (s^2), and to the Chebyshev
/// history. `coupled` holds another family's reaction per particle (a membrane's,
/// [`crate::solve::coupling`]).
pub(crate) fn correct<T: Real>(
    sys: &mut ParticleSystem<T>,
    colliders: &[ColliderModel<T>],
    coupled: &[Vector3<T>],
    h2: f64,
) {
    let mut coarse = std::mem::take(&mut sys.coarse);
    free_bodies(sys, &mut coarse, coupled);
    collider_gaps(sys, &mut coarse, colliders);
    let energy = net_residuals(sys, &mut coarse, h2);
    if energy > 0.0 {
        gather_contacts(sys, &mut coarse, colliders, energy);
        translate_only_in_contact(&mut coarse);
        coarse.solve();
        apply(sys, &coarse);
    }
    sys.coarse = coarse;
}

/// Each body's inverse mass and `K_b^+` ([`super::coarse_space`]): zero for a fixed body
/// (module doc), `K_b^+` also for a body that takes the translation only.
fn free_bodies<T: Real>(sys: &ParticleSystem<T>, coarse: &mut Coarse, coupled: &[Vector3<T>]) {
    let points = &sys.points;
    for (b, range) in points.ranges.iter().enumerate() {
        let fixed = range.clone().any(|i| {
            let coupled = coupled.get(i).is_some_and(|r| *r != Vector3::zeros());
            points.pinned[i] || coupled || (sys.touched[i] && !coarse.solid[b])
        });
        let total: f64 = if fixed {
            0.0
        } else {
            range.clone().map(|i| points.mass[i].to_f64()).sum()
        };
        let free = total > 0.0;
        coarse.inverse_mass[b] = if free { 1.0 / total } else { 0.0 };
        coarse.compliance[b] = if free {
            sys.affine.compliance[b]
        } else {
            Matrix3::zeros()
        };
        coarse.radius[b] = sys.affine.radius[b];
    }
}

/// Per particle of a free body, in parallel: its smallest gap to a collider less its margin
/// at `p_i = y_i + delta_i` (where the sweep put it; m, infinite with none), so that the
/// serial gathering ([`gather_contacts`]) evaluates the colliders only where one is within
/// reach.
fn collider_gaps<T: Real>(
    sys: &ParticleSystem<T>,
    coarse: &mut Coarse,
    colliders: &[ColliderModel<T>],
) {
    let points = &sys.points;
    let body_of = |j: usize| points.ranges.partition_point(|r| r.end <= j);
    let Coarse {
        inverse_mass,
        collider_gap,
        ..
    } = coarse;
    collider_gap.resize(points.y.len(), f64::INFINITY);
    collider_gap
        .par_iter_mut()
        .enumerate()
        .for_each(|(i, gap)| {
            *gap = f64::INFINITY;
            if inverse_mass[body_of(i)] == 0.0 {
                return;
            }
            let p = points.y[i] + sys.delta[i];
            for c in Points::colliders_of(&points.collides, i, colliders) {
                *gap = gap.min((c.signed_distance(&p) - points.margin[i]).to_f64());
            }
        });
}

/// Each body's net residual `F_b` and moment `R_b` ([`super::coarse_space`]) and the
/// unconstrained move `t0 = F / M`, `A0 = R K^+` as the start of the solve (zero for a fixed
/// body), summed in f64 in particle order (the same for any thread count), at the squared
/// step `h2` (s^2); returns the move's energy `sum_b (M_b |t0_b|^2 + tr(A0_b K_b A0_b^T))`
/// (kg m^2).
fn net_residuals<T: Real>(sys: &ParticleSystem<T>, coarse: &mut Coarse, h2: f64) -> f64 {
    let (points, space) = (&sys.points, &sys.affine);
    let (mass, r) = (&points.mass, &sys.current.residual);
    let mut energy = 0.0;
    for (b, range) in points.ranges.iter().enumerate() {
        let free = coarse.inverse_mass[b] > 0.0;
        let (mut force, mut moment) = (Vector3::<f64>::zeros(), Matrix3::<f64>::zeros());
        if free {
            for i in range.clone() {
                let unbalanced = (r[i] - sys.delta[i] * mass[i]).map(|c| c.to_f64());
                force += unbalanced;
                let d = sys.delta[i].map(|c| c.to_f64());
                moment +=
                    unbalanced * space.lever[i].transpose() - d * (space.pull[i] * h2).transpose();
            }
        }
        coarse.force[b] = force;
        coarse.moment[b] = moment;
        coarse.translation[b] = force * coarse.inverse_mass[b];
        coarse.affine[b] = moment * coarse.compliance[b];
        energy += force.dot(&coarse.translation[b]) + coarse.affine[b].component_mul(&moment).sum();
    }
    energy
}

/// The contacts (module doc) that a coarse move within the bound of `energy` (the unconstrained
/// move's, kg m^2) can reach, in particle order: particle `i` of body `b` moves by at most
/// `sqrt(energy (1 / M_b + l_i^T K_b^+ l_i))` (Cauchy-Schwarz in the operator's norm, per
/// coordinate). The serial gathering evaluates the colliders only where the smallest gap
/// ([`collider_gaps`]) is within reach (the same contacts for any thread count).
fn gather_contacts<T: Real>(
    sys: &ParticleSystem<T>,
    coarse: &mut Coarse,
    colliders: &[ColliderModel<T>],
    energy: f64,
) {
    let points = &sys.points;
    let body_of = |j: usize| points.ranges.partition_point(|r| r.end <= j);
    let at = |i: usize| points.y[i] + sys.delta[i];
    let lever = &sys.affine.lever;
    let Coarse {
        inverse_mass,
        compliance,
        contacts,
        collider_gap,
        ..
    } = coarse;
    let reach = |b: usize, i: usize| {
        let l = &lever[i];
        (energy * (inverse_mass[b] + l.dot(&(compliance[b] * l)))).sqrt()
    };
    contacts.clear();
    for (a, range) in points.ranges.iter().enumerate() {
        if inverse_mass[a] == 0.0 {
            continue;
        }
        for i in range.clone() {
            let s_a = reach(a, i);
            let p = at(i);
            let near = if collider_gap[i] < s_a {
                Points::colliders_of(&points.collides, i, colliders)
            } else {
                &[]
            };
            for c in near {
                let gap = (c.signed_distance(&p) - points.margin[i]).to_f64();
                if gap >= s_a {
                    continue;
                }
                let n = c.normal(&p).map(|x| x.to_f64());
                let on = |n, bound, equality| {
                    Contact::new(a, None, n, bound, equality).at(lever[i], Vector3::zeros())
                };
                contacts.push(on(n, -gap.max(0.0), false));
                if c.friction > T::zero() && gap <= 0.0 {
                    let u = n
                        .cross(&Vector3::x())
                        .try_normalize(0.5)
                        .unwrap_or_else(|| n.cross(&Vector3::y()).normalize());
                    contacts.push(on(u, 0.0, true));
                    contacts.push(on(n.cross(&u), 0.0, true));
                }
            }
            let Some(repulsion) = &sys.repulsion else {
                continue;
            };
            for &j in repulsion.partners(i) {
                let j = j as usize;
                let b = body_of(j);
                let b_free = inverse_mass[b] > 0.0;
                if b == a || (b_free && j < i) {
                    continue;
                }
                let offset = p - at(j);
                let distance = offset.norm().to_f64();
                let gap = distance - (points.margin[i] + points.margin[j]).to_f64();
                let s_b = if b_free { reach(b, j) } else { 0.0 };
                if gap >= s_a + s_b || distance == 0.0 {
                    continue;
                }
                let n = offset.map(|x| x.to_f64()) / distance;
                let b = b_free.then_some(b);
                let contact = Contact::new(a, b, n, -gap.max(0.0), false);
                contacts.push(contact.at(lever[i], lever[j]));
            }
        }
    }
}

/// Takes the affine part from every body that a gathered contact reaches: such a body moves
/// by its translation alone (module doc, "Not with contacts"); the others keep their
/// unconstrained affine move, which no contact reaches: the exact solution.
fn translate_only_in_contact(coarse: &mut Coarse) {
    let Coarse {
        compliance,
        affine,
        contacts,
        ..
    } = coarse;
    for c in contacts.iter() {
        for b in std::iter::once(c.a).chain(c.b) {
            compliance[b] = Matrix3::zeros();
            affine[b] = Matrix3::zeros();
        }
    }
}

/// Adds each body's coarse move `t_b + A_b l_i` to its particles' moves and Chebyshev
/// history.
fn apply<T: Real>(sys: &mut ParticleSystem<T>, coarse: &Coarse) {
    let (points, lever) = (&mut sys.points, &sys.affine.lever);
    let history = points.y_prev.len() == points.y.len();
    for (b, range) in points.ranges.iter().enumerate() {
        let (t, a) = (coarse.translation[b], coarse.affine[b]);
        if coarse.inverse_mass[b] == 0.0 || (t == Vector3::zeros() && a == Matrix3::zeros()) {
            continue;
        }
        let moved = |i: usize| (t + a * lever[i]).map(T::of);
        sys.delta[range.clone()]
            .par_iter_mut()
            .zip(range.clone())
            .for_each(|(d, i)| *d += moved(i));
        if history {
            points.y_prev[range.clone()]
                .par_iter_mut()
                .zip(range.clone())
                .for_each(|(p, i)| *p += moved(i));
        }
    }
}
