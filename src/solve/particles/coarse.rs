//! The coarse correction of the Jacobi global step: a two-level method whose coarse space is
//! the translation of each particle body, with the contacts between bodies and with the
//! colliders as linearised one-sided constraints (beyond the 2017 paper, issue 38).
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
//! in the sweep (their error decays by `1 - m / D` per iteration).
//!
//! **What.** After the sweep every body `b` that takes part (below) moves by a translation
//! `t_b` (m), the solution of the Galerkin coarse problem of eq. 12's linear system on the
//! bodies' translations `P` (`delta += P t`), with the contacts as constraints:
//!
//! `min_t  1/2 sum_b M_b |t_b|^2 - sum_b F_b . t_b`
//! subject to `n_c . (t_a - t_b) >= -max(g_c, 0)` for every contact `c`,
//!
//! `M_b` (kg) the body's mass and `F_b = sum_(i in b) (r_i - m_i s_i)` (kg m) the net
//! residual the settled moves `s` leave (below, "Fixed point"): `P^T (M + h^2 L) P =
//! diag(M_b)` and `P^T (r - (M + h^2 L) s) = F` because `L` (symmetric, bonds within a body)
//! has no stiffness against a translation.
//! A contact `c` is a particle `i` of body `a` at `p_i = y_i + delta_i` (where the sweep put
//! it) and either a collider (`g_c` its signed distance less the margin, `n_c` its normal;
//! `t_b = 0`) or a particle `j` of another body `b` among the repulsion's candidates
//! (`g_c = |p_i - p_j| - margin_i - margin_j`, `n_c = (p_i - p_j) / |p_i - p_j|`): the
//! translation may close a gap, but carries no particle deeper than the sweep put it. The
//! constraints are the linearisation of the distance, which underestimates it for a pair and
//! for a convex collider, so a feasible `t` keeps the contacts; the collider projection and the
//! repulsion that follow ([`super::step`]) correct the rest. A contact with a frictional
//! collider (coefficient `mu`) adds Coulomb friction
//! ([`super::coarse_problem::Friction`]): a tangential reaction within `mu` times the
//! contact's normal multiplier that stops the particle's slip over the step (from its start
//! position, relative to the collider's material point, at its settled position moved by
//! `t_a`) where it can, and otherwise opposes it on the cone's edge: the fine projection's
//! friction ([`crate::collider::push_out_with_friction`]) on the body's translation, so that a
//! body sliding on a frictional floor decelerates by `mu g h^2` in one coarse solve instead of
//! by the sweep's `m_i / D_i` of it. Only the contacts that a translation of
//! at most `|t_b| <= sqrt(sum_c M_c |t0_c|^2 / M_b)` can reach enter (`t0 = F / M` the
//! unconstrained solution; the solution is the `M`-projection of `t0` onto a convex set that
//! holds `t = 0`, so its `M`-norm is at most `t0`'s).
//!
//! The problem is solved by projected Gauss-Seidel on its dual ([`super::coarse_problem`]).
//!
//! **Fixed point.** The residual is taken at the settled moves `s_i`: the sweep's move, the
//! repulsion's answer to it and the push out of the colliders along their normals, where the
//! projection that follows will put the particle. At the fixed point the projection takes
//! back the sweep's move (`s = 0`, the friction's tangential correction included), the
//! residual is the contacts' reactions, `r_i = -D_i c_i`
//! with `c_i` the particle's projection move (`D_i = m_i + h^2 L_ii`, kg), and the repulsion's
//! reactions are pairwise equal and opposite (they share in the Jacobi metric): so
//! `F_b = sum_c lambda_c n_c` holds with `t = 0` and the multipliers of the projection,
//! `lambda_c = D_i (margin - gap)` at a collider, its gap measured where the colliders before
//! it left the particle (the push [`out_of_colliders`] gives it, not the gap at the sweep's
//! position: in a corner the first collider's friction may take back part of the second's
//! depth, and a start above the push let the friction start beyond `mu lambda_c`), and
//! `D_i D_j / (D_i + D_j)` times the overlap at a pair (the share of
//! [`super::repulsion::Repulsion::share`]) at the sweep's positions, and the friction's `D_i`
//! times its tangential correction (within the cone by construction; each collider's own, as
//! the projection applied it). The solve starts from these multipliers, so at the fixed point it starts at its
//! solution and moves nothing, whatever the number of sweeps; elsewhere they are a warm start.
//! (From the sweep's moves, `F_b = sum_i (r_i - m_i delta_i)`, and from zero multipliers, the
//! redundant contacts of bodies in contact are not solved within the sweeps, and the
//! translation left at an unconverged step carries momentum: docs/particles/solids.md, round s.) A
//! granular body and one with fluid particles keep the sweep's moves and start their contacts
//! from zero: their pairs share by mass and carry friction, whose reactions are not the coarse
//! problem's rows (docs/particles/solids.md); and a frictional collider that the sweep put within
//! their margin holds their tangential translation at zero ([`Friction::sticking`]; a dry and a wet
//! pile's runout and rest were measured that way, their grains' own slide on the floor being
//! the fine iteration's); the repulsion answers the sweep's move for the settled
//! moves only where two solid bodies may touch.
//!
//! **Who takes part.** A body with a pinned particle, or with a particle that another family
//! holds (`coupled`, a membrane's reaction on it, [`crate::solve::coupling`]), is fixed (as a
//! collider is). So is a granular body or one with fluid particles that a collider or another
//! body touched in the step's last trial (`touched`): their grains and fluid particles are
//! held by the repulsion within and the density constraints, not as one body; they take the
//! coarse translation in free flight only. `touched` starts empty at each step (at its first
//! iteration their contacts enter as constraints, as a solid body's), since no state file
//! holds the last step's. Rotations are left to the sweep: the deviatoric bond
//! forces (eq. 10) are not central, so their torques need not sum to zero over a body, and a
//! rigid rotation fitted to them would spin it.
//!
//! The Chebyshev history `y_prev` moves with the body, so that the extrapolation acts on the
//! fine iteration's error and does not repeat the translation.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::collider::ColliderModel;
use crate::real::Real;
use crate::solve::points::Points;

