//! The two-level correction of the particles' Jacobi sweep (issue 38): a coarse-grid
//! correction on aggregates of particles, which holds the slow elastic modes the sweep barely
//! moves (a body's compression against the floor after a landing: its Jacobi factor is
//! `1 - (1 + (h w)^2) m / D`, within 1e-3 of 1 at 8K particles).
//!
//! **What.** The global step's linear system is `A delta = r` with `A = M + h^2 L` (eq. 12;
//! `L` the constant bond matrix, the same for the three coordinates). After the sweep's move
//! `delta_J = D^-1 r` the correction adds `delta += P e`, the Galerkin coarse-grid correction
//!
//! `(P^T A P) e = P^T (r - A delta_J)`,
//!
//! with `P` the piecewise-constant prolongation of the free particles' aggregates: `P_ia = 1`
//! where free particle `i` lies in aggregate `a`, 0 otherwise (the multiplicative two-level
//! method with a Jacobi smoother; Vanek, Mandel and Brezina 1996 for the aggregation).
//! `P^T A P` is formed from `A`'s entries (`(P^T A P)_ab = sum_(i in a, j in b) A_ij`, `i`
//! and `j` free) and factored by a sparse Cholesky (AMD ordering, [`SparseLlt`]) when the time
//! step or the held set changes; each iteration then restricts the sweep's residual
//! `r - A delta_J` (one pass over the bonds), solves for the three coordinates and prolongs.
//!
//! **Held particles.** A pinned particle, one another family holds (a membrane's reaction,
//! [`crate::solve::coupling`]), one a collider or the repulsion moved in the last trial
//! (`touched`), and one within [`super::contact_gap::contact_reach`] of a collider at the
//! current iterate or at the sweep's move has no column in `P`: the correction leaves it
//! where the sweep put it, and the body's aggregates above a floor compress against it (the
//! contact held in the coarse space, as the direct solver holds it, [`super::direct`]). A
//! held particle enters the restriction with its settled move: the sweep's plus the last
//! moves of the repulsion and of another family's reaction (the coupling's, which acts after
//! the move), pushed out of the colliders with their friction (where it goes,
//! [`super::settled_move`]). At the fixed point these reactions take back the sweep's move (`y_next = y`), so the settled moves, the restriction and the
//! correction vanish there (with the sweep's move alone, the correction would pull a body
//! resting on a cloth into it every iteration: docs/model.md has the measurements).
//! The colliders, the repulsion and the translations' coarse problem
//! ([`super::coarse`], which keeps the contacts one-sided) follow. Since the correction is a
//! Galerkin projection it leaves the fixed point `r = 0` alone.
//!
//! **Who takes part.** A body that holds no particle (no pin, no contact) takes no correction.
//! The coarse matrix is the constant `A`, the tangent of eq. 12 only near the rest shape;
//! where a large deformation makes the true tangent indefinite, the coarse step along the
//! aggregates goes astray: a flattened inverted 5^3 block (`tests/test_particles.py`) ran its
//! first step to the cap of 200 iterations at 1.3e-3 m with it (134 iterations to 1e-7 m
//! without), and the unconverged iterate left it spinning (turned over within 1 s). Taking
//! the rigid rotation out of a free body's correction did not help (3.3e-3 m after 200).
//! A held particle anchors the body, and the slow modes the correction is for (a body's
//! compression against a floor, a stretched body between pins) are there. Nor does a body
//! within the contact reach of another body's particle (the repulsion's partners): at a
//! contact between two bodies the correction kept two stacked 4^3 blocks at rest from
//! converging (300 iterations a step at 5e-3 m, against 2 iterations without; holding the
//! particles within reach of a partner and moving them by the repulsion's last move in the
//! restriction left 2e-3 m). There the settled moves (above) keep the fixed point, but the
//! support is itself a slow mode: the interface between the bodies sinks as the lower one
//! compresses, and a held contact layer leaves that to the sweep; pair springs fed by the
//! repulsion's last moves fail too, since the repulsion's move is the projection's answer to
//! the whole last move, the last correction included, not a
//! force that the next correction may take as given. A body on a membrane takes part: the
//! membrane is not in the coarse problem, and its reaction enters as the held particles'
//! settled moves.
//!
//! **When.** Not in a step's first iteration: its convergence measure is taken at the
//! iterate before the move, so a step that converges there (a body at rest) gains nothing from
//! the correction, whose held set differs from the last step's (`touched` starts empty) and
//! would refactor the coarse matrix every step. A body whose merit `sum_i |r_i|^2 / m_i`
//! (kg m^2, over its own particles) is below its round-off floor is held whole (its move is
//! round-off: at rest or in free fall), each body by its own merit, so that a body's iterates
//! do not depend on another body's it does not touch. Off with `two_level=False`
//! ([`crate::solve::SolverParams::particle_two_level`]).
//!
//! **Aggregates.** Plain aggregation on the bond graph, once per working set, in particle
//! order (the same for any thread count): a particle whose neighbours are all unaggregated
//! founds an aggregate of itself and them (about the 30 particles of a horizon); a leftover
//! joins the aggregate of its first aggregated neighbour, else founds one with its
//! unaggregated neighbours. Granular and fluid bodies take no part (their particles are held
//! by their own constraints, not by bonds), nor does a plastic body (its bonds change every
//! step); their particles have no aggregate. When a plastic body's neighbourhoods change the
//! family's bonds are renumbered, and the correction is built anew ([`super::plastic`]).

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::collider::ColliderModel;
use crate::error::{invalid, Result};
use crate::parallel::chunked_sum;
use crate::particles::ParticleRest;
use crate::real::Real;
use crate::solve::points::Points;
use crate::sparse_llt::SparseLlt;

