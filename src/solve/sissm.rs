//! The SISSM time step (Lu et al. 2023, Algorithm 1 without the contact local step), and the
//! loop that the descent and Newton methods share with it.
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
//! The iteration starts from the lower-energy of `y*` and `y_t` (and, for particles sliding on
//! a collider, `y_t + h v_t`: [`initial_guess`]) and stops
//! when `max_i |r_i| / m_i < tol` for the residual `r = m (y* - y) + h^2 f` (without the
//! reactions of the colliders and of the membrane contacts the vertex is in, see
//! [`super::membranes::jacobi::free_residual`]; with contact, not before the first local step). Where the energy is convex its Hessian `H` satisfies
//! `H >= M`, so the error `e = H^-1 r` obeys `|e|_M <= |r|_(M^-1)`: the test bounds the
//! mass-weighted RMS distance to the exact implicit Euler solution. Algorithm 1 tests the last
//! move `max_i |y_i^{k+1} - y_i^k|` instead, which declares slowly converging (stiff, fine)
//! problems solved far from their solution; that move is still reported as the residual history.

use std::time::Instant;

use nalgebra::Vector3;

use crate::collider::{Collider, ColliderModel, MovingCollider, Pose};
use crate::error::{invalid, Divergence, Error, Result};
use crate::real::Real;

use super::body::{BodyMut, ByKind};
use super::collider_passes::{extrapolate_local_step, push_next_out_of_colliders};
use super::coupling::ClothCoupling;
use super::families::Families;
use super::initial_guess::initial_guess;
use super::membranes::auto;
use super::membranes::contact_step::ContactState;
use super::membranes::descent::{descent_iteration, DescentState, LineSearch};
use super::membranes::newton::{newton_iteration, start_iteration, NewtonState};
use super::particles::ParticleSystem;
use super::update::{MoveOptions, Update};
use super::{Acceleration, Clock, Method, SolverParams, SolverState, StepStats, Timings};
use crate::timing::millis;

/// Steps a set of membranes in time.
pub struct Solver<T: Real> {
    params: SolverParams,
    colliders: Vec<MovingCollider>,
    pool: Option<rayon::ThreadPool>,
    /// The families of the current body list (built on the first step with it).
    families: Option<Families<T>>,
    /// Contact topology of the current body list (built on the first step with contact).
    contact: Option<ContactState<T>>,
    /// Particles against membrane triangles, when the body list has both (built with the
    /// families).
    coupling: Option<ClothCoupling<T>>,
    /// The descent method's working set (built on the first descent step).
    descent: Option<DescentState>,
    /// The Newton method's working set (built on the first Newton step).
    newton: Option<NewtonState<T>>,
    /// A state given to [`Self::restore_state`], or the one a failed step started from,
    /// taken by the next step.
    restored: Option<SolverState>,
    /// Whether `restored` is a failed step's start, which a change of the body list drops
    /// (as it drops the state a step leaves), where a restored one is checked against it.
    rolled_back: bool,
    clock: Clock,
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
            families: None,
            contact: None,
            coupling: None,
            descent: None,
            newton: None,
            restored: None,
            rolled_back: false,
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

