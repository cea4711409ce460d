//! The SISSM time step on the GPU: the algorithm of [`crate::solve::Solver`] (f32 or f64), with the
//! rest data, the iterates and the per-bond scratch resident on the device.
//!
//! Per step the host uploads whatever of the bodies' positions, velocities and pins Python
//! changed since the last step (nothing, usually), records every iteration's commands,
//! and reads back the small control header every [`CHECK_EVERY`] iterations: the convergence
//! test (`max_i |r_i| / m_i < tol`) and the divergence test run on the device, which sets a
//! stopping point that turns every later command of the step into a no-op. The iterations are
//! thus exactly those of the CPU solver, and the device never waits for the host inside a
//! batch. At the end of the step only the per-iteration history is read back: the new
//! positions and velocities stay on the device, and each body reads its own back when
//! something asks for them ([`crate::membrane::Membrane::sync`], which the Python layer calls before every
//! access to a body's state, and which this solver calls for bodies another solver stepped).

use std::time::Instant;

use nalgebra::Vector3;

use crate::collider::{Collider, ColliderModel, MovingCollider, Shape};
use crate::error::{invalid, Divergence, Error, Result};
use crate::solve::body::ByKind;
use crate::solve::points::step_speed;
use crate::solve::BodyMut;
use crate::solve::{Acceleration, Clock, Method, SolverParams, StepStats, Timings};
use crate::timing::millis;

use super::device::GpuContext;
use super::layout::{GpuReal, IterValues};
use super::pass::{RECORD_FINAL, RECORD_FIRST_ITERATION};
use super::pipelines::Pipelines;
use super::working_set::State;

/// Iterations recorded between two reads of the control header.
pub const CHECK_EVERY: usize = 8;

/// Steps a set of membranes in time on the GPU, in `T` (f32 on every adapter, f64 where
/// the adapter has SHADER_F64).
///
/// [`StepStats::timings`] are host wall-clock times: `predict` the upload, `global` the
/// initial guess and the iterations (colliders included; `colliders` stays 0), `finish` the
/// velocity update and the read-back of the history (positions and velocities stay on the
/// device until a body is synced).
pub struct GpuSolver<T: GpuReal> {
    params: SolverParams,
    colliders: Vec<Collider>,
    ctx: GpuContext,
    pipelines: Pipelines,
    state: Option<State<T>>,
    clock: Clock,
}

impl<T: GpuReal> GpuSolver<T> {
    /// A solver on the adapter [`super::gpu_info`] describes; fails with [`Error::Gpu`] when
    /// there is none (or it lacks f64 for `T = f64`), and builds every pipeline now, so a
    /// broken driver fails here.
    pub fn new(params: SolverParams) -> Result<Self> {
        Self::check_supported(&params)?;
        let ctx = GpuContext::new(T::FEATURES)?;
        let pipelines = Pipelines::new::<T>(&ctx);
        ctx.wait()?;
        ctx.check()?;
        Ok(Self {
            params,
            colliders: Vec::new(),
            ctx,
            pipelines,
            state: None,
            clock: Clock::default(),
        })
    }

    pub fn params(&self) -> &SolverParams {
        &self.params
    }

    /// Validates parameters and refuses what the GPU kernels do not implement (yet): contact,
    /// the descent baseline and inner Jacobi sweeps.
    fn check_supported(params: &SolverParams) -> Result<()> {
        params.validate()?;
        if params.contact.is_some() {
            return Err(invalid!("the GPU backend has no contact between membranes yet; use backend='cpu' for contact"));
        }
        if !matches!(params.method, Method::Sissm | Method::Auto) || params.inner_iters != 1 {
            return Err(invalid!(
                "the GPU backend runs method='sissm' with inner_iters=1; got method={:?}, inner_iters={}",
                params.method,
                params.inner_iters
            ));
        }
        Ok(())
    }

    /// Replaces the parameters (validated).
    pub fn set_params(&mut self, params: SolverParams) -> Result<()> {
        Self::check_supported(&params)?;
        self.params = params;
        Ok(())
    }

