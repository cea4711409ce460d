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
//! something asks for them ([`Membrane::sync`], which the Python layer calls before every
//! access to a body's state, and which this solver calls for bodies another solver stepped).

use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Instant;

use nalgebra::Vector3;

use crate::contact::{Collider, ColliderModel, MovingCollider, Shape};
use crate::error::{invalid, Error, Result};
use crate::membrane::{DeviceCopy, Fetch, Membrane, Preconditioner};
use crate::solve::system::System;
use crate::solve::{Acceleration, Clock, Method, SolverParams, StepStats, Timings};

use super::device::GpuContext;
use super::layout::{self, GpuReal, IterValues, ParamValues};
use super::pipelines::{Pipelines, BINDINGS, REDUCE_GROUP, VERTEX_GROUP};

/// Iterations recorded between two reads of the control header.
pub const CHECK_EVERY: usize = 8;

/// `Iter` records: the two candidates of the initial guess, the energy after the loop, then
/// one per iteration.
const RECORD_PREVIOUS: usize = 0;
const RECORD_PREDICTION: usize = 1;
const RECORD_FINAL: usize = 2;
const RECORD_FIRST_ITERATION: usize = 3;

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

/// Identities of the device working sets, unique in the process.
static NEXT_STATE: AtomicU64 = AtomicU64::new(1);

/// The device-resident working set of one list of bodies.
struct State<T: GpuReal> {
    /// Identifies these buffers in the bodies' [`DeviceCopy`].
    id: u64,
    /// Steps these buffers have finished.
    epoch: u64,
    system: System<T>,
    n: u32,
    bonds: u64,
    iter_capacity: usize,
    collider_capacity: usize,
    /// The parameters the `Iter` records were written for.
    records_for: Option<SolverParams>,
    /// Whether the device's pin flags and pinned targets equal the host system's (after the
    /// first upload): then only pin changes are uploaded.
    pins_synced: bool,
    buffers: Buffers,
    bind_group: wgpu::BindGroup,
}

struct Buffers {
    params: wgpu::Buffer,
    iters: wgpu::Buffer,
    colliders: wgpu::Buffer,
    pinned: wgpu::Buffer,
    y_start: wgpu::Buffer,
    velocity: wgpu::Buffer,
    y_star: wgpu::Buffer,
    ctrl: wgpu::Buffer,
    /// MAP_READ copies: the control header, and the history at the end of a step.
    header_readback: wgpu::Buffer,
    history_readback: wgpu::Buffer,
}

