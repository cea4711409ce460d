//! The compute pipelines, built once per device from one shader module: the scalar type's
//! prelude (`shaders/real_f32.wgsl` or `real_f64.wgsl`), `shaders/common.wgsl` (the bind
//! group), then one file per concern.

use super::device::GpuContext;
use super::layout::GpuReal;

/// The WGSL source of every kernel after the prelude, compiled into the crate.
const KERNELS: &str = concat!(
    include_str!("../../shaders/common.wgsl"),
    include_str!("../../shaders/material.wgsl"),
    include_str!("../../shaders/kernel.wgsl"),
    include_str!("../../shaders/colliders.wgsl"),
    include_str!("../../shaders/jacobi.wgsl"),
    include_str!("../../shaders/predict.wgsl"),
    include_str!("../../shaders/reduce.wgsl"),
);

/// Threads per workgroup of the per-vertex kernels and of the reductions (as in the WGSL).
pub(super) const VERTEX_GROUP: u32 = 64;
pub(super) const REDUCE_GROUP: u32 = 256;

/// Bindings of `@group(0)` in `shaders/common.wgsl`: 0 the parameters, 1 the per-iteration
/// record (dynamic offset), 2..=8 read-only storage, 9..=19 read-write storage.
const READ_ONLY: std::ops::RangeInclusive<u32> = 2..=8;
pub(super) const BINDINGS: u32 = 20;

/// Every pipeline of the solver.
pub(super) struct Pipelines {
    pub layout: wgpu::BindGroupLayout,
    pub predict: wgpu::ComputePipeline,
    pub use_previous: wgpu::ComputePipeline,
    pub use_prediction: wgpu::ComputePipeline,
    pub choose_initial: wgpu::ComputePipeline,
    pub evaluate: wgpu::ComputePipeline,
    pub jacobi: wgpu::ComputePipeline,
    pub project: wgpu::ComputePipeline,
    pub commit: wgpu::ComputePipeline,
    pub finish: wgpu::ComputePipeline,
    pub reduce_measure: wgpu::ComputePipeline,
    pub finish_measure: wgpu::ComputePipeline,
    pub reduce_energy: wgpu::ComputePipeline,
    pub finish_energy: wgpu::ComputePipeline,
}

/// The sphere-tracing constants of the crossing check and the rounds of the metric push in
/// colliders.wgsl, written from the CPU's (`collider::crossing`, `collider::shape`), so that
/// the two cannot drift apart.
fn trace_constants() -> String {
    use crate::collider::{
        PUSH_ROUNDS, PUSH_SETTLE_ULPS, TOUCH_DISTANCE, TRACE_STEPS, TRACE_TOLERANCE,
    };
    format!(
        "const TRACE_STEPS: u32 = {TRACE_STEPS}u;\n\
         const TRACE_TOLERANCE: real = {TRACE_TOLERANCE:?};\n\
         const TOUCH_DISTANCE: real = {TOUCH_DISTANCE:?};\n\
         const PUSH_ROUNDS: u32 = {PUSH_ROUNDS}u;\n\
         const PUSH_SETTLE_ULPS: real = {PUSH_SETTLE_ULPS:?};\n"
    )
}

impl Pipelines {
    pub fn new<T: GpuReal>(ctx: &GpuContext) -> Self {
        let device = &ctx.device;
        let source = format!("{}{}{KERNELS}", T::PRELUDE, trace_constants());
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("peridyn kernels"),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });
        let entries: Vec<wgpu::BindGroupLayoutEntry> = (0..BINDINGS)
            .map(|binding| wgpu::BindGroupLayoutEntry {
                binding,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: match binding {
                        0 | 1 => wgpu::BufferBindingType::Uniform,
                        b => wgpu::BufferBindingType::Storage {
                            read_only: READ_ONLY.contains(&b),
                        },
                    },
                    has_dynamic_offset: binding == 1,
                    min_binding_size: (binding == 1)
                        .then(|| wgpu::BufferSize::new(std::mem::size_of::<T::Iter>() as u64))
                        .flatten(),
                },
                count: None,
            })
            .collect();
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("peridyn state"),
            entries: &entries,
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("peridyn"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let make = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        Self {
            predict: make("predict"),
            use_previous: make("use_previous"),
            use_prediction: make("use_prediction"),
            choose_initial: make("choose_initial"),
            evaluate: make("evaluate"),
            jacobi: make("jacobi"),
            project: make("project"),
            commit: make("commit"),
            finish: make("finish"),
            reduce_measure: make("reduce_measure"),
            finish_measure: make("finish_measure"),
            reduce_energy: make("reduce_energy"),
            finish_energy: make("finish_energy"),
            layout,
        }
    }
}

/// Workgroups of `size` invocations that cover `count` items (at least one).
pub(super) fn groups(count: u32, size: u32) -> u32 {
    count.div_ceil(size).max(1)
}