use super::contact_gap::contact_reach;
use super::repulsion::Repulsion;
use super::roundoff::residual_floor;
use super::settled_move::out_of_colliders;

/// No aggregate (a particle of a body that takes no part), or no slot (a bond whose entry is
/// in the upper triangle or outside the coarse matrix).
const NONE: usize = usize::MAX;

/// The aggregates, the coarse matrix `P^T A P` and its factor for one time step and held set.
pub(crate) struct TwoLevel {
    /// Per particle its aggregate, or [`NONE`].
    aggregate: Vec<usize>,
    /// The time step (s) and per particle whether it was free when last factored (`h = NaN`:
    /// no factor yet), and this iteration's free set.
    h: f64,
    factored_free: Vec<bool>,
    free: Vec<bool>,
    /// `P^T A P` (right-hand sides `aggregates x 3`); per aggregate the slot of its diagonal
    /// and per bond the slot of its entry (or [`NONE`]).
    llt: SparseLlt,
    diagonal_slot: Vec<usize>,
    bond_slot: Vec<usize>,
    /// Per particle the sweep's residual `r - A delta_J` (kg m), and a held particle's
    /// settled move (m; module doc, "Held particles"): the sweep's plus the repulsion's and
    /// another family's last moves, out of the colliders along their normals with friction.
    remainder: Vec<Vector3<f64>>,
    held_move: Vec<Vector3<f64>>,
    /// Per aggregate the restricted residual `P^T (r - A delta_J)` (kg m), then the coarse
    /// solution `e` (m): the prolongation and the post-smoothing read it once per bond, from
    /// here rather than through the factor's right-hand-side matrix.
    coarse: Vec<Vector3<f64>>,
    /// Numeric factorisations since the last [`Self::take_factorizations`].
    factorizations: usize,
    /// Whether the step's first iteration is still to come ([`Self::past_first_iteration`]).
    first_iteration: bool,
    /// Partial sums of a body's merit and its floor (reused).
    chunks: Vec<f64>,
}