fn millis(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

fn groups(count: u32, size: u32) -> u32 {
    count.div_ceil(size).max(1)
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
        if params.method != Method::Sissm || params.inner_iters != 1 {
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
    /// - colliders, the convergence measure and the commit: per vertex 64 + 16 + 32 (+32 with
    ///   Chebyshev); with `record_energy` another 68.
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
        let rest = (64 + 16 + 32 + if accelerated { 32 } else { 0 }) * n;
        let energy = if self.params.record_energy { 68 * n } else { 0 };
        let scale = std::mem::size_of::<T>() as u64 / 4;
        Some((kernel + jacobi + rest + energy) * scale)
    }

    /// Advances `bodies` by one time step. On divergence the bodies keep their state and an
    /// [`Error::Diverged`] names the first non-finite vertex.
    pub fn step(&mut self, bodies: &mut [&mut Membrane]) -> Result<StepStats> {
        let started = Instant::now();
        let params = self.params;
        let records = params.max_iters + RECORD_FIRST_ITERATION;
        let rebuild = match &self.state {
            None => true,
            Some(s) => {
                !s.system.matches(bodies)
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
                let (body, vertex) = state.system.locate(header[1] as usize);
                return Err(Error::Diverged {
                    step: self.clock.steps,
                    iteration: header[2] as usize,
                    body,
                    vertex,
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

impl<T: GpuReal> State<T> {
    fn build(
        ctx: &GpuContext,
        pipelines: &Pipelines,
        bodies: &[&mut Membrane],
        iter_capacity: usize,
        collider_capacity: usize,
    ) -> Result<Self> {
        let system = System::<T>::build(bodies, false)?;
        let n = system.y.len();
        let bonds = system.nb.indices.len();
        if n == 0 {
            return Err(invalid!("the bodies have no vertices"));
        }
        let device = &ctx.device;
        let limits = &ctx.limits;
        let too_big = |what: &str, bytes: u64| {
            Error::Gpu(format!(
                "{what} needs {bytes} bytes, more than the adapter {:?} binds ({} bytes per storage buffer)",
                ctx.info.name, limits.max_storage_buffer_binding_size
            ))
        };
        let vertex_groups = groups(n as u32, VERTEX_GROUP);
        if vertex_groups > limits.max_compute_workgroups_per_dimension {
            return Err(Error::Gpu(format!(
                "{n} vertices need {vertex_groups} workgroups, more than the adapter's {}",
                limits.max_compute_workgroups_per_dimension
            )));
        }
        let storage =
            |label: &str, bytes: u64, extra: wgpu::BufferUsages| -> Result<wgpu::Buffer> {
                let bytes = bytes.max(16);
                if bytes > limits.max_storage_buffer_binding_size {
                    return Err(too_big(label, bytes));
                }
                Ok(device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: bytes,
                    usage: wgpu::BufferUsages::STORAGE | extra,
                    mapped_at_creation: false,
                }))
            };
        let init = |label: &str, contents: &[u8]| -> Result<wgpu::Buffer> {
            let buffer = storage(label, contents.len() as u64, wgpu::BufferUsages::COPY_DST)?;
            ctx.queue.write_buffer(&buffer, 0, contents);
            Ok(buffer)
        };
        let copy = wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC;
        let vec_bytes = n as u64 * T::VEC_BYTES;
        let rest = &system.rest;
        let vertices: Vec<T::Vertex> = rest
            .frames
            .iter()
            .zip(&rest.vertices)
            .map(|(f, c)| T::vertex(f, c))
            .collect();
        let bond_data: Vec<T::Bond> = rest.bonds.iter().map(T::bond).collect();
        let history_bytes = (iter_capacity as u64) * T::VEC_BYTES;
        let ctrl_bytes = T::CONTROL_HEADER_BYTES + history_bytes;
        let uniform = |label: &str, bytes: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let readback = |label: &str, bytes: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let buffers = Buffers {
            params: uniform("params", std::mem::size_of::<T::Params>() as u64),
            iters: uniform("iters", iter_capacity as u64 * layout::ITER_STRIDE),
            colliders: storage(
                "colliders",
                (collider_capacity * std::mem::size_of::<T::Collider>()) as u64,
                wgpu::BufferUsages::COPY_DST,
            )?,
            pinned: storage("pinned", n as u64 * 4, wgpu::BufferUsages::COPY_DST)?,
            y_start: storage("y_start", vec_bytes, copy)?,
            velocity: storage("velocity", vec_bytes, copy)?,
            y_star: storage("y_star", vec_bytes, copy)?,
            ctrl: storage("ctrl", ctrl_bytes, copy)?,
            header_readback: readback("header readback", T::CONTROL_HEADER_BYTES),
            history_readback: readback("history readback", history_bytes),
        };
        let owned = [
            init("vertices", bytemuck::cast_slice(&vertices))?,
            init("bonds", bytemuck::cast_slice(&bond_data))?,
            init("offsets", bytemuck::cast_slice(&system.nb.offsets))?,
            init("indices", bytemuck::cast_slice(&system.nb.indices))?,
            init("reverse", bytemuck::cast_slice(&system.nb.reverse))?,
            storage("y", vec_bytes, wgpu::BufferUsages::empty())?,
            storage("y_next", vec_bytes, wgpu::BufferUsages::empty())?,
            storage("y_prev", vec_bytes, wgpu::BufferUsages::empty())?,
            storage(
                "bond_grad",
                bonds as u64 * T::VEC_BYTES,
                wgpu::BufferUsages::empty(),
            )?,
            storage(
                "response",
                n as u64 * T::RESPONSE_BYTES,
                wgpu::BufferUsages::empty(),
            )?,
            storage(
                "measure",
                n as u64 * T::MEASURE_BYTES,
                wgpu::BufferUsages::empty(),
            )?,
            storage(
                "partials",
                groups(n as u32, REDUCE_GROUP) as u64 * T::PARTIAL_BYTES,
                wgpu::BufferUsages::empty(),
            )?,
        ];
        let [vertices, bond_buf, offsets, indices, reverse, y, y_next, y_prev, bond_grad, response, measure, partials] =
            &owned;
        let b = &buffers;
        let by_binding: [&wgpu::Buffer; BINDINGS as usize] = [
            &b.params,
            &b.iters,
            vertices,
            bond_buf,
            offsets,
            indices,
            reverse,
            &b.colliders,
            &b.pinned,
            &b.y_start,
            &b.velocity,
            &b.y_star,
            y,
            y_next,
            y_prev,
            bond_grad,
            response,
            measure,
            partials,
            &b.ctrl,
        ];
        let entries: Vec<wgpu::BindGroupEntry> = by_binding
            .iter()
            .enumerate()
            .map(|(k, buffer)| wgpu::BindGroupEntry {
                binding: k as u32,
                resource: if k == 1 {
                    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer,
                        offset: 0,
                        size: wgpu::BufferSize::new(std::mem::size_of::<T::Iter>() as u64),
                    })
                } else {
                    buffer.as_entire_binding()
                },
            })
            .collect();
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("peridyn state"),
            layout: &pipelines.layout,
            entries: &entries,
        });
        ctx.check()?;
        Ok(Self {
            id: NEXT_STATE.fetch_add(1, Ordering::Relaxed),
            epoch: 0,
            n: n as u32,
            bonds: bonds as u64,
            system,
            iter_capacity,
            collider_capacity,
            records_for: None,
            pins_synced: false,
            buffers,
            bind_group,
        })
    }

    /// Uploads the positions and velocities of the bodies whose newest state the device does
    /// not hold (those Python set, or another solver stepped), and the pins when they changed;
    /// then writes the parameters, colliders, per-iteration records (when the parameters
    /// changed) and a fresh control header.
    fn upload(
        &mut self,
        ctx: &GpuContext,
        bodies: &mut [&mut Membrane],
        params: &SolverParams,
        colliders: &[ColliderModel<T>],
    ) -> Result<()> {
        let q = &ctx.queue;
        let sys = &mut self.system;
        let as_vec4 = |v: &[Vector3<f64>]| {
            v.iter()
                .map(|x| layout::vec4(&x.map(T::of)))
                .collect::<Vec<_>>()
        };
        for (body, range) in bodies.iter_mut().zip(&sys.ranges) {
            if body.device_copy() == Some((self.id, self.epoch)) {
                continue;
            }
            body.sync()?;
            let at = range.start as u64 * T::VEC_BYTES;
            let (y, v) = (as_vec4(body.positions()), as_vec4(body.velocities()));
            q.write_buffer(&self.buffers.y_start, at, bytemuck::cast_slice(&y));
            q.write_buffer(&self.buffers.velocity, at, bytemuck::cast_slice(&v));
        }
        // `load_pins` writes y_star only at pinned vertices (their targets); elsewhere the
        // device computes it, so comparing the whole host arrays compares exactly what is
        // uploaded.
        let device = self
            .pins_synced
            .then(|| (sys.y_star.clone(), sys.pinned.clone()));
        sys.load_pins(bodies);
        let (same_star, same_pins) = match &device {
            Some((star, pins)) => (*star == sys.y_star, *pins == sys.pinned),
            None => (false, false),
        };
        // a vertex pinned anew needs its target even if the host's stale entry matches
        if !(same_star && same_pins) {
            let targets: Vec<[T; 4]> = sys.y_star.iter().map(layout::vec4).collect();
            q.write_buffer(&self.buffers.y_star, 0, bytemuck::cast_slice(&targets));
        }
        if !same_pins {
            let pinned: Vec<u32> = sys.pinned.iter().map(|&p| p as u32).collect();
            q.write_buffer(&self.buffers.pinned, 0, bytemuck::cast_slice(&pinned));
        }
        self.pins_synced = true;
        let gpu_colliders: Vec<T::Collider> = colliders.iter().map(T::collider).collect();
        if !gpu_colliders.is_empty() {
            q.write_buffer(
                &self.buffers.colliders,
                0,
                bytemuck::cast_slice(&gpu_colliders),
            );
        }
        let gpu_params = T::params(&ParamValues {
            gravity: params.gravity,
            h: params.dt,
            n: self.n,
            n_colliders: colliders.len() as u32,
            step_length: params.step_length as u32,
            preconditioner: match params.preconditioner {
                Preconditioner::Tangent => 0,
                Preconditioner::Paper => 1,
            },
            tol: params.tol,
            groups: groups(self.n, REDUCE_GROUP),
            accelerated: (params.acceleration != Acceleration::None) as u32,
        });
        q.write_buffer(&self.buffers.params, 0, bytemuck::bytes_of(&gpu_params));
        q.write_buffer(
            &self.buffers.ctrl,
            0,
            bytemuck::cast_slice(&[u32::MAX, u32::MAX, u32::MAX, 0]),
        );
        if self.records_for != Some(*params) {
            let mut records = vec![IterValues::default(); self.iter_capacity];
            records[RECORD_PREDICTION].lane = 1;
            let mut omega = 1.0;
            for k in 0..params.max_iters {
                let extrapolation = params.acceleration.omega(k, omega);
                omega = extrapolation.unwrap_or(1.0);
                records[RECORD_FIRST_ITERATION + k] = IterValues {
                    iteration: k as u32,
                    slot: 1 + k as u32,
                    lane: 2,
                    extrapolate: extrapolation.is_some() as u32,
                    omega,
                };
            }
            let mut bytes = vec![0u8; self.iter_capacity * layout::ITER_STRIDE as usize];
            for (k, r) in records.iter().enumerate() {
                let at = k * layout::ITER_STRIDE as usize;
                let record = T::iter(r);
                bytes[at..at + std::mem::size_of::<T::Iter>()]
                    .copy_from_slice(bytemuck::bytes_of(&record));
            }
            q.write_buffer(&self.buffers.iters, 0, &bytes);
            self.records_for = Some(*params);
        }
        Ok(())
    }

    fn write_record(&self, ctx: &GpuContext, index: usize, record: &IterValues) {
        ctx.queue.write_buffer(
            &self.buffers.iters,
            index as u64 * layout::ITER_STRIDE,
            bytemuck::bytes_of(&T::iter(record)),
        );
    }

    fn pass<'a>(
        &'a self,
        encoder: &'a mut wgpu::CommandEncoder,
        pipelines: &'a Pipelines,
    ) -> Pass<'a> {
        Pass {
            pass: encoder.begin_compute_pass(&Default::default()),
            pipelines,
            bind_group: &self.bind_group,
            vertex_groups: groups(self.n, VERTEX_GROUP),
            reduce_groups: groups(self.n, REDUCE_GROUP),
        }
    }

    /// Submits `encoder` after a copy of the control header, and returns the header
    /// `(limit, bad_vertex, bad_iteration)`.
    fn read_header(&self, ctx: &GpuContext, mut encoder: wgpu::CommandEncoder) -> Result<[u32; 3]> {
        let b = &self.buffers;
        encoder.copy_buffer_to_buffer(&b.ctrl, 0, &b.header_readback, 0, T::CONTROL_HEADER_BYTES);
        ctx.queue.submit([encoder.finish()]);
        let bytes = map_read(ctx, &b.header_readback)?;
        let words: Vec<u32> = bytemuck::pod_collect_to_vec(&bytes);
        Ok([words[0], words[1], words[2]])
    }

    /// Submits `encoder` (the end of a step) after a copy of the history, records in every
    /// body that its new state is on the device, and returns the history `[0, max_iters + 2)`.
    fn finish_step(
        &mut self,
        ctx: &GpuContext,
        mut encoder: wgpu::CommandEncoder,
        bodies: &mut [&mut Membrane],
        max_iters: usize,
    ) -> Result<Vec<[T; 4]>> {
        let b = &self.buffers;
        let history_bytes = (max_iters as u64 + 2) * T::VEC_BYTES;
        encoder.copy_buffer_to_buffer(
            &b.ctrl,
            T::CONTROL_HEADER_BYTES,
            &b.history_readback,
            0,
            history_bytes,
        );
        ctx.queue.submit([encoder.finish()]);
        // y_t and v hold the new state on the device from here on (the queue runs in order,
        // so a body's read-back sees it)
        self.epoch += 1;
        for (body, range) in bodies.iter_mut().zip(&self.system.ranges) {
            let fetch = fetch_body::<T>(ctx, b, range.clone());
            body.leave_on_device(DeviceCopy::pending(self.id, self.epoch, fetch));
        }
        let bytes = map_read(ctx, &b.history_readback)?;
        let all: Vec<[T; 4]> = bytemuck::pod_collect_to_vec(&bytes);
        Ok(all[..max_iters + 2].to_vec())
    }
}

