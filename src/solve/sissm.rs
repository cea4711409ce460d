//! The SISSM time step (Lu et al. 2023, Algorithm 1 without the contact local step).
//!
//! Implicit Euler asks for `m_i (y_i - y*_i) = h^2 f_i(y)` with `y* = y_t + h v_t + h^2 g`.
//! Each global iteration takes, per vertex and independently (one Jacobi sweep of eq. 25),
//!
//! `delta_i = (m_i I + h^2 sum_j (C_i + C_j))^-1 (m_i (y*_i - y_i) + h^2 f_i(y))`
//!
//! which is eq. 25-26 written in residual form: `A_ij = h^2 (C_i + C_j)` are the implicit
//! (positive) blocks and every other part of the exact force is explicit. The fixed point is
//! therefore the exact implicit Euler solution for any `C`. The step is scaled by the
//! per-vertex step length of eq. 31-33, `alpha_i = min(E_i / (f_i . delta_i), 1)`, where `E_i`
//! is the elastic energy of the vertices whose neighbourhood holds `i` (zero elastic energy is a
//! lower bound the linearised energy may not cross). Colliders project the result, then the
//! contact local step (Algorithm 2, [`crate::contact::resolve_contacts`]) when contact is on.
//!
//! The iteration starts from the lower-energy of `y*` and `y_t` ([`initial_guess`]) and stops
//! when `max_i |r_i| / m_i < tol` for the residual `r = m (y* - y) + h^2 f` (without the
//! reactions of the colliders and of the membrane contacts the vertex is in, see
//! [`super::jacobi::free_residual`]; with contact, not before the first local step). Where the energy is convex its Hessian `H` satisfies
//! `H >= M`, so the error `e = H^-1 r` obeys `|e|_M <= |r|_(M^-1)`: the test bounds the
//! mass-weighted RMS distance to the exact implicit Euler solution. Algorithm 1 tests the last
//! move `max_i |y_i^{k+1} - y_i^k|` instead, which declares slowly converging (stiff, fine)
//! problems solved far from their solution; that move is still reported as the residual history.

use std::time::Instant;

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::contact::{
    push_out_of_colliders, Collider, ColliderModel, MoveStart, MovingCollider, Pose,
};
use crate::error::{invalid, Error, Result};
use crate::membrane::{Membrane, Preconditioner};
use crate::real::Real;

use super::contact_step::ContactState;
use super::descent::{descent_iteration, DescentState, LineSearch};
use super::evaluate::{evaluate, inertial_energy, total_energy};
use super::jacobi::{jacobi_update, MoveOptions, Update};
use super::system::System;
use super::{Acceleration, Clock, Method, SolverParams, StepStats, Timings};

/// Steps a set of membranes in time.
pub struct Solver<T: Real> {
    params: SolverParams,
    colliders: Vec<MovingCollider>,
    pool: Option<rayon::ThreadPool>,
    system: Option<System<T>>,
    /// Contact topology of the current body list (built on the first step with contact).
    contact: Option<ContactState<T>>,
    /// The descent method's working set (built on the first descent step).
    descent: Option<DescentState>,
    clock: Clock,
}