use super::coarse_problem::{Coarse, Contact, Friction};
use super::settled_move::out_of_colliders;
use super::system::ParticleSystem;

/// Adds every body's coarse translation (module doc) to `sys.delta`, the fine sweep's move
/// from the residual `sys.current.residual` at time step squared `h2` (s^2), and to the
/// Chebyshev history. `coupled` holds another family's reaction per particle (a membrane's,
/// [`crate::solve::coupling`]).
pub(crate) fn correct<T: Real>(
    sys: &mut ParticleSystem<T>,
    colliders: &[ColliderModel<T>],
    coupled: &[Vector3<T>],
    h2: T,
) {
    let mut coarse = std::mem::take(&mut sys.coarse);
    settle(sys, &mut coarse, colliders, h2);
    let energy = net_residuals(sys, &mut coarse, coupled);
    if energy > 0.0 {
        gather_contacts(sys, &mut coarse, colliders, energy, h2);
        coarse.solve();
        apply(sys, &coarse);
    }
    sys.coarse = coarse;
}

/// Every particle's settled move `s_i` (m; module doc, "Fixed point"): in a solid body the
/// sweep's move, the repulsion's answer to it (its [`super::repulsion::Repulsion::correct`] at
/// `y + delta` in the Jacobi metric of time step squared `h2`, s^2, when two solid bodies
/// may touch) and out of the colliders along their normals with their friction
/// ([`out_of_colliders`], the move it starts from kept in `coarse.swept`), zero for a pinned particle; in a
/// granular body or one with fluid particles the sweep's move.
fn settle<T: Real>(
    sys: &mut ParticleSystem<T>,
    coarse: &mut Coarse,
    colliders: &[ColliderModel<T>],
    h2: T,
) {
    let solid_pairs = coarse.solid.iter().filter(|&&s| s).count() >= 2;
    if let (Some(repulsion), true) = (&mut sys.repulsion, solid_pairs) {
        let rest = &sys.rest;
        repulsion.correct(&sys.points, &sys.delta, T::one(), |i| rest.diagonal(i, h2));
    }
    let repulsion = sys.repulsion.as_ref().filter(|_| solid_pairs);
    let (points, delta, rest) = (&sys.points, &sys.delta, &sys.rest);
    coarse.settled.resize(points.y.len(), Vector3::zeros());
    coarse.swept.resize(points.y.len(), Vector3::zeros());
    for (range, &solid) in points.ranges.iter().zip(&coarse.solid) {
        let start = range.start;
        coarse.settled[range.clone()]
            .par_iter_mut()
            .zip(coarse.swept[range.clone()].par_iter_mut())
            .enumerate()
            .for_each(|(k, (settled, swept))| {
                let i = start + k;
                *settled = delta[i].map(|c| c.to_f64());
                *swept = *settled;
                if !solid {
                    return;
                }
                if points.pinned[i] {
                    *settled = Vector3::zeros();
                    return;
                }
                let moved = delta[i] + repulsion.map_or(Vector3::zeros(), |r| r.of_particle(i));
                let colliders = Points::colliders_of(&points.collides, i, colliders);
                *swept = moved.map(|c| c.to_f64());
                let moved = out_of_colliders(
                    &points.y[i],
                    &points.y_start[i],
                    moved,
                    points.margin[i],
                    rest.diagonal(i, h2),
                    colliders,
                    |_, _, _| {},
                );
                *settled = moved.map(|c| c.to_f64());
            });
    }
}

