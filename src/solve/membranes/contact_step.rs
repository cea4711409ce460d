//! The solver's side of contact: every body's triangles in global vertex indices, the last
//! intersection-free positions, and the call of the contact local step (Algorithm 2) after
//! each global iteration.

use std::cell::OnceCell;

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::collider::{push_out_of_colliders, ColliderModel, MoveStart};
use crate::contact::{
    resolve_contacts, ContactMesh, ContactParams, ContactStats, ProximalMetric, ProximalWeights,
    SavedRestGaps, Workspace,
};
use crate::membrane::Membrane;
use crate::parallel::chunked_sum;
use crate::real::Real;
use crate::symmetric::SymmetricMatrix3;

use super::jacobi::jacobi_block;
use super::reaction::realised_reaction;
use super::system::MembraneSystem;
use crate::solve::point_system::PointSystem;

/// How close to a collider's surface (m, beyond the vertex's half thickness) a vertex counts as
/// resting on it: the local step leaves the vertices it keeps out on the surface, up to
/// round-off (tens of nanometres in f32).
const TOUCHING: f64 = 1e-6;

/// Contact topology (built once per body list) and the state of the current time step.
pub(crate) struct ContactState<T: Real> {
    triangles: Vec<[u32; 3]>,
    body: Vec<u32>,
    self_contact: Vec<bool>,
    /// `z^{k-1}`: the last positions the local step left (intersection-free), in f64.
    safe: Vec<Vector3<f64>>,
    /// `z^k` while the local step works on it (reused, swapped with `safe`).
    next: Vec<Vector3<f64>>,
    /// The local step's buffers, kept from iteration to iteration and step to step.
    work: Workspace,
    /// Per vertex, the part of the last local step's move `z_i - y_i^k` that is a non-negative
    /// mix of the barrier's push at `z_i` and the outward normals of the colliders `z_i` rests
    /// on ([`realised_reaction`]): the contact reaction it realised (m; zero away from contact;
    /// empty before the first local step of a time step).
    reaction: Vec<Vector3<T>>,
    /// Per vertex, its body's friction coefficient against membranes (set each step).
    friction: Vec<f64>,
}

impl<T: Real> ContactState<T> {
    /// Concatenates the bodies' triangles in the system's global vertex numbering; call
    /// [`Self::start_step`] before each step.
    pub fn new(bodies: &[&mut Membrane], sys: &MembraneSystem<T>) -> Self {
        let mut triangles = Vec::new();
        let mut body = Vec::new();
        for (b, (membrane, range)) in bodies.iter().zip(&sys.points.ranges).enumerate() {
            let base = range.start as u32;
            for t in membrane.mesh().triangles() {
                triangles.push(t.map(|v| v + base));
                body.push(b as u32);
            }
        }
        let n = sys.points.y_start.len();
        Self {
            triangles,
            body,
            self_contact: Vec::with_capacity(bodies.len()),
            safe: vec![Vector3::zeros(); n],
            next: vec![Vector3::zeros(); n],
            work: Workspace::default(),
            reaction: Vec::with_capacity(n),
            friction: Vec::with_capacity(n),
        }
    }

    /// Takes the bodies' current self-contact switches and friction coefficients, and the
    /// start-of-step positions `y_t` as the first safe positions.
    pub fn start_step(&mut self, bodies: &[&mut Membrane], sys: &MembraneSystem<T>) {
        self.reaction.clear();
        self.self_contact.clear();
        self.self_contact
            .extend(bodies.iter().map(|b| b.self_contact()));
        self.friction.clear();
        for (b, range) in bodies.iter().zip(&sys.points.ranges) {
            self.friction.resize(range.end, b.friction());
        }
        for (safe, start) in self.safe.iter_mut().zip(&sys.points.y_start) {
            *safe = start.map(|c| c.to_f64());
        }
        self.work.start_step(&self.safe, &self.friction);
    }