fn millis(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

impl<T: Real> Solver<T> {
    /// A solver with `threads` workers (`None`: rayon's global pool, one per core).
    pub fn new(params: SolverParams, threads: Option<usize>) -> Result<Self> {
        params.validate()?;
        let pool = match threads {
            None => None,
            Some(0) => return Err(invalid!("threads must be >= 1, got 0")),
            Some(n) => Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .map_err(|e| invalid!("cannot start {n} threads: {e}"))?,
            ),
        };
        Ok(Self {
            params,
            colliders: Vec::new(),
            pool,
            system: None,
            contact: None,
            descent: None,
            clock: Clock::default(),
        })
    }

    pub fn params(&self) -> &SolverParams {
        &self.params
    }

    /// Replaces the parameters (validated).
    pub fn set_params(&mut self, params: SolverParams) -> Result<()> {
        params.validate()?;
        self.params = params;
        Ok(())
    }

    /// Number of worker threads used by `step`.
    pub fn threads(&self) -> usize {
        self.pool
            .as_ref()
            .map_or_else(rayon::current_num_threads, |p| p.current_num_threads())
    }

    /// Adds a collider (any shape, friction and motion).
    pub fn add_collider(&mut self, collider: Collider) -> Result<()> {
        self.colliders.push(MovingCollider::new(collider));
        Ok(())
    }

    pub fn colliders(&self) -> impl Iterator<Item = &Collider> {
        self.colliders.iter().map(|c| &c.collider)
    }

    /// The pose (shape frame to world) of collider `index` now.
    pub fn collider_pose(&self, index: usize) -> Result<Pose> {
        Ok(self.moving_collider(index)?.pose(self.clock.time))
    }

    /// Sets the pose collider `index` reaches at the end of the next step (see
    /// [`MovingCollider`]).
    pub fn set_collider_pose(&mut self, index: usize, pose: Pose) -> Result<()> {
        self.moving_collider(index)?;
        self.colliders[index].set_target(pose);
        Ok(())
    }

    /// The base pose and pending target of collider `index` (see [`MovingCollider::motion`]).
    pub fn collider_motion(&self, index: usize) -> Result<(Pose, Option<Pose>)> {
        Ok(self.moving_collider(index)?.motion())
    }

    /// Restores the motion of collider `index` read with [`Self::collider_motion`].
    pub fn set_collider_motion(
        &mut self,
        index: usize,
        base: Pose,
        target: Option<Pose>,
    ) -> Result<()> {
        self.moving_collider(index)?;
        self.colliders[index].set_motion(base, target);
        Ok(())
    }

    fn moving_collider(&self, index: usize) -> Result<&MovingCollider> {
        self.colliders.get(index).ok_or_else(|| {
            invalid!(
                "collider index {index} is out of range: the solver has {} colliders",
                self.colliders.len()
            )
        })
    }

    /// Simulation time and steps taken.
    pub fn clock(&self) -> Clock {
        self.clock
    }

    /// Sets the clock (restoring a saved simulation).
    pub fn set_clock(&mut self, clock: Clock) {
        self.clock = clock;
    }

    /// Advances `bodies` by one time step. On divergence the bodies keep their state and an
    /// [`Error::Diverged`] names the first non-finite vertex.
    pub fn step(&mut self, bodies: &mut [&mut Membrane]) -> Result<StepStats> {
        match self.pool.take() {
            Some(pool) => {
                let out = pool.install(|| self.step_in_pool(bodies));
                self.pool = Some(pool);
                out
            }
            None => self.step_in_pool(bodies),
        }
    }

    fn step_in_pool(&mut self, bodies: &mut [&mut Membrane]) -> Result<StepStats> {
        let started = Instant::now();
        let params = self.params;
        if !self.system.as_ref().is_some_and(|s| s.matches(bodies)) {
            self.system = Some(System::build(bodies, true)?);
            self.contact = None;
            self.descent = None;
        }
        if params.method == Method::Descent && self.descent.is_none() {
            self.descent = Some(DescentState::new(bodies)?);
        }
        let step_end = self.clock.time + params.dt;
        let colliders: Vec<ColliderModel<T>> = self
            .colliders
            .iter()
            .map(|c| c.during_step(self.clock.time, step_end))
            .collect();
        let sys = self.system.as_mut().expect("built above");
        let h = T::of(params.dt);
        let gravity = Vector3::from(params.gravity).map(T::of);

        for body in bodies.iter_mut() {
            body.sync()?;
        }
        sys.load(bodies);
        if params.contact.is_some() {
            let contact = self
                .contact
                .get_or_insert_with(|| ContactState::new(bodies, sys));
            contact.start_step(bodies, sys);
        }
        predict(sys, h, gravity);
        let mut energy = initial_guess(sys, h, params.preconditioner, &colliders);
        let mut timings = Timings {
            predict: millis(started),
            ..Timings::default()
        };

        let mut stats = StepStats {
            step: self.clock.steps,
            residuals: Vec::with_capacity(params.max_iters.min(4096)),
            error_estimates: Vec::with_capacity(params.max_iters.min(4096)),
            energies: Vec::with_capacity(if params.record_energy {
                params.max_iters.min(4096) + 1
            } else {
                0
            }),
            ..StepStats::default()
        };
        let accelerated = params.acceleration != Acceleration::None;
        if accelerated && sys.y_prev.len() != sys.y.len() {
            sys.y_prev = sys.y.clone();
        }
        let mut search = LineSearch::new(energy);
        let mut omega = 1.0;
        // Iteration at which the Chebyshev sequence (re)started: 0, or after a descent trial
        // was rejected.
        let mut chebyshev_origin = 0;
        for iteration in 0..params.max_iters {
            let t = Instant::now();
            let extrapolation = params
                .acceleration
                .omega(iteration - chebyshev_origin, omega);
            omega = extrapolation.unwrap_or(1.0);
            let contact_reaction = self
                .contact
                .as_ref()
                .map(ContactState::reaction)
                .unwrap_or_default();
            // With contact, the first iterate of a step has not been through a local step: its
            // residual says nothing of the contacts, so it cannot decide convergence.
            let decisive = params.contact.is_none() || !contact_reaction.is_empty();
            let converges =
                |update: &Update| decisive && params.tol > 0.0 && update.residual < params.tol;
            // With contact the extrapolation follows the local step (see
            // [`extrapolate_local_step`]), not the global step.
            let options = MoveOptions {
                step_length: params.step_length,
                inner_iters: params.inner_iters,
                omega: extrapolation
                    .filter(|_| params.contact.is_none())
                    .map(T::of),
                colliders: &colliders,
                contact_reaction,
            };
            let mut update = match params.method {
                Method::Sissm => {
                    if iteration > 0 {
                        let t = Instant::now();
                        evaluate(sys, params.preconditioner);
                        timings.kernel += millis(t);
                        if params.record_energy {
                            energy = total_energy(sys, h);
                        }
                    }
                    if params.record_energy {
                        stats.energies.push(energy);
                    }
                    jacobi_update(sys, h, &options)
                }
                Method::Descent => {
                    if params.record_energy {
                        stats.energies.push(search.energy);
                    }
                    let state = self.descent.as_mut().expect("built above");
                    let update = descent_iteration(
                        sys,
                        state,
                        h,
                        params.preconditioner,
                        &options,
                        &mut search,
                    );
                    if search.restarted {
                        chebyshev_origin = iteration + 1;
                        omega = 1.0;
                    }
                    update
                }
            };
            timings.global += millis(t);
            if params.method == Method::Sissm && !colliders.is_empty() {
                let t = Instant::now();
                let projected = project_colliders(sys, &colliders);
                update = Update {
                    residual: update.residual,
                    ..Update::merge(update, projected)
                };
                update.moved = projected.moved;
                timings.colliders += millis(t);
            }
            if let Some(vertex) = update.first_bad {
                let (body, vertex) = sys.locate(vertex);
                return Err(Error::Diverged {
                    step: self.clock.steps,
                    iteration,
                    body,
                    vertex,
                });
            }
            if let (Some(state), Some(contact_params)) = (self.contact.as_mut(), &params.contact) {
                let (moved, figures) =
                    state.local_step(sys, h, contact_params, params.tol, &colliders);
                update.moved = moved;
                stats.contact.accumulate(&figures);
                // The iteration the step stops at is not extrapolated: it ends on `z`.
                let last = iteration + 1 == params.max_iters || converges(&update);
                if let Some(w) = extrapolation.filter(|_| !last) {
                    extrapolate_local_step(sys, T::of(w), &colliders);
                }
            }
            if accelerated {
                std::mem::swap(&mut sys.y_prev, &mut sys.y);
            }
            std::mem::swap(&mut sys.y, &mut sys.y_next);
            stats.iterations = iteration + 1;
            stats.residuals.push(update.moved);
            stats.error_estimates.push(update.residual);
            if converges(&update) {
                stats.converged = true;
                break;
            }
        }

        if params.record_energy {
            let t = Instant::now();
            let last = match params.method {
                Method::Sissm => {
                    evaluate(sys, params.preconditioner);
                    total_energy(sys, h)
                }
                Method::Descent => search.energy,
            };
            stats.energies.push(last);
            timings.global += millis(t);
        }

        let t = Instant::now();
        finish(sys, h);
        sys.store(bodies);
        timings.finish = millis(t);
        for c in &mut self.colliders {
            c.finish_step(step_end);
        }
        self.clock.tick(params.dt);
        timings.total = millis(started);
        stats.time = self.clock.time;
        stats.timings = timings;
        Ok(stats)
    }
}