    /// Adds a collider (any shape, friction and motion, as on the CPU).
    pub fn add_collider(&mut self, collider: Collider) -> Result<()> {
        if let Shape::Mesh(grid) = &collider.shape {
            return Err(invalid!(
                "the GPU backend does not support MeshCollider ({grid:?}); use backend='cpu'"
            ));
        }
        self.colliders.push(collider);
        Ok(())
    }

    pub fn colliders(&self) -> &[Collider] {
        &self.colliders
    }

    /// Simulation time and steps taken.
    pub fn clock(&self) -> Clock {
        self.clock
    }

    /// Sets the clock (restoring a saved simulation).
    pub fn set_clock(&mut self, clock: Clock) {
        self.clock = clock;
    }

    /// Bytes the kernels of one global iteration load and store for the bodies of the last
    /// step (None before the first step), counting every load a kernel issues (a cache may
    /// serve repeats). In f32, with `n` vertices and `b` bonds,
    ///
    /// - vertex kernel: per vertex 144 (position, rest constants, offsets, response), per bond
    ///   100 without and 248 with bending/hourglass (neighbour position and bond rest data
    ///   read in every pass, the gradient written, re-read and updated);
    /// - Jacobi update: per vertex 176 (+16 with Chebyshev), per bond 72 (both gradients of
    ///   the bond, the reverse index, the neighbour's response);
    /// - colliders, the convergence and divergence measure and the commit: per vertex
    ///   64 + 16 + 16 (`y_t` for the speed limit) + 32 (+32 with Chebyshev); with `record_energy` another 68.
    ///
    /// f64 doubles the count (index loads, a few percent of it, are counted twice too).
    pub fn bytes_per_iteration(&self) -> Option<u64> {
        let state = self.state.as_ref()?;
        let (n, b) = (state.n as u64, state.bonds);
        let non_affine = state
            .system
            .rest
            .vertices
            .iter()
            .any(|c| c.kappa_t > T::zero() || c.kappa_n > T::zero());
        let accelerated = self.params.acceleration != Acceleration::None;
        let kernel = 144 * n + if non_affine { 248 } else { 100 } * b;
        let jacobi = (176 + if accelerated { 16 } else { 0 }) * n + 72 * b;
        let rest = (64 + 16 + 16 + 32 + if accelerated { 32 } else { 0 }) * n;
        let energy = if self.params.record_energy { 68 * n } else { 0 };
        let scale = std::mem::size_of::<T>() as u64 / 4;
        Some((kernel + jacobi + rest + energy) * scale)
    }