    /// Runs the local step on `sys.points.y_next` (the global step's result, after colliders), keeping
    /// vertices out of the colliders, and makes the result the new safe positions. `h` (s) is
    /// the time step, for the Jacobi blocks of [`ProximalMetric::Jacobi`]; `tol` (m) the
    /// solver's tolerance, which bounds the local step's stopping distance
    /// ([`ContactParams::stop_distance`]). `blocks`: the systems `D_k` at the iterate
    /// `sys.points.y` the global step started from, when the responses of the last evaluation
    /// are not those of that iterate (Newton's line search leaves them evaluated at its
    /// trial); `None`: from the responses. The proximal metric must be taken there for every
    /// method alike: at a fixed point `W(y) (y - y^k) = p(y)` with `y^k - y = D(y)^-1 r(y)` is
    /// `r(y) = -d(y) p(y)`, the stationarity of `E + d mu B / h^2`, only if `W = D(y) / d(y)`
    /// (with `W` taken at Newton's trial the two methods' solutions differed by 9e-7 m).
    /// Returns the largest move from `sys.points.y` (m) and the step's figures.
    pub fn local_step(
        &mut self,
        sys: &mut MembraneSystem<T>,
        h: T,
        params: &ContactParams,
        tol: f64,
        colliders: &[ColliderModel<T>],
        blocks: Option<&[PointSystem<T>]>,
    ) -> (f64, ContactStats) {
        let mut z = std::mem::take(&mut self.next);
        for (zi, next) in z.iter_mut().zip(&sys.points.y_next) {
            *zi = next.map(|c| c.to_f64());
        }
        let mesh = ContactMesh {
            triangles: &self.triangles,
            body: &self.body,
            self_contact: &self.self_contact,
        };
        let rest = &sys.rest;
        // `d` of the Jacobi metric (kg), for the barrier's energy `d mu B / h^2`.
        let scale = std::sync::OnceLock::new();
        let jacobi = |weights: &mut Vec<SymmetricMatrix3<f64>>| {
            let d = jacobi_weights(sys, h, blocks, weights);
            let _ = scale.set(d);
        };
        let weights = match params.proximal {
            ProximalMetric::Identity => None,
            ProximalMetric::Jacobi => Some(&jacobi as &ProximalWeights),
        };
        let push_out = |i: usize,
                        from: &Vector3<f64>,
                        zi: &mut Vector3<f64>,
                        metric: Option<&SymmetricMatrix3<f64>>| {
            let inverse = metric.map(|a| a.map(T::of));
            let (from, margin) = (
                MoveStart::Now(from.map(T::of)),
                rest.vertices[i].half_thickness,
            );
            *zi = push_out_of_colliders(colliders, from, zi.map(T::of), margin, inverse.as_ref())
                .map(|c| c.to_f64());
        };
        let mut stats = resolve_contacts(
            &self.safe,
            &mut z,
            &sys.points.pinned,
            weights,
            &mesh,
            params,
            tol,
            &push_out,
            &mut self.work,
        );
        if stats.barrier > 0.0 {
            let d = scale
                .get()
                .copied()
                .unwrap_or_else(|| mass_scale(sys, h, blocks));
            let h = h.to_f64();
            stats.barrier_energy = d * stats.barrier / (h * h);
        }
        let y = &sys.points.y;
        let (push, weights) = (self.work.push(), self.work.weights());
        let friction = self.work.friction_move();
        self.reaction.clear();
        self.reaction.resize(z.len(), Vector3::zeros());
        let moved = sys
            .points
            .y_next
            .par_iter_mut()
            .zip(z.par_iter_mut())
            .zip(self.reaction.par_iter_mut())
            .enumerate()
            .map(|(i, ((next, zi), reaction))| {
                // The local step's move as far as the barrier's push and the colliders the
                // vertex ends on explain it: the realised contact reaction. In the local step's
                // metric a force `f` moves the vertex along `W_i^-1 f`.
                // The friction move is a reaction within its cone by construction (see
                // `contact::local_step::friction`), counted whole; the rest as below.
                let friction = friction.get(i).copied().unwrap_or_else(Vector3::zeros);
                let local_move = *zi - next.map(|c| c.to_f64()) - friction;
                // A vertex the local step left where the global step put it (most of a
                // draping cloth) realised no reaction beyond its friction move: its colliders
                // and metric are not looked at.
                let realised = if local_move == Vector3::zeros() {
                    Vector3::zeros()
                } else {
                    // `W_i^-1`, taken once for all of the vertex's directions, and only for a
                    // vertex that has one (most have none).
                    let metric_inverse = OnceCell::new();
                    let moves_along = |f: Vector3<f64>| {
                        let along = match weights {
                            Some(w) if f != Vector3::zeros() => metric_inverse
                                .get_or_init(|| w[i].try_inverse())
                                .as_ref()?
                                .mul_vector(&f),
                            _ => f,
                        };
                        let norm = along.norm();
                        (norm > 0.0).then(|| along / norm)
                    };
                    let push_direction = moves_along(push[i]);
                    let at = zi.map(T::of);
                    let touching = rest.vertices[i].half_thickness + T::of(TOUCHING);
                    // Empty (no allocation) unless the vertex rests on a collider.
                    let mut directions: Vec<Vector3<f64>> = colliders
                        .iter()
                        .filter(|c| c.signed_distance(&at) <= touching)
                        .filter_map(|c| moves_along(c.normal(&at).map(|x| x.to_f64())))
                        .collect();
                    match (directions.is_empty(), push_direction) {
                        (true, None) => Vector3::zeros(),
                        (true, Some(u)) => realised_reaction(&local_move, &[u]),
                        (false, _) => {
                            directions.extend(push_direction);
                            realised_reaction(&local_move, &directions)
                        }
                    }
                };
                *reaction = (friction + realised).map(T::of);
                *next = zi.map(T::of);
                // The safe positions are the ones the solver holds (rounded in f32).
                *zi = next.map(|c| c.to_f64());
                (*next - y[i]).norm_squared().to_f64().sqrt()
            })
            .reduce(|| 0.0, f64::max);
        self.next = std::mem::replace(&mut self.safe, z);
        // From now on the Jacobi move keeps its blocks for the metric.
        let n = sys.points.y.len();
        if params.proximal == ProximalMetric::Jacobi && sys.blocks.len() != n {
            sys.blocks.resize(n, SymmetricMatrix3::zeros());
            sys.blocks_fresh = false;
        }
        (moved, stats)
    }