/// `y* = y_t + h v_t + h^2 g` for free vertices; the initial iterate is `y*` (Algorithm 1, line 2).
fn predict<T: Real>(sys: &mut System<T>, h: T, gravity: Vector3<T>) {
    let (y_start, velocity, pinned) = (&sys.y_start, &sys.velocity, &sys.pinned);
    let kick = gravity * (h * h);
    sys.y_star.par_iter_mut().enumerate().for_each(|(i, star)| {
        if !pinned[i] {
            *star = y_start[i] + velocity[i] * h + kick;
        }
    });
    sys.y.copy_from_slice(&sys.y_star);
}

/// Starts the iteration from whichever of the inertial prediction `y*` (Algorithm 1, line 2) and
/// the previous positions `y_t` has the lower variational energy, and returns that energy;
/// the responses are left evaluated at the chosen start.
///
/// `y*` is exact in free flight, but for a stiff body it can hold a large elastic energy
/// (a pinned sheet's first row of bonds stretched by `h^2 g`); starting there, a step that runs
/// out of iterations releases that energy as spurious motion. From `y_t` an unfinished step
/// moves too little instead, which dissipates. `E(y*)` is the elastic energy `U(y*)`, and
/// `E(y_t) >= m |y_t - y*|^2 / (2 h^2)`, so `y_t` is evaluated only when `U(y*)` exceeds that
/// inertial term: most dynamic steps cost one kernel pass here, not two.
fn initial_guess<T: Real>(
    sys: &mut System<T>,
    h: T,
    mode: Preconditioner,
    colliders: &[ColliderModel<T>],
) -> f64 {
    keep_feasible(sys, colliders);
    evaluate(sys, mode);
    let at_prediction = total_energy(sys, h);
    let inertia_of_previous = inertial_energy(sys, h, true);
    if at_prediction <= inertia_of_previous {
        return at_prediction;
    }
    let (y_start, y_star, pinned) = (&sys.y_start, &sys.y_star, &sys.pinned);
    sys.y.par_iter_mut().enumerate().for_each(|(i, y)| {
        *y = if pinned[i] { y_star[i] } else { y_start[i] };
    });
    keep_feasible(sys, colliders);
    evaluate(sys, mode);
    let at_previous = total_energy(sys, h);
    if at_previous < at_prediction {
        at_previous
    } else {
        sys.y.copy_from_slice(&sys.y_star);
        keep_feasible(sys, colliders);
        evaluate(sys, mode);
        at_prediction
    }
}