impl TwoLevel {
    /// The aggregates of the particles `takes_part` marks, on the bonds of `rest`, the
    /// pattern of their coarse matrix and its symbolic factor (no numeric factor yet).
    pub fn new<T: Real>(rest: &ParticleRest<T>, takes_part: &[bool]) -> Result<Self> {
        let n = rest.len();
        let neighbours = |i: usize| rest.row(i).map(|b| rest.indices[b] as usize);
        let mut aggregate = vec![NONE; n];
        let mut count = 0;
        for i in 0..n {
            if takes_part[i] && aggregate[i] == NONE && neighbours(i).all(|j| aggregate[j] == NONE)
            {
                aggregate[i] = count;
                neighbours(i).for_each(|j| aggregate[j] = count);
                count += 1;
            }
        }
        let founded = aggregate.clone();
        for i in 0..n {
            if takes_part[i] && aggregate[i] == NONE {
                if let Some(j) = neighbours(i).find(|&j| founded[j] != NONE) {
                    aggregate[i] = founded[j];
                } else {
                    aggregate[i] = count;
                    for j in neighbours(i) {
                        if aggregate[j] == NONE {
                            aggregate[j] = count;
                        }
                    }
                    count += 1;
                }
            }
        }
        let mut lower: Vec<(usize, usize)> = (0..count).map(|a| (a, a)).collect();
        for i in 0..n {
            let a = aggregate[i];
            if a == NONE {
                continue;
            }
            lower.extend(
                neighbours(i)
                    .map(|j| aggregate[j])
                    .filter(|&b| b != NONE && b < a)
                    .map(|b| (a, b)),
            );
        }
        lower.sort_unstable();
        lower.dedup();
        let llt = SparseLlt::new(count, lower, 3)
            .map_err(|e| invalid!("the two-level coarse matrix's pattern failed: {e}"))?;
        let diagonal_slot = (0..count).map(|a| llt.slot(a, a)).collect();
        let mut bond_slot = vec![NONE; rest.indices.len()];
        for i in 0..n {
            let a = aggregate[i];
            for b in rest.row(i) {
                let c = aggregate[rest.indices[b] as usize];
                if a != NONE && c != NONE && c <= a {
                    bond_slot[b] = llt.slot(a, c);
                }
            }
        }
        Ok(Self {
            aggregate,
            h: f64::NAN,
            factored_free: vec![false; n],
            free: vec![false; n],
            llt,
            diagonal_slot,
            bond_slot,
            remainder: vec![Vector3::zeros(); n],
            held_move: vec![Vector3::zeros(); n],
            coarse: vec![Vector3::zeros(); count],
            factorizations: 0,
            first_iteration: true,
            chunks: Vec::new(),
        })
    }

    /// Readies the correction for a step: it waits for the step's second iteration (module
    /// doc, "When").
    pub fn start_step(&mut self) {
        self.first_iteration = true;
    }

    /// Whether the step's first iteration is over; marks it over.
    pub fn past_first_iteration(&mut self) -> bool {
        !std::mem::replace(&mut self.first_iteration, false)
    }

    /// Numeric factorisations since the last call (a measure for [`crate::solve::StepStats`]).
    pub fn take_factorizations(&mut self) -> usize {
        std::mem::take(&mut self.factorizations)
    }

    /// Fills `P^T A P` for the time step `h` (s) and the free set, and factors it, unless the
    /// factor at hand is that one. An aggregate without a free particle keeps a unit diagonal
    /// (its unknown is decoupled and its right-hand side zero).
    fn factor<T: Real>(&mut self, rest: &ParticleRest<T>, h: f64) -> Result<()> {
        if self.h == h && self.factored_free == self.free {
            return Ok(());
        }
        let h2 = h * h;
        let (aggregate, free) = (&self.aggregate, &self.free);
        let values = self.llt.values_mut();
        values.fill(0.0);
        for i in 0..aggregate.len() {
            let a = aggregate[i];
            if a == NONE || !free[i] {
                continue;
            }
            values[self.diagonal_slot[a]] +=
                rest.mass[i].to_f64() + h2 * rest.stiffness[i].to_f64();
            for b in rest.row(i) {
                let slot = self.bond_slot[b];
                if slot != NONE && free[rest.indices[b] as usize] {
                    values[slot] -= h2 * rest.coupling[b].to_f64();
                }
            }
        }
        for &slot in &self.diagonal_slot {
            if values[slot] == 0.0 {
                values[slot] = 1.0;
            }
        }
        self.h = f64::NAN;
        self.factorizations += 1;
        self.llt
            .factor()
            .map_err(|e| invalid!("the two-level coarse factorisation failed: {e}"))?;
        self.h = h;
        self.factored_free.copy_from_slice(&self.free);
        Ok(())
    }