    /// Per vertex, the contact reaction the last local step realised (m), for the convergence
    /// measure (empty before the first local step of the time step).
    pub fn reaction(&self) -> &[Vector3<T>] {
        &self.reaction
    }

    /// Per vertex, the warm start of the next local step (m; empty: none), in the system's
    /// global vertex numbering: the only part of this state carried from one time step to the
    /// next that changes results (the rest are caches or set anew each step).
    pub fn warm_start(&self) -> &[Vector3<f64>] {
        self.work.warm_start()
    }

    /// Replaces the warm start of the next local step (see [`Self::warm_start`]).
    pub fn set_warm_start(&mut self, warm: &[Vector3<f64>]) {
        self.work.set_warm_start(warm);
    }

    /// The rest gaps of the pairs that started within the barrier's reach, in the system's
    /// global vertex numbering (`None` before the first local step seeds them): carried from
    /// one time step to the next, and changing results, like the warm start.
    pub fn rest_gaps(&self) -> Option<SavedRestGaps> {
        self.work.rest_gaps()
    }

    /// Replaces the rest gaps (see [`Self::rest_gaps`]); every vertex of a saved pair must be
    /// one of the system's.
    pub fn set_rest_gaps(&mut self, saved: &SavedRestGaps) {
        let mesh = ContactMesh {
            triangles: &self.triangles,
            body: &self.body,
            self_contact: &self.self_contact,
        };
        self.work.set_rest_gaps(saved, &mesh);
    }

    /// The barrier's push `-mu grad_i B` per vertex at the last local step's result (m; empty
    /// before it, zero away from contact).
    #[cfg(test)]
    pub fn push(&self) -> &[Vector3<f64>] {
        self.work.push()
    }

    /// The local step's buffers, for the tests that drop a piece of them.
    #[cfg(test)]
    pub fn work_mut(&mut self) -> &mut Workspace {
        &mut self.work
    }
}

/// `d`, the mean of `trace(D_i) / 3` over the free vertices (kg; 1 if none is free), with `D_i`
/// the Jacobi block of eq. 25 at the current iterate (`blocks`, or from the responses, see
/// [`ContactState::local_step`]): the barrier's energy is `d mu B / h^2` (J) whatever the
/// proximal metric (see [`ProximalMetric::Jacobi`]).
fn mass_scale<T: Real>(sys: &MembraneSystem<T>, h: T, blocks: Option<&[PointSystem<T>]>) -> f64 {
    let mut weights = Vec::new();
    jacobi_weights(sys, h, blocks, &mut weights)
}

/// Writes into `weights` the metric of [`ProximalMetric::Jacobi`] for every vertex, `W_i = D_i /
/// d` with `D_i` its Jacobi block of eq. 25 at the current iterate (kg; `blocks`, or from the
/// responses of the last evaluation, see [`ContactState::local_step`]) and `d` the mean of
/// `trace(D_i) / 3` over the free vertices (the identity everywhere if none is free), and
/// returns `d` (kg; 1 if none is free).
fn jacobi_weights<T: Real>(
    sys: &MembraneSystem<T>,
    h: T,
    blocks: Option<&[PointSystem<T>]>,
    weights: &mut Vec<SymmetricMatrix3<f64>>,
) -> f64 {
    let h2 = h * h;
    // The blocks the Jacobi move just assembled from the same responses, when it kept them.
    let kept = (blocks.is_none() && sys.blocks_fresh).then_some(&sys.blocks[..]);
    (0..sys.points.y.len())
        .into_par_iter()
        .map(|k| {
            let block = match (blocks, kept) {
                (Some(b), _) => b[k].system,
                (None, Some(kept)) => kept[k],
                (None, None) => jacobi_block(sys, k, h2),
            };
            block.map(|x| x.to_f64())
        })
        .collect_into_vec(weights);
    let pinned = &sys.points.pinned;
    let free = pinned.iter().filter(|&&p| !p).count();
    let sum = chunked_sum(weights.len(), &mut Vec::new(), |k| {
        if pinned[k] {
            0.0
        } else {
            weights[k].diagonal.iter().sum::<f64>() / 3.0
        }
    });
    let scale = if free > 0 { free as f64 / sum } else { 0.0 };
    weights.par_iter_mut().for_each(|w| {
        *w = if scale > 0.0 {
            *w * scale
        } else {
            SymmetricMatrix3::zeros().plus_identity(1.0)
        }
    });
    if scale > 0.0 {
        1.0 / scale
    } else {
        1.0
    }
}
