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
//! and `j` free) and factored by a sparse Cholesky (AMD ordering, [`AggregateMatrix`]) when the time
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
//! resting on a cloth into it every iteration: docs/particles/solids.md has the measurements).
//! The colliders, the repulsion and the translations' coarse problem
//! ([`super::coarse`], which keeps the contacts one-sided) follow. Since the correction is a
//! Galerkin projection it leaves the fixed point `r = 0` alone.
//!
//! **Sliding particles.** A held particle whose only hold is one frictionless collider whose
//! normal is the same over the contact ([`crate::collider::ColliderModel::flat_normal`]: a
//! plane, a box's face away from its edges; no pin, no second collider within reach, no
//! repulsion move, no other family's reaction) holds only its move along that collider's
//! unit normal `n`: its row of `P` is `T = I - n n^T` in its aggregate's column, so the
//! correction moves it along the collider (the contact layer spreading sideways under a
//! landing body, which a held layer leaves to the sweep: its count grew with the particles
//! a side; docs/particles/performance.md, issue 38 rounds w, w2 and y). It enters the residual with
//! its settled move (a held particle's, above) and the restriction and the post-smoothing
//! through `T`. All sliding particles share one normal (the first sliding particle's; one
//! with another normal, on a second plane or another face of a box, is held whole): in the
//! frame `Q = [t_1 t_2 n]` then `T = diag(1, 1, 0)`, and since `A` is the same for the three
//! coordinates, `P^T A P` splits into the tangential coordinates' matrix, with the sliding
//! particles free, and the normal coordinate's, with them held ([`AggregateMatrix`] each):
//! the restricted residual is turned into `Q`, the first solves its three coordinates, the
//! second the normal one, which replaces the first's, and the solution is turned back. An
//! aggregate of sliding particles alone has a unit diagonal and a zero right-hand side in the
//! normal coordinate. A frictional collider holds the particle whole (static
//! friction takes the tangential move), and so does a curved one (a sphere, a capsule, a
//! mesh, a box's edge): there the normal turns as the particle slides, and a factor kept
//! with the old normals pulled a landing on a 2 m sphere off its fixed point
//! (docs/particles/solids.md, round w2). A body that slides on nothing takes the scalar matrix and
//! main's iterates.
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

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::collider::ColliderModel;
use crate::error::Result;
use crate::geometry::any_orthogonal_unit;
use crate::parallel::chunked_sum;
use crate::particles::ParticleRest;
use crate::real::Real;
use crate::solve::points::Points;

use super::aggregate_matrix::{AggregateMatrix, NONE};
use super::contact_gap::contact_reach;
use super::repulsion::Repulsion;
use super::roundoff::residual_floor;
use super::settled_move::out_of_colliders;