    /// The particle family's working set, once a step built it (tests reach its solvers).
    #[cfg(test)]
    pub(crate) fn particle_system(&mut self) -> Option<&mut super::particles::ParticleSystem<T>> {
        self.families.as_mut()?.particles.as_mut()
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

    /// The state the next steps depend on beyond the bodies, the clock and the colliders'
    /// motion (see [`SolverState`]), `revisions` each particle body's
    /// [`crate::particles::Particles::positions_revision`] (in the order of the bodies): the
    /// grain contacts of a body whose positions were replaced since the last step are left
    /// out, as the next step drops them.
    pub fn saved_state(&self, revisions: &[u64]) -> SolverState {
        let particles = self.families.as_ref().and_then(|f| f.particles.as_ref());
        let mut state = match &self.restored {
            Some(restored) => restored.clone(),
            None => carried_state(None, self.contact.as_ref(), particles),
        };
        if let Some(particles) = particles {
            particles.forget_replaced(revisions, &mut state.grain_contacts);
        }
        state
    }

    /// Restores a state read with [`Self::saved_state`] (from a solver set up the same way),
    /// replacing this solver's own; the next step takes it, after checking it against its
    /// bodies (see [`SolverState::check_against`]).
    pub fn restore_state(&mut self, state: SolverState) -> Result<()> {
        state.validate()?;
        self.restored = Some(state);
        self.rolled_back = false;
        Ok(())
    }

    /// The membranes' system and the contact state as the last step left them, for the tests
    /// of a step's first-order conditions.
    #[cfg(test)]
    pub(crate) fn membranes_and_contact(
        &mut self,
    ) -> (
        Option<&mut super::membranes::MembraneSystem<T>>,
        Option<&ContactState<T>>,
    ) {
        (
            self.families.as_mut().and_then(|f| f.membranes.as_mut()),
            self.contact.as_ref(),
        )
    }

    /// Advances `bodies` by one time step. On divergence the bodies keep their state and an
    /// [`Error::Diverged`] names the first non-finite point, or the first one faster than
    /// [`SolverParams::max_speed`] (the body by its index in `bodies`).
    pub fn step(&mut self, bodies: &mut [BodyMut<'_>]) -> Result<StepStats> {
        match self.pool.take() {
            Some(pool) => {
                let out = pool.install(|| self.step_in_pool(bodies));
                self.pool = Some(pool);
                out
            }
            None => self.step_in_pool(bodies),
        }
    }

    /// [`Self::step`] in the pool. A step that fails (a divergence, bad input found on the
    /// way) leaves the bodies as they were and hands the next step the state this one started
    /// from, as a restore would ([`Self::restore_state`]): the contact warm start and rest
    /// gaps and the grains' friction multipliers, which the step changes as it goes.
    fn step_in_pool(&mut self, bodies: &mut [BodyMut<'_>]) -> Result<StepStats> {
        // A restore given from outside stays one; a failed step's start is the solver's own.
        let own = self.restored.is_none() || self.rolled_back;
        if let Some(newton) = &mut self.newton {
            newton.begin_step();
        }
        let mut start = None;
        let stepped = self.advance(bodies, &mut start);
        if let (Err(_), Some(newton)) = (&stepped, &mut self.newton) {
            newton.roll_back();
        }
        match (&stepped, start) {
            (Ok(_), _) => {
                if let Some(families) = &mut self.families {
                    families.settle();
                }
            }
            (Err(_), Some(start)) => {
                self.restored = Some(start);
                self.rolled_back = own;
            }
            (Err(_), None) => {}
        }
        stepped
    }

    /// One step. Sets `start` to the state it starts from ([`Self::saved_state`], the grain
    /// contacts of a body whose positions were replaced forgotten) before it changes any.
    fn advance(
        &mut self,
        bodies: &mut [BodyMut<'_>],
        start: &mut Option<SolverState>,
    ) -> Result<StepStats> {
        let started = Instant::now();
        let mut params = self.params;
        let mut by_kind = ByKind::sort(bodies);
        if !self.families.as_ref().is_some_and(|f| f.matches(&by_kind)) {
            let mut families = Families::build(&by_kind, true)?;
            // A failed step's start is the same bodies' (a working set left stale, bonds
            // given from outside, keep it); another body list drops it, as it drops the
            // state a step leaves.
            match self.families.as_ref().filter(|old| old.hold(&by_kind)) {
                Some(old) => families.keep_placements(old),
                None if self.rolled_back => {
                    self.restored = None;
                    self.rolled_back = false;
                }
                None => {}
            }
            self.coupling = ClothCoupling::of(&by_kind.membranes, &families);
            self.families = Some(families);
            self.contact = None;
            self.descent = None;
            self.newton = None;
        }
        // A restored state (checked before anything changes), applied once the contact state
        // is there.
        let vertices = by_kind
            .membranes
            .iter()
            .map(|m| m.num_vertices())
            .sum::<usize>();
        let particles = by_kind
            .particles
            .iter()
            .map(|p| p.num_particles())
            .sum::<usize>();
        if let Some(restored) = &self.restored {
            restored.check_against(vertices, particles)?;
            self.families
                .as_ref()
                .expect("built above")
                .check_restored(restored)?;
            // The contact state restarts from what was restored (its caches are rebuilt).
            self.contact = None;
        }
        if params.method == Method::Auto && !by_kind.particle_indices.is_empty() {
            params.method = Method::Sissm;
        }
        if !matches!(params.method, Method::Sissm | Method::Auto) {
            if let Some(&body) = by_kind.particle_indices.first() {
                let method = if params.method == Method::Descent {
                    "descent"
                } else {
                    "newton"
                };
                return Err(invalid!(
                    "method='{method}' steps membranes only; body {body} is a particle body \
                     (use method='sissm')"
                ));
            }
        }
        if params.method == Method::Descent && self.descent.is_none() {
            self.descent = Some(DescentState::new(&by_kind.membranes)?);
        }
        if params.method == Method::Newton && self.newton.is_none() {
            self.newton = Some(NewtonState::new(&by_kind.membranes)?);
        }
        let step_end = self.clock.time + params.dt;
        let colliders: Vec<ColliderModel<T>> = self
            .colliders
            .iter()
            .map(|c| c.during_step(self.clock.time, step_end))
            .collect();
        let families = self.families.as_mut().expect("built above");
        let h = T::of(params.dt);
        let gravity = Vector3::from(params.gravity).map(T::of);

        by_kind.sync()?;
        if let Some(restored) = &self.restored {
            families.restore(restored);
        }
        families.load(&by_kind)?;
        // Each family's colliders in its frame (a particle family's origin near its bodies,
        // docs/architecture.md "Particle frame"); a family in the world frame keeps the world
        // models of `colliders` bit for bit.
        let framed: Vec<Vec<ColliderModel<T>>> = families
            .each()
            .map(|family| {
                let origin = family.points().origin;
                if origin == Vector3::zeros() {
                    return colliders.clone();
                }
                self.colliders
                    .iter()
                    .map(|c| c.during_step_in_frame(self.clock.time, step_end, &origin))
                    .collect()
            })
            .collect();
        let restored = self.restored.take();
        self.rolled_back = false;
        *start = Some(carried_state(
            restored.as_ref(),
            self.contact.as_ref(),
            families.particles.as_ref(),
        ));
        if let (Some(sys), true) = (families.membranes.as_mut(), params.contact.is_some()) {
            let contact = self
                .contact
                .get_or_insert_with(|| ContactState::new(&by_kind.membranes, sys));
            if let Some(gaps) = restored.as_ref().and_then(|r| r.contact_rest_gaps.as_ref()) {
                contact.set_rest_gaps(gaps);
            }
            contact.start_step(&by_kind.membranes, sys);
        }
        if let (Some(restored), Some(contact)) = (restored, &mut self.contact) {
            contact.set_warm_start(&restored.contact_warm_start);
        }
        let list_indices = by_kind.list_indices();
        for (family, indices) in families.each().zip(&list_indices) {
            let points = family.points();
            if let Some(point) = points.first_unbounded_move(params.dt, params.gravity.into()) {
                let (body, vertex) = points.locate(point);
                return Err(Error::Diverged {
                    step: self.clock.steps,
                    iteration: 0,
                    body: indices[body],
                    vertex,
                    cause: Divergence::UnboundedMove,
                });
            }
        }
        let mut energy = 0.0;
        let mut timed_elsewhere = 0.0;
        for (family, colliders) in families.each().zip(&framed) {
            family.start_step(&params)?;
            timed_elsewhere += family.start_millis_timed_elsewhere();
            family.points_mut().predict(h, gravity);
            energy += initial_guess(family, h, params.preconditioner, colliders);
        }
        if let Some(coupling) = &mut self.coupling {
            coupling.start_step(families);
        }
        if params.method == Method::Auto {
            params.method = families
                .membranes
                .as_ref()
                .map_or(Method::Sissm, |sys| auto::choose(sys, h * h, params.tol));
            if params.method == Method::Newton {
                params.acceleration = Acceleration::None;
                if self.newton.is_none() {
                    self.newton = Some(NewtonState::new(&by_kind.membranes)?);
                }
            }
        }
        let mut timings = Timings {
            predict: (millis(started) - timed_elsewhere).max(0.0),
            ..Timings::default()
        };

        let mut stats = StepStats {
            step: self.clock.steps,
            moves: Vec::with_capacity(params.max_iters.min(4096)),
            residuals: Vec::with_capacity(params.max_iters.min(4096)),
            energies: Vec::with_capacity(if params.record_energy {
                params.max_iters.min(4096) + 1
            } else {
                0
            }),
            ..StepStats::default()
        };
        // Per family (in the order of `Families::each`): its acceleration and the last
        // extrapolation weight.
        let accelerations: Vec<Acceleration> =
            families.each().map(|f| f.acceleration(&params)).collect();
        for (family, acceleration) in families.each().zip(&accelerations) {
            let points = family.points_mut();
            if *acceleration != Acceleration::None && points.y_prev.len() != points.y.len() {
                points.y_prev = points.y.clone();
            }
        }
        // Per family, the threshold its convergence measure must fall below.
        let thresholds: Vec<f64> = families.each().map(|f| f.threshold(&params)).collect();
        let mut omegas = vec![1.0; accelerations.len()];
        let mut updates = Vec::with_capacity(list_indices.len());
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
            // The membrane contact reactions.
            let contact_reaction = self
                .contact
                .as_ref()
                .map(ContactState::reaction)
                .unwrap_or_default();
            // With contact, the first iterate of a step has not been through a local step: its
            // residual says nothing of the contacts, so it cannot decide convergence.
            let decisive = (params.contact.is_none()
                || self.contact.is_none()
                || !contact_reaction.is_empty())
                && self.coupling.as_ref().is_none_or(ClothCoupling::ran);
            let converges = |updates: &[Update]| {
                decisive
                    && params.tol > 0.0
                    && updates
                        .iter()
                        .zip(&thresholds)
                        .all(|(u, t)| u.residual < *t)
            };
            // Each family's extrapolation weight this iteration.
            let family_omegas: Vec<Option<f64>> = accelerations
                .iter()
                .zip(&mut omegas)
                .map(|(a, previous)| {
                    let w = a.omega(iteration - chebyshev_origin, *previous);
                    *previous = w.unwrap_or(1.0);
                    w
                })
                .collect();
            // With contact the extrapolation follows the local step (see
            // [`extrapolate_local_step`]), not the global step.
            // Family `k`'s options ([`Families::each`] order: the membranes are 0).
            let options = |contact_reaction, omega: Option<f64>, k: usize| MoveOptions {
                step_length: params.step_length,
                inner_iters: params.inner_iters,
                omega: omega.filter(|_| params.contact.is_none()).map(T::of),
                colliders: &framed[k],
                contact_reaction,
                global_solver: params.global_solver,
            };
            updates.clear();
            match params.method {
                Method::Sissm | Method::Auto => {
                    if iteration > 0 {
                        let t = Instant::now();
                        for family in families.each() {
                            family.evaluate(params.preconditioner);
                        }
                        timings.kernel += millis(t);
                        if params.record_energy {
                            energy = families.each().map(|f| f.total_energy(h)).sum();
                        }
                    }
                    if params.record_energy {
                        stats.energies.push(energy);
                    }
                    // Per family, the reactions its residual is measured with.
                    let reactions = match &mut self.coupling {
                        Some(coupling) => coupling.reactions(contact_reaction),
                        None => [contact_reaction; 2],
                    };
                    for (k, ((family, w), reaction)) in families
                        .each()
                        .zip(&family_omegas)
                        .zip(reactions)
                        .enumerate()
                    {
                        updates.push(family.global_move(h, &options(reaction, *w, k)));
                    }
                }
                Method::Descent => {
                    if params.record_energy {
                        stats.energies.push(search.energy);
                    }
                    let state = self.descent.as_mut().expect("built above");
                    if let Some(sys) = families.membranes.as_mut() {
                        updates.push(descent_iteration(
                            sys,
                            state,
                            h,
                            params.preconditioner,
                            &options(contact_reaction, extrapolation, 0),
                            &mut search,
                        ));
                    }
                    if search.restarted {
                        chebyshev_origin = iteration + 1;
                        omega = 1.0;
                        omegas.fill(1.0);
                    }
                }
                Method::Newton => {
                    let state = self.newton.as_mut().expect("built above");
                    if let Some(sys) = families.membranes.as_mut() {
                        let options = options(contact_reaction, None, 0);
                        start_iteration(sys, h, params.preconditioner, &options, &mut search);
                        if params.record_energy {
                            stats.energies.push(search.energy);
                        }
                        let before = state.products;
                        updates.push(newton_iteration(
                            sys,
                            state,
                            h,
                            params.preconditioner,
                            &options,
                            &mut search,
                        ));
                        stats.linear_products += state.products - before;
                        stats.newton.accumulate(&std::mem::take(&mut state.timings));
                    }
                }
            };
            timings.global += millis(t);
            if matches!(params.method, Method::Sissm | Method::Auto) && !colliders.is_empty() {
                let t = Instant::now();
                for ((family, update), colliders) in
                    families.each().zip(updates.iter_mut()).zip(&framed)
                {
                    if family.keeps_out_of_colliders() {
                        continue;
                    }
                    let projected = push_next_out_of_colliders(family.points_mut(), colliders);
                    *update = Update {
                        residual: update.residual,
                        ..Update::merge(*update, projected)
                    };
                    update.moved = projected.moved;
                }
                timings.colliders += millis(t);
            }
            for ((family, update), indices) in families.each().zip(&updates).zip(&list_indices) {
                if let Some(point) = update.first_bad {
                    let (body, vertex) = family.points().locate(point);
                    return Err(Error::Diverged {
                        step: self.clock.steps,
                        iteration,
                        body: indices[body],
                        vertex,
                        cause: Divergence::NonFinite,
                    });
                }
            }
            if let Some(coupling) = &mut self.coupling {
                let moved = coupling.iterate(families, h);
                for update in &mut updates {
                    update.moved = update.moved.max(moved);
                }
            }
            let mut update = updates.iter().copied().fold(Update::NONE, Update::merge);
            if let (Some(state), Some(contact_params), Some(sys)) = (
                self.contact.as_mut(),
                &params.contact,
                families.membranes.as_mut(),
            ) {
                // Newton's line search leaves the responses at its trial: the local step's
                // metric is taken at the iterate instead, as SISSM's is.
                let blocks = self
                    .newton
                    .as_ref()
                    .filter(|_| params.method == Method::Newton)
                    .map(NewtonState::metric);
                let t = Instant::now();
                let (moved, figures) =
                    state.local_step(sys, h, contact_params, params.tol, &colliders, blocks);
                timings.contact += millis(t);
                updates[0].moved = moved;
                update = updates.iter().copied().fold(Update::NONE, Update::merge);
                stats.contact.accumulate(&figures);
                // The iteration the step stops at is not extrapolated: it ends on `z`.
                let last = iteration + 1 == params.max_iters || converges(&updates);
                if let Some(w) = extrapolation.filter(|_| !last) {
                    for (family, colliders) in families.each().zip(&framed) {
                        extrapolate_local_step(family.points_mut(), T::of(w), colliders);
                    }
                }
            }
            for (family, acceleration) in families.each().zip(&accelerations) {
                let points = family.points_mut();
                if *acceleration != Acceleration::None {
                    std::mem::swap(&mut points.y_prev, &mut points.y);
                }
                std::mem::swap(&mut points.y, &mut points.y_next);
            }
            stats.iterations = iteration + 1;
            stats.moves.push(update.moved);
            stats.residuals.push(update.residual);
            if converges(&updates) {
                stats.converged = true;
                break;
            }
        }

        if params.record_energy {
            let t = Instant::now();
            let last = match params.method {
                Method::Sissm | Method::Auto => families
                    .each()
                    .map(|f| {
                        f.evaluate(params.preconditioner);
                        f.total_energy(h)
                    })
                    .sum(),
                Method::Descent | Method::Newton => search.energy,
            };
            stats.energies.push(last);
            timings.global += millis(t);
        }

        for (family, colliders) in families.each().zip(&framed) {
            family.project(h, colliders, &mut timings)?;
        }
        if let Some(coupling) = &mut self.coupling {
            coupling.finish(families, h);
            timings.coupling = coupling.millis;
        }
        let t = Instant::now();
        for (family, indices) in families.each().zip(&list_indices) {
            if let Some((point, speed)) = family.points().first_bad_velocity(h, params.max_speed) {
                let (body, vertex) = family.points().locate(point);
                return Err(Error::Diverged {
                    step: self.clock.steps,
                    iteration: stats.iterations,
                    body: indices[body],
                    vertex,
                    cause: if speed.is_finite() {
                        Divergence::TooFast {
                            speed,
                            limit: params.max_speed,
                        }
                    } else {
                        Divergence::NonFinite
                    },
                });
            }
        }
        for family in families.each() {
            family.points_mut().finish(h);
            family.end_step(&mut timings)?;
            family.report(&mut stats);
        }
        families.store(&mut by_kind);
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

/// The state a solver carries to its next step ([`SolverState`]): the contact warm start and
/// rest gaps of `restored` when given (a restore the contact state has not taken yet), else
/// of `contact`; the grains' friction multipliers of the particle family `particles`.
fn carried_state<T: Real>(
    restored: Option<&SolverState>,
    contact: Option<&ContactState<T>>,
    particles: Option<&ParticleSystem<T>>,
) -> SolverState {
    let (contact_warm_start, contact_rest_gaps) = match restored {
        Some(r) => (r.contact_warm_start.clone(), r.contact_rest_gaps.clone()),
        None => (
            contact.map(|c| c.warm_start().to_vec()).unwrap_or_default(),
            contact.and_then(|c| c.rest_gaps()),
        ),
    };
    SolverState {
        contact_warm_start,
        contact_rest_gaps,
        grain_contacts: particles.map_or_else(Vec::new, |p| p.saved_friction()),
    }
}

/// A piece of the state a [`Solver`] carries from one step to the next, for the tests that
/// tell the caches from the state that results depend on ([`Solver::forget`]).
#[cfg(test)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Forget {
    /// The families' working sets (with the Chebyshev history `y_prev`), and the contact
    /// state and descent working set built with them (the saved state kept).
    Families,
    /// The contact state, the local step's workspace with it (the saved state kept).
    Contact,
    /// The descent method's working set.
    Descent,
    /// One piece of the local step's workspace.
    Workspace(crate::contact::local_step::Piece),
}

#[cfg(test)]
impl<T: Real> Solver<T> {
    /// Drops `what` as if this solver had never held it.
    pub(crate) fn forget(&mut self, what: Forget) {
        // Dropping the contact state drops the warm start with it: that is saved state, handed
        // back as a restore would.
        let saved = self.saved_state(&[]);
        match what {
            Forget::Families => {
                self.families = None;
                self.contact = None;
                self.coupling = None;
                self.descent = None;
                self.newton = None;
                self.restored = Some(saved);
            }
            Forget::Contact => {
                self.contact = None;
                self.restored = Some(saved);
            }
            Forget::Descent => self.descent = None,
            Forget::Workspace(piece) => {
                if let Some(contact) = &mut self.contact {
                    contact.work_mut().forget(piece);
                }
            }
        }
    }
}