    /// The correction for the particle bodies `ranges` of the working set `rest`, if some
    /// particle takes part: every particle of a body that `takes_part` marks (an elastic
    /// solid: not granular, no fluid particle, not plastic).
    pub fn of_bodies<T: Real>(
        rest: &ParticleRest<T>,
        ranges: &[std::ops::Range<usize>],
        takes_part: &[bool],
    ) -> Result<Option<Self>> {
        let mut part = vec![false; rest.len()];
        for (range, &takes_part) in ranges.iter().zip(takes_part) {
            part[range.clone()].fill(takes_part);
        }
        if !part.iter().any(|&p| p) {
            return Ok(None);
        }
        Self::new(rest, &part).map(Some)
    }

    /// Marks the particles the correction holds at the sweep's move `delta` (m; module doc):
    /// pinned, touched in the last trial (`touched`), with another family's reaction
    /// (`coupled`, its last move, m), or within the contact reach of a collider at `y` or
    /// `y + delta`; and stores a held particle's settled move: the sweep's plus the
    /// `repulsion`'s and the coupling's last moves, out of the colliders along their normals
    /// with their friction ([`out_of_colliders`]; not for a particle of a body that takes no
    /// part, which no free particle's bond reaches). Then frees no particle of a body that holds
    /// none, that is within the contact reach
    /// of one of its `repulsion` partners (another body's particle, at `y` or `y + delta`),
    /// or whose merit from the `residual` (kg m) at time step `h` (s) is below its round-off
    /// floor: module doc, "Who takes part" and "When".
    #[allow(clippy::too_many_arguments)]
    pub fn hold<T: Real>(
        &mut self,
        rest: &ParticleRest<T>,
        residual: &[Vector3<T>],
        h: T,
        points: &Points<T>,
        touched: &[bool],
        delta: &[Vector3<T>],
        colliders: &[ColliderModel<T>],
        coupled: &[Vector3<T>],
        repulsion: Option<&Repulsion<T>>,
    ) {
        let aggregate = &self.aggregate;
        let h2 = h * h;
        self.free
            .par_iter_mut()
            .zip(self.held_move.par_iter_mut())
            .enumerate()
            .for_each(|(i, (free, held_move))| {
                *held_move = Vector3::zeros();
                if points.pinned[i] || aggregate[i] == NONE {
                    *free = false;
                    return;
                }
                let margin = points.margin[i];
                let reach = contact_reach(margin);
                let reaction = coupled.get(i).copied().unwrap_or_default();
                let repelled = repulsion.map_or(Vector3::zeros(), |r| r.of_particle(i));
                let to = points.y[i] + delta[i];
                let colliders = Points::colliders_of(&points.collides, i, colliders);
                let near = colliders.iter().any(|c| {
                    c.signed_distance(&to) <= reach || c.signed_distance(&points.y[i]) <= reach
                });
                let moved = out_of_colliders(
                    &points.y[i],
                    &to,
                    &points.y_start[i],
                    delta[i] + reaction + repelled,
                    margin,
                    rest.diagonal(i, h2),
                    colliders,
                    |_, _| {},
                );
                let held = near || touched[i] || reaction != Vector3::zeros();
                *free = !held;
                *held_move = moved.map(|c| c.to_f64());
            });
        for range in &points.ranges {
            if !self.free[range.clone()].iter().any(|&f| f) {
                continue;
            }
            let start = range.start;
            let merit = chunked_sum(range.len(), &mut self.chunks, |k| {
                let i = start + k;
                residual[i].norm_squared().to_f64() / points.mass[i].to_f64()
            });
            let floor = chunked_sum(range.len(), &mut self.chunks, |k| {
                let i = start + k;
                let nu = residual_floor(&points.y[i], rest.diagonal(i, h2), points.mass[i]);
                points.mass[i].to_f64() * nu * nu
            });
            let touches_a_body = repulsion.is_some_and(|rep| {
                range.clone().any(|i| {
                    rep.partners(i).iter().any(|&j| {
                        let j = j as usize;
                        let reach = contact_reach(points.margin[i] + points.margin[j]);
                        (points.y[i] - points.y[j]).norm() <= reach
                            || (points.y[i] + delta[i] - points.y[j] - delta[j]).norm() <= reach
                    })
                })
            });
            let holds_none = self.free[range.clone()].iter().all(|&f| f);
            if merit <= floor || touches_a_body || holds_none {
                self.free[range.clone()].fill(false);
            }
        }
    }