/// Each body's inverse mass and net residual `F_b` at the settled moves, and the
/// unconstrained translation
/// `t0 = F / M` as the start of the solve (zero for a fixed body), summed in f64 in particle
/// order (the same for any thread count); returns `sum_b M_b |t0_b|^2` (kg m^2).
fn net_residuals<T: Real>(
    sys: &ParticleSystem<T>,
    coarse: &mut Coarse,
    coupled: &[Vector3<T>],
) -> f64 {
    let points = &sys.points;
    let (mass, r, settled) = (&points.mass, &sys.current.residual, &coarse.settled);
    let mut energy = 0.0;
    for (b, range) in points.ranges.iter().enumerate() {
        let fixed = range.clone().any(|i| {
            let coupled = coupled.get(i).is_some_and(|r| *r != Vector3::zeros());
            points.pinned[i] || coupled || (sys.touched[i] && !coarse.solid[b])
        });
        let (mut total, mut force) = (0.0, Vector3::<f64>::zeros());
        if !fixed {
            for i in range.clone() {
                total += mass[i].to_f64();
                force += r[i].map(|c| c.to_f64()) - settled[i] * mass[i].to_f64();
            }
        }
        let free = total > 0.0;
        coarse.inverse_mass[b] = if free { 1.0 / total } else { 0.0 };
        coarse.force[b] = if free { force } else { Vector3::zeros() };
        coarse.translation[b] = coarse.force[b] * coarse.inverse_mass[b];
        energy += coarse.force[b].dot(&coarse.translation[b]);
    }
    energy
}