    /// Advances `bodies` by one time step. On divergence the bodies keep their state and an
    /// [`Error::Diverged`] names the first vertex whose iterate is not finite or, unless
    /// pinned, moved from `y_t` faster than [`SolverParams::max_speed`] (the body by its index
    /// in `bodies`). The kernels test every iterate, not only the last as the CPU does: an
    /// iterate that far from `y_t` is already a blow-up, and the step stops there. The GPU steps membranes only: a particle body is refused, by its index.
    pub fn step(&mut self, bodies: &mut [BodyMut<'_>]) -> Result<StepStats> {
        let started = Instant::now();
        let mut by_kind = ByKind::sort(bodies);
        if let Some(&body) = by_kind.particle_indices.first() {
            return Err(crate::error::invalid!(
                "the GPU backend steps membranes only; body {body} is a particle body \
                 (use backend='cpu')"
            ));
        }
        let (bodies, list_indices) = (&mut by_kind.membranes[..], &by_kind.membrane_indices);
        let params = self.params;
        let records = params.max_iters + RECORD_FIRST_ITERATION;
        let rebuild = match &self.state {
            None => true,
            Some(s) => {
                !s.system.points.matches(bodies)
                    || s.iter_capacity < records
                    || s.collider_capacity < self.colliders.len().max(1)
            }
        };
        if rebuild {
            // read back what the old buffers hold before they go
            for body in bodies.iter_mut() {
                body.sync()?;
            }
            self.state = None;
            self.state = Some(State::build(
                &self.ctx,
                &self.pipelines,
                bodies,
                records,
                self.colliders.len().max(1),
            )?);
        }
        let step_end = self.clock.time + params.dt;
        let colliders: Vec<ColliderModel<T>> = self
            .colliders
            .iter()
            .map(|c| MovingCollider::new(c.clone()).during_step(self.clock.time, step_end))
            .collect();
        let state = self.state.as_mut().expect("built above");
        state.upload(&self.ctx, bodies, &params, &colliders)?;
        let mut timings = Timings {
            predict: millis(started),
            ..Timings::default()
        };
        let mut stats = StepStats {
            step: self.clock.steps,
            ..StepStats::default()
        };

        let t = Instant::now();
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = state.pass(&mut encoder, &self.pipelines);
            pass.initial_guess();
        }
        let mut iterations = 0;
        let mut limit = u32::MAX;
        while iterations < params.max_iters && limit == u32::MAX {
            let batch = CHECK_EVERY.min(params.max_iters - iterations);
            {
                let mut pass = state.pass(&mut encoder, &self.pipelines);
                for k in iterations..iterations + batch {
                    pass.iteration(k, params.record_energy);
                }
            }
            iterations += batch;
            let header = state.read_header(&self.ctx, encoder)?;
            limit = header[0];
            if limit != u32::MAX && header[1] != u32::MAX {
                let point = header[1] as usize;
                let (y, y_start) = state.read_move(&self.ctx, point)?;
                let (body, vertex) = state.system.points.locate(point);
                return Err(Error::Diverged {
                    step: self.clock.steps,
                    iteration: header[2] as usize,
                    body: list_indices[body],
                    vertex,
                    cause: cause_of(&y, &y_start, &params),
                });
            }
            encoder = self.ctx.device.create_command_encoder(&Default::default());
        }
        if limit != u32::MAX {
            iterations = limit as usize;
            stats.converged = true;
        }
        stats.iterations = iterations;
        timings.global = millis(t);

        let t = Instant::now();
        if params.record_energy {
            state.write_record(
                &self.ctx,
                RECORD_FINAL,
                &IterValues {
                    slot: 1 + iterations as u32,
                    lane: 2,
                    ..IterValues::default()
                },
            );
        }
        {
            let mut pass = state.pass(&mut encoder, &self.pipelines);
            if params.record_energy {
                pass.energy(RECORD_FINAL, true);
            }
            pass.finish();
        }
        let history = state.finish_step(&self.ctx, encoder, bodies, params.max_iters)?;
        for k in 0..iterations {
            let [moved, residual, _, _] = history[1 + k];
            stats.moves.push(moved.to_f64());
            stats.residuals.push(residual.to_f64());
        }
        if params.record_energy {
            let [previous, prediction, _, _] = history[0];
            stats.energies.push(if previous < prediction {
                previous.to_f64()
            } else {
                prediction.to_f64()
            });
            stats
                .energies
                .extend((1..=iterations).map(|k| history[1 + k][2].to_f64()));
        }
        timings.finish = millis(t);
        self.clock.tick(params.dt);
        timings.total = millis(started);
        stats.time = self.clock.time;
        stats.timings = timings;
        Ok(stats)
    }
}

/// Why the kernels flagged a vertex that moved from `y_start` to `y` (m): a velocity that is
/// not finite in `T` (the kernels compute it in `T`), else a speed above `max_speed`.
fn cause_of<T: GpuReal>(y: &Vector3<T>, y_start: &Vector3<T>, params: &SolverParams) -> Divergence {
    let speed = step_speed(y, y_start, 1.0 / params.dt);
    if T::of(speed).to_f64().is_finite() {
        Divergence::TooFast {
            speed,
            limit: params.max_speed,
        }
    } else {
        Divergence::NonFinite
    }
}