/// Projects the free vertices of the iterate `y` out of the colliders (a start outside every
/// collider, so that the residual there measures a feasible state), on the side of each that
/// the vertex was on at the start of the step (`y_t`, carried by the collider's motion).
fn keep_feasible<T: Real>(sys: &mut System<T>, colliders: &[ColliderModel<T>]) {
    if colliders.is_empty() {
        return;
    }
    let (pinned, rest, start) = (&sys.pinned, &sys.rest, &sys.y_start);
    sys.y.par_iter_mut().enumerate().for_each(|(k, y)| {
        if !pinned[k] {
            let from = MoveStart::OfStep(start[k]);
            *y = push_out_of_colliders(colliders, from, *y, rest.vertices[k].half_thickness, None);
        }
    });
}

/// Projects the free vertices of `y_next` out of the colliders and measures the move from `y`.
fn project_colliders<T: Real>(sys: &mut System<T>, colliders: &[ColliderModel<T>]) -> Update {
    let (y, pinned, rest) = (&sys.y, &sys.pinned, &sys.rest);
    sys.y_next
        .par_iter_mut()
        .enumerate()
        .map(|(k, next)| {
            if !pinned[k] {
                let (from, margin) = (MoveStart::Now(y[k]), rest.vertices[k].half_thickness);
                *next = push_out_of_colliders(colliders, from, *next, margin, None);
            }
            Update::of(k, &y[k], next)
        })
        .reduce(|| Update::NONE, Update::merge)
}

/// Chebyshev's extrapolation with contact: `y^{k+1} = w (z - y^{k-1}) + y^{k-1}` on the local
/// step's result `z` (in `y_next`; `y^{k-1}` in `y_prev`), so that it extrapolates the whole
/// iteration, global and local step, as the semi-iterative method asks. The extrapolated
/// iterate is only where the next global step evaluates the forces: the local step keeps its
/// own safe positions (`z`, intersection-free) and runs its CCD from them, and the solver
/// does not extrapolate the iteration it stops at, so every step still ends on a local step's
/// result. A vertex that the extrapolation could take into a collider (its signed distance at
/// `z`, beyond its half thickness, no more than the extrapolation's move) keeps `z`: the global
/// step's collider projection starts from outside, and friction does not see an extrapolated
/// slide.
fn extrapolate_local_step<T: Real>(sys: &mut System<T>, w: T, colliders: &[ColliderModel<T>]) {
    let (y_prev, pinned, rest) = (&sys.y_prev, &sys.pinned, &sys.rest);
    sys.y_next.par_iter_mut().enumerate().for_each(|(k, z)| {
        if !pinned[k] {
            let margin = rest.vertices[k].half_thickness;
            *z = extrapolated(z, &y_prev[k], w, margin, colliders);
        }
    });
}

/// One vertex of [`extrapolate_local_step`]: `w (z - previous) + previous`, or `z` where
/// that move could reach into a collider (within `margin`, m, of its surface).
pub(super) fn extrapolated<T: Real>(
    z: &Vector3<T>,
    previous: &Vector3<T>,
    w: T,
    margin: T,
    colliders: &[ColliderModel<T>],
) -> Vector3<T> {
    let moved = (z - previous) * w + previous;
    let reach = (moved - z).norm() + margin;
    if colliders.iter().all(|c| c.signed_distance(z) > reach) {
        moved
    } else {
        *z
    }
}

/// `v_{t+1} = (y_{t+1} - y_t) / h`, `y_t <- y_{t+1}`.
fn finish<T: Real>(sys: &mut System<T>, h: T) {
    let inv_h = T::one() / h;
    let y = &sys.y;
    sys.velocity
        .par_iter_mut()
        .zip(sys.y_start.par_iter_mut())
        .enumerate()
        .for_each(|(i, (v, start))| {
            *v = (y[i] - *start) * inv_h;
            *start = y[i];
        });
}