/// Reads the positions and velocities of the vertices `range` back from `buffers` (through a
/// staging buffer of its own, so that bodies can be read from any thread).
fn fetch_body<T: GpuReal>(ctx: &GpuContext, buffers: &Buffers, range: Range<usize>) -> Fetch {
    let ctx = ctx.clone();
    let (y_start, velocity) = (buffers.y_start.clone(), buffers.velocity.clone());
    Arc::new(move || {
        let at = range.start as u64 * T::VEC_BYTES;
        let bytes = range.len() as u64 * T::VEC_BYTES;
        let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("body readback"),
            size: 2 * bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&y_start, at, &staging, 0, bytes);
        encoder.copy_buffer_to_buffer(&velocity, at, &staging, bytes, bytes);
        ctx.queue.submit([encoder.finish()]);
        let all: Vec<[T; 4]> = bytemuck::pod_collect_to_vec(&map_read(&ctx, &staging)?);
        let f64s = |v: &[[T; 4]]| {
            v.iter()
                .map(|c| Vector3::new(c[0].to_f64(), c[1].to_f64(), c[2].to_f64()))
                .collect::<Vec<_>>()
        };
        let (y, v) = all.split_at(range.len());
        Ok((f64s(y), f64s(v)))
    })
}

/// Maps `buffer` for reading once the queue has finished, and copies it out.
fn map_read(ctx: &GpuContext, buffer: &wgpu::Buffer) -> Result<Vec<u8>> {
    let outcome = std::sync::Arc::new(std::sync::Mutex::new(None));
    let sink = outcome.clone();
    buffer.map_async(wgpu::MapMode::Read, .., move |r| {
        if let Ok(mut slot) = sink.lock() {
            *slot = Some(r);
        }
    });
    ctx.wait()?;
    ctx.check()?;
    let mapped = outcome.lock().unwrap_or_else(|p| p.into_inner()).take();
    match mapped {
        Some(Ok(())) => {}
        Some(Err(e)) => return Err(Error::Gpu(format!("cannot read GPU results back: {e}"))),
        None => return Err(Error::Gpu("GPU read-back did not complete".into())),
    }
    let bytes = buffer
        .get_mapped_range(..)
        .map_err(|e| Error::Gpu(format!("cannot read GPU results back: {e}")))?
        .to_vec();
    buffer.unmap();
    Ok(bytes)
}