    /// Adds the coarse-grid correction `P e` and one Jacobi post-smoothing sweep to the
    /// sweep's move `delta` (m) from the residual `residual` (kg m) of eq. 12 at time step
    /// `h` (s), with the held set of the last [`Self::hold`] (nothing when it frees no
    /// particle). On a failed factorisation the move is left alone.
    pub fn correct<T: Real>(
        &mut self,
        rest: &ParticleRest<T>,
        residual: &[Vector3<T>],
        delta: &mut [Vector3<T>],
        h: T,
    ) -> Result<()> {
        if !self.free.iter().any(|&f| f) {
            return Ok(());
        }
        let h2 = h.to_f64() * h.to_f64();
        self.factor(rest, h.to_f64())?;
        {
            let (free, held_move) = (&self.free, &self.held_move);
            let delta = &*delta;
            self.remainder
                .par_iter_mut()
                .enumerate()
                .for_each(|(i, out)| {
                    if !free[i] {
                        return;
                    }
                    let mut coupled = Vector3::<f64>::zeros();
                    for b in rest.row(i) {
                        let j = rest.indices[b] as usize;
                        let d = if free[j] {
                            delta[j].map(|c| c.to_f64())
                        } else {
                            held_move[j]
                        };
                        coupled += d * rest.coupling[b].to_f64();
                    }
                    // In f64 whatever the body's precision (mixed precision: the restriction
                    // sums some 30 nearly cancelling terms per aggregate).
                    let d_i = rest.mass[i].to_f64() + h2 * rest.stiffness[i].to_f64();
                    let r = residual[i].map(|c| c.to_f64()) - delta[i].map(|c| c.to_f64()) * d_i;
                    *out = r + coupled * h2;
                });
        }
        self.coarse.fill(Vector3::zeros());
        for (i, &a) in self.aggregate.iter().enumerate() {
            if self.free[i] {
                self.coarse[a] += self.remainder[i];
            }
        }
        let rhs = self.llt.rhs_mut();
        for c in 0..3 {
            for (out, sum) in rhs.col_as_slice_mut(c).iter_mut().zip(&self.coarse) {
                *out = sum[c];
            }
        }
        self.llt.solve();
        let x = self.llt.rhs();
        let (x0, x1, x2) = (x.col_as_slice(0), x.col_as_slice(1), x.col_as_slice(2));
        for (a, e) in self.coarse.iter_mut().enumerate() {
            *e = Vector3::new(x0[a], x1[a], x2[a]);
        }
        // The prolonged correction, then one Jacobi sweep on what it leaves,
        // `r - A (delta_J + P e)`, at the free particles (post-smoothing: the piecewise-constant
        // correction's jumps between aggregates are the sweep's to smooth).
        let (coarse, aggregate, free, remainder) =
            (&self.coarse, &self.aggregate, &self.free, &self.remainder);
        let at = |i: usize| coarse[aggregate[i]];
        delta.par_iter_mut().enumerate().for_each(|(i, d)| {
            if !free[i] {
                return;
            }
            let e = at(i);
            let d_i = rest.mass[i].to_f64() + h2 * rest.stiffness[i].to_f64();
            let mut coupled = Vector3::<f64>::zeros();
            for b in rest.row(i) {
                let j = rest.indices[b] as usize;
                if free[j] {
                    coupled += at(j) * rest.coupling[b].to_f64();
                }
            }
            let left = remainder[i] - e * d_i + coupled * h2;
            *d += (e + left / d_i).map(T::of);
        });
        Ok(())
    }
}