/// The contacts (module doc) that a translation within the bound of `energy`
/// (`sum_b M_b |t0_b|^2`, kg m^2) can reach, in particle order. Each particle's smallest
/// collider gap is found in parallel first, so that the serial gathering evaluates the
/// colliders only where one is within reach (the same contacts for any thread count). Each
/// starts from the projection's reaction (module doc, "Fixed point"; `h2` the time step
/// squared, s^2).
fn gather_contacts<T: Real>(
    sys: &ParticleSystem<T>,
    coarse: &mut Coarse,
    colliders: &[ColliderModel<T>],
    energy: f64,
    h2: T,
) {
    let points = &sys.points;
    let diagonal = |i: usize| sys.rest.diagonal(i, h2);
    let body_of = |j: usize| points.ranges.partition_point(|r| r.end <= j);
    let at = |i: usize| points.y[i] + sys.delta[i];
    let Coarse {
        solid,
        inverse_mass,
        contacts,
        frictions,
        collider_gap,
        settled,
        swept,
        collider_reaction,
        ..
    } = coarse;
    let reach = |b: usize| (energy * inverse_mass[b]).sqrt();
    collider_gap.resize(points.y.len(), f64::INFINITY);
    collider_gap
        .par_iter_mut()
        .enumerate()
        .for_each(|(i, gap)| {
            *gap = f64::INFINITY;
            if inverse_mass[body_of(i)] == 0.0 {
                return;
            }
            let p = at(i);
            for c in Points::colliders_of(&points.collides, i, colliders) {
                *gap = gap.min((c.signed_distance(&p) - points.margin[i]).to_f64());
            }
        });
    contacts.clear();
    frictions.clear();
    for (a, range) in points.ranges.iter().enumerate() {
        if inverse_mass[a] == 0.0 {
            continue;
        }
        let s_a = reach(a);
        for i in range.clone() {
            let p = at(i);
            let near = if collider_gap[i] < s_a {
                Points::colliders_of(&points.collides, i, colliders)
            } else {
                &[]
            };
            collider_reaction.clear();
            collider_reaction.resize(near.len(), (0.0, Vector3::zeros()));
            if solid[a] && !near.is_empty() {
                let d = diagonal(i);
                out_of_colliders(
                    &points.y[i],
                    &points.y_start[i],
                    swept[i].map(T::of),
                    points.margin[i],
                    d,
                    near,
                    |k, push, phi| {
                        collider_reaction[k] = (d.to_f64() * push.to_f64(), phi.map(|c| c.to_f64()))
                    },
                );
            }
            for (c, (reaction, start)) in near.iter().zip(collider_reaction.iter()) {
                let gap = (c.signed_distance(&p) - points.margin[i]).to_f64();
                if gap >= s_a {
                    continue;
                }
                let n = c.normal(&p).map(|x| x.to_f64());
                contacts.push(Contact::new(a, None, n, -gap.max(0.0)).starting_from(*reaction));
                if c.friction > T::zero() && !solid[a] {
                    if gap <= 0.0 {
                        let normal = contacts.len() - 1;
                        frictions.push(Friction::sticking(a, normal, &n));
                    }
                } else if c.friction > T::zero() {
                    let at = points.y[i] + settled[i].map(T::of);
                    let slip = ((at - points.y_start[i]) - c.displacement(&at)).map(|x| x.to_f64());
                    let slip_t = slip - n * n.dot(&slip);
                    let mu = c.friction.to_f64();
                    let normal = contacts.len() - 1;
                    frictions.push(Friction::new(a, normal, &n, &slip_t, mu, start));
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
                let s_b = if b_free { reach(b) } else { 0.0 };
                if gap >= s_a + s_b || distance == 0.0 {
                    continue;
                }
                let n = offset.map(|x| x.to_f64()) / distance;
                let b = b_free.then_some(b);
                let reaction = if solid[a] && solid[body_of(j)] {
                    let share = repulsion.share(points, &diagonal, i, j).to_f64();
                    diagonal(i).to_f64() * share * (-gap).max(0.0)
                } else {
                    0.0
                };
                contacts.push(Contact::new(a, b, n, -gap.max(0.0)).starting_from(reaction));
            }
        }
    }
}

/// Adds each body's translation to its particles' moves and Chebyshev history.
fn apply<T: Real>(sys: &mut ParticleSystem<T>, coarse: &Coarse) {
    let points = &mut sys.points;
    let history = points.y_prev.len() == points.y.len();
    for (b, range) in points.ranges.iter().enumerate() {
        if coarse.inverse_mass[b] == 0.0 || coarse.translation[b] == Vector3::zeros() {
            continue;
        }
        let t = coarse.translation[b].map(T::of);
        sys.delta[range.clone()]
            .par_iter_mut()
            .for_each(|d| *d += t);
        if history {
            let exact = &coarse.translation[b];
            sys.exact
                .shift_previous(range.clone(), &mut points.y_prev, exact);
        }
    }
}