/// The aggregates, the coarse matrix `P^T A P` and its factor for one time step and held set.
pub(crate) struct TwoLevel {
    /// Per particle its aggregate, or [`NONE`].
    aggregate: Vec<usize>,
    /// This iteration's free set (the sliding particles among them), and `P^T A P` for it
    /// (three right-hand sides: the coordinates, or in the sliding frame the tangential ones).
    free: Vec<bool>,
    matrix: AggregateMatrix,
    /// The coarse matrix's lower triangle (pairs of aggregates `a >= b`, sorted): the pattern
    /// of the normal coordinate's matrix when particles slide.
    lower: Vec<(usize, usize)>,
    /// Per particle the unit normal of the flat frictionless collider it slides on in this
    /// iteration (zero: free or held; module doc, "Sliding particles"), the sliding
    /// particles' common normal (zero: none slides) and its frame `Q = [t_1 t_2 n]`.
    normal: Vec<Vector3<f64>>,
    slide_normal: Vector3<f64>,
    frame: Matrix3<f64>,
    /// The free particles that do not slide, and the normal coordinate's matrix for them
    /// with a copy of the restricted residuals it solves (built at the first iteration a
    /// particle slides).
    free_along: Vec<bool>,
    along: Option<(AggregateMatrix, Vec<Vector3<f64>>)>,
    /// Per particle the sweep's residual `r - A delta_J` (kg m), and a held particle's
    /// settled move (m; module doc, "Held particles"): the sweep's plus the repulsion's and
    /// another family's last moves, out of the colliders along their normals with friction.
    remainder: Vec<Vector3<f64>>,
    held_move: Vec<Vector3<f64>>,
    /// Per aggregate the restricted residual `P^T (r - A delta_J)` (kg m), then the coarse
    /// solution `e` (m): the prolongation and the post-smoothing read it once per bond, from
    /// here rather than through the factor's right-hand-side matrix.
    coarse: Vec<Vector3<f64>>,
    /// Symbolic analyses (of the coarse matrix and of the normal coordinate's) and numeric
    /// factorisations since the last [`Self::take_counts`].
    analyses: usize,
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
        let matrix = AggregateMatrix::new(rest, &aggregate, &lower, count, 3)?;
        Ok(Self {
            aggregate,
            free: vec![false; n],
            matrix,
            lower,
            normal: vec![Vector3::zeros(); n],
            slide_normal: Vector3::zeros(),
            frame: Matrix3::identity(),
            free_along: vec![false; n],
            along: None,
            remainder: vec![Vector3::zeros(); n],
            held_move: vec![Vector3::zeros(); n],
            coarse: vec![Vector3::zeros(); count],
            analyses: 1,
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

    /// Symbolic analyses and numeric factorisations since the last call (measures for
    /// [`crate::solve::StepStats`]).
    pub fn take_counts(&mut self) -> (usize, usize) {
        (
            std::mem::take(&mut self.analyses),
            std::mem::take(&mut self.factorizations),
        )
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
    /// part, which no free particle's bond reaches). A particle held by one flat frictionless
    /// collider alone slides on it (its normal at `y + delta`; module doc, "Sliding
    /// particles"). Then frees no particle of a body that holds none, that is within the contact reach
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
        let may_slide = colliders.iter().any(|c| c.may_slide());
        self.free
            .par_iter_mut()
            .zip(self.held_move.par_iter_mut())
            .zip(self.normal.par_iter_mut())
            .enumerate()
            .for_each(|(i, ((free, held_move), normal))| {
                *held_move = Vector3::zeros();
                *normal = Vector3::zeros();
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
                let (mut near, mut flat) = (0, None);
                for c in colliders {
                    if c.signed_distance(&to) <= reach || c.signed_distance(&points.y[i]) <= reach {
                        near += 1;
                        flat = c.may_slide().then(|| c.flat_normal(&to, reach)).flatten();
                    }
                }
                let held = near > 0 || touched[i] || reaction != Vector3::zeros();
                let unmoved = reaction == Vector3::zeros() && repelled == Vector3::zeros();
                let slides = flat.filter(|_| near == 1 && unmoved);
                *free = !held || slides.is_some();
                if !held {
                    // A free particle enters the restriction with the sweep's move.
                    return;
                }
                let moved = out_of_colliders(
                    &points.y[i],
                    &points.y_start[i],
                    delta[i] + reaction + repelled,
                    margin,
                    rest.diagonal(i, h2),
                    colliders,
                    |_, _, _| {},
                );
                *held_move = moved.map(|c| c.to_f64());
                if let Some(n) = slides {
                    *normal = n.map(|c| c.to_f64()).normalize();
                }
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
            let holds_none =
                (range.clone()).all(|i| self.free[i] && self.normal[i] == Vector3::zeros());
            if merit <= floor || touches_a_body || holds_none {
                self.free[range.clone()].fill(false);
                self.normal[range.clone()].fill(Vector3::zeros());
            }
        }
        if may_slide {
            self.share_normal();
        } else {
            self.slide_normal = Vector3::zeros();
        }
    }

    /// Holds whole a sliding particle whose normal is not the first sliding particle's
    /// (module doc, "Sliding particles"), and sets the common normal, its frame and the
    /// free particles that do not slide.
    fn share_normal(&mut self) {
        let zero = Vector3::zeros();
        let first = self.normal.iter().position(|n| *n != zero);
        let Some(first) = first else {
            self.slide_normal = zero;
            return;
        };
        let n = self.normal[first];
        self.slide_normal = n;
        for (normal, free) in (self.normal[first..].iter_mut()).zip(&mut self.free[first..]) {
            if *normal != zero && *normal != n {
                (*normal, *free) = (zero, false);
            }
        }
        let t = any_orthogonal_unit(&n);
        self.frame = Matrix3::from_columns(&[t, n.cross(&t), n]);
        for ((along, &free), n) in self.free_along.iter_mut().zip(&self.free).zip(&self.normal) {
            *along = free && *n == zero;
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
        let slides = self.slide_normal != Vector3::zeros();
        if self
            .matrix
            .factor(rest, &self.aggregate, &self.free, h.to_f64())?
        {
            self.factorizations += 1;
        }
        if slides {
            let (aggregate, count) = (&self.aggregate, self.coarse.len());
            let (along, _) = match &mut self.along {
                Some(along) => along,
                None => {
                    self.analyses += 1;
                    self.along.insert((
                        AggregateMatrix::new(rest, aggregate, &self.lower, count, 1)?,
                        vec![Vector3::zeros(); count],
                    ))
                }
            };
            if along.factor(rest, aggregate, &self.free_along, h.to_f64())? {
                self.factorizations += 1;
            }
        }
        {
            let (free, normal, held_move) = (&self.free, &self.normal, &self.held_move);
            let delta = &*delta;
            // A particle's move in `r - A delta`: the sweep's where free and not sliding, else
            // the settled one (module doc, "Held particles").
            let settled = |j: usize| {
                if free[j] && normal[j] == Vector3::zeros() {
                    delta[j].map(|c| c.to_f64())
                } else {
                    held_move[j]
                }
            };
            self.remainder
                .par_iter_mut()
                .enumerate()
                .for_each(|(i, out)| {
                    if !free[i] {
                        return;
                    }
                    let mut coupled = Vector3::<f64>::zeros();
                    for b in rest.row(i) {
                        coupled += settled(rest.indices[b] as usize) * rest.coupling[b].to_f64();
                    }
                    // In f64 whatever the body's precision (mixed precision: the restriction
                    // sums some 30 nearly cancelling terms per aggregate).
                    let d_i = rest.mass[i].to_f64() + h2 * rest.stiffness[i].to_f64();
                    let r = residual[i].map(|c| c.to_f64()) - settled(i) * d_i;
                    *out = r + coupled * h2;
                });
        }
        self.coarse.fill(Vector3::zeros());
        for (i, &a) in self.aggregate.iter().enumerate() {
            if !self.free[i] {
                continue;
            }
            let n = &self.normal[i];
            if *n == Vector3::zeros() {
                self.coarse[a] += self.remainder[i];
            } else {
                self.coarse[a] += tangent(n) * self.remainder[i];
            }
        }
        match (slides, &mut self.along) {
            (true, Some((along, normal_part))) => {
                let q = self.frame;
                for (c, out) in self.coarse.iter_mut().zip(normal_part.iter_mut()) {
                    *c = q.tr_mul(c);
                    *out = *c;
                }
                self.matrix.solve(&mut self.coarse, 0);
                along.solve(normal_part, 2);
                for (c, normal) in self.coarse.iter_mut().zip(normal_part.iter()) {
                    c.z = normal.z;
                    *c = q * *c;
                }
            }
            _ => self.matrix.solve(&mut self.coarse, 0),
        }
        // The prolonged correction `P e`, then one Jacobi sweep on what it leaves,
        // `r - A (delta_J + P e)`, at the free particles and along the sliding ones' colliders
        // (post-smoothing: the piecewise-constant correction's jumps between aggregates are
        // the sweep's to smooth).
        let (coarse, aggregate, free, normal, remainder) = (
            &self.coarse,
            &self.aggregate,
            &self.free,
            &self.normal,
            &self.remainder,
        );
        let at = |i: usize| {
            let (e, n) = (coarse[aggregate[i]], normal[i]);
            if n == Vector3::zeros() {
                e
            } else {
                e - n * n.dot(&e)
            }
        };
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
            let n = &normal[i];
            if *n == Vector3::zeros() {
                *d += (e + left / d_i).map(T::of);
            } else {
                *d += (e + tangent(n) * left / d_i).map(T::of);
            }
        });
        Ok(())
    }
}

/// `I - n n^T`: the prolongator row of a particle sliding on a collider of unit normal `n`.
#[inline]
fn tangent(n: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::identity() - n * n.transpose()
}

#[cfg(test)]
#[path = "two_level_tests.rs"]
mod tests;