/// A compute pass recording the kernels of a step.
struct Pass<'a> {
    pass: wgpu::ComputePass<'a>,
    pipelines: &'a Pipelines,
    bind_group: &'a wgpu::BindGroup,
    vertex_groups: u32,
    reduce_groups: u32,
}

impl Pass<'_> {
    fn run(&mut self, pipeline: &wgpu::ComputePipeline, record: usize, groups: u32) {
        self.pass.set_pipeline(pipeline);
        let offset = (record as u64 * layout::ITER_STRIDE) as u32;
        self.pass.set_bind_group(0, self.bind_group, &[offset]);
        self.pass.dispatch_workgroups(groups, 1, 1);
    }

    fn per_vertex(&mut self, pipeline: fn(&Pipelines) -> &wgpu::ComputePipeline, record: usize) {
        let p = pipeline(self.pipelines);
        self.run(p, record, self.vertex_groups);
    }

    /// The variational energy of `y` into the history slot of `record` (after the kernel
    /// when `evaluate`).
    fn energy(&mut self, record: usize, evaluate: bool) {
        if evaluate {
            self.per_vertex(|p| &p.evaluate, record);
        }
        let p = self.pipelines;
        self.run(&p.reduce_energy, record, self.reduce_groups);
        self.run(&p.finish_energy, record, 1);
    }

    /// `y* = y_t + h v + h^2 g`, then the lower-energy of `y_t` and `y*` as first iterate,
    /// evaluated.
    fn initial_guess(&mut self) {
        self.per_vertex(|p| &p.predict, RECORD_PREVIOUS);
        self.per_vertex(|p| &p.use_previous, RECORD_PREVIOUS);
        self.energy(RECORD_PREVIOUS, true);
        self.per_vertex(|p| &p.use_prediction, RECORD_PREDICTION);
        self.energy(RECORD_PREDICTION, true);
        self.per_vertex(|p| &p.choose_initial, RECORD_PREDICTION);
        self.per_vertex(|p| &p.evaluate, RECORD_PREDICTION);
    }

    /// Global iteration `k`: kernel (k > 0), energy, Jacobi update, colliders, convergence
    /// measure, commit.
    fn iteration(&mut self, k: usize, record_energy: bool) {
        let record = RECORD_FIRST_ITERATION + k;
        if k > 0 {
            self.per_vertex(|p| &p.evaluate, record);
            if record_energy {
                self.energy(record, false);
            }
        }
        self.per_vertex(|p| &p.jacobi, record);
        self.per_vertex(|p| &p.project, record);
        let p = self.pipelines;
        self.run(&p.reduce_measure, record, self.reduce_groups);
        self.run(&p.finish_measure, record, 1);
        self.per_vertex(|p| &p.commit, record);
    }

    /// `v = (y - y_t) / h`, `y_t <- y`.
    fn finish(&mut self) {
        self.per_vertex(|p| &p.finish, RECORD_PREVIOUS);
    }
}
