//! The device-resident working set of one list of bodies: its buffers, their upload, and
//! the read-back of a finished step.

use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use nalgebra::Vector3;

use crate::collider::ColliderModel;
use crate::error::{invalid, Error, Result};
use crate::membrane::{DeviceCopy, Fetch, Membrane, Preconditioner};
use crate::solve::membranes::MembraneSystem;
use crate::solve::{Acceleration, SolverParams};

use super::device::GpuContext;
use super::layout::{self, GpuReal, IterValues, ParamValues};
use super::pass::{Pass, RECORD_FIRST_ITERATION, RECORD_PREDICTION};
use super::pipelines::{groups, Pipelines, BINDINGS, REDUCE_GROUP, VERTEX_GROUP};

/// Identities of the device working sets, unique in the process.
static NEXT_STATE: AtomicU64 = AtomicU64::new(1);

/// The device-resident working set of one list of bodies.
pub(super) struct State<T: GpuReal> {
    /// Identifies these buffers in the bodies' [`DeviceCopy`].
    pub(super) id: u64,
    /// Steps these buffers have finished.
    pub(super) epoch: u64,
    pub(super) system: MembraneSystem<T>,
    pub(super) n: u32,
    pub(super) bonds: u64,
    pub(super) iter_capacity: usize,
    pub(super) collider_capacity: usize,
    /// The parameters the `Iter` records were written for.
    pub(super) records_for: Option<SolverParams>,
    /// Whether the device's pin flags and pinned targets equal the host system's (after the
    /// first upload): then only pin changes are uploaded.
    pub(super) pins_synced: bool,
    pub(super) buffers: Buffers,
    pub(super) bind_group: wgpu::BindGroup,
}

pub(super) struct Buffers {
    pub(super) params: wgpu::Buffer,
    pub(super) iters: wgpu::Buffer,
    pub(super) colliders: wgpu::Buffer,
    pub(super) pinned: wgpu::Buffer,
    pub(super) y_start: wgpu::Buffer,
    pub(super) velocity: wgpu::Buffer,
    pub(super) y_star: wgpu::Buffer,
    /// The iterate a flagged vertex reached, read back to report a divergence's cause.
    pub(super) y_next: wgpu::Buffer,
    pub(super) ctrl: wgpu::Buffer,
    /// MAP_READ copies: the control header, and the history at the end of a step.
    pub(super) header_readback: wgpu::Buffer,
    pub(super) history_readback: wgpu::Buffer,
}

impl<T: GpuReal> State<T> {
    pub(super) fn build(
        ctx: &GpuContext,
        pipelines: &Pipelines,
        bodies: &[&mut Membrane],
        iter_capacity: usize,
        collider_capacity: usize,
    ) -> Result<Self> {
        let system = MembraneSystem::<T>::build(bodies, false)?;
        let n = system.points.y.len();
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
            y_next: storage("y_next", vec_bytes, wgpu::BufferUsages::COPY_SRC)?,
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
        let [vertices, bond_buf, offsets, indices, reverse, y, y_prev, bond_grad, response, measure, partials] =
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
            &b.y_next,
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
    pub(super) fn upload(
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
        for (body, range) in bodies.iter_mut().zip(&sys.points.ranges) {
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
            .then(|| (sys.points.y_star.clone(), sys.points.pinned.clone()));
        sys.points.load_pins(bodies);
        let (same_star, same_pins) = match &device {
            Some((star, pins)) => (*star == sys.points.y_star, *pins == sys.points.pinned),
            None => (false, false),
        };
        // a vertex pinned anew needs its target even if the host's stale entry matches
        if !(same_star && same_pins) {
            let targets: Vec<[T; 4]> = sys.points.y_star.iter().map(layout::vec4).collect();
            q.write_buffer(&self.buffers.y_star, 0, bytemuck::cast_slice(&targets));
        }
        if !same_pins {
            let pinned: Vec<u32> = sys.points.pinned.iter().map(|&p| p as u32).collect();
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
            max_move: params.max_speed * params.dt,
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

    pub(super) fn write_record(&self, ctx: &GpuContext, index: usize, record: &IterValues) {
        ctx.queue.write_buffer(
            &self.buffers.iters,
            index as u64 * layout::ITER_STRIDE,
            bytemuck::bytes_of(&T::iter(record)),
        );
    }

    pub(super) fn pass<'a>(
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
    pub(super) fn read_header(
        &self,
        ctx: &GpuContext,
        mut encoder: wgpu::CommandEncoder,
    ) -> Result<[u32; 3]> {
        let b = &self.buffers;
        encoder.copy_buffer_to_buffer(&b.ctrl, 0, &b.header_readback, 0, T::CONTROL_HEADER_BYTES);
        ctx.queue.submit([encoder.finish()]);
        let bytes = map_read(ctx, &b.header_readback)?;
        let words: Vec<u32> = bytemuck::pod_collect_to_vec(&bytes);
        Ok([words[0], words[1], words[2]])
    }

    /// The iterate `y_next` and the start `y_t` (m) of `vertex`, read back after the kernels
    /// flagged it (the step's commands stop there, so `y_next` holds the flagged iterate).
    pub(super) fn read_move(
        &self,
        ctx: &GpuContext,
        vertex: usize,
    ) -> Result<(Vector3<T>, Vector3<T>)> {
        let b = &self.buffers;
        let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("flagged vertex readback"),
            size: 2 * T::VEC_BYTES,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let at = vertex as u64 * T::VEC_BYTES;
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&b.y_next, at, &staging, 0, T::VEC_BYTES);
        encoder.copy_buffer_to_buffer(&b.y_start, at, &staging, T::VEC_BYTES, T::VEC_BYTES);
        ctx.queue.submit([encoder.finish()]);
        let both: Vec<[T; 4]> = bytemuck::pod_collect_to_vec(&map_read(ctx, &staging)?);
        let xyz = |c: &[T; 4]| Vector3::new(c[0], c[1], c[2]);
        Ok((xyz(&both[0]), xyz(&both[1])))
    }

    /// Submits `encoder` (the end of a step) after a copy of the history, records in every
    /// body that its new state is on the device, and returns the history `[0, max_iters + 2)`.
    pub(super) fn finish_step(
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
        for (body, range) in bodies.iter_mut().zip(&self.system.points.ranges) {
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
pub(super) fn fetch_body<T: GpuReal>(
    ctx: &GpuContext,
    buffers: &Buffers,
    range: Range<usize>,
) -> Fetch {
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
pub(super) fn map_read(ctx: &GpuContext, buffer: &wgpu::Buffer) -> Result<Vec<u8>> {
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
