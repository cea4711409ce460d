//! Host mirrors of the structs in `shaders/common.wgsl` (same field order, 16-byte aligned),
//! and their conversion from the CPU solver's data.

use bytemuck::{Pod, Zeroable};
use nalgebra::Vector3;

use crate::contact::{Collider, ColliderModel};
use crate::material::MaterialModel;
use crate::membrane::{BondRest, Frame, VertexConstants};

/// `struct Params`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct Params {
    pub gravity: [f32; 3],
    pub h: f32,
    pub n: u32,
    pub n_colliders: u32,
    pub step_length: u32,
    pub preconditioner: u32,
    pub tol: f32,
    pub min_stretch: f32,
    pub groups: u32,
    pub accelerated: u32,
}

/// `struct Iter`, one per 256-byte dynamic-offset slot.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct Iter {
    pub iteration: u32,
    pub slot: u32,
    pub lane: u32,
    pub extrapolate: u32,
    pub omega: f32,
    pub pad: [u32; 3],
}

/// `struct Vertex`: rest frame and constants of one vertex.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct Vertex {
    t1: [f32; 3],
    volume: f32,
    t2: [f32; 3],
    mass: f32,
    nc: [f32; 3],
    half_thickness: f32,
    k_iso: f32,
    k_bound: f32,
    kappa_t: f32,
    kappa_n: f32,
    s0: f32,
    s1: f32,
    model: u32,
    pad: u32,
}

impl Vertex {
    pub fn new(frame: &Frame<f32>, c: &VertexConstants<f32>) -> Self {
        let (model, s0, s1) = match c.material {
            MaterialModel::StretchA3 { s0 } => (0, s0, 0.0),
            MaterialModel::NeoHookean { s0, s1 } => (1, s0, s1),
        };
        Self {
            t1: frame.t1.into(),
            volume: c.volume,
            t2: frame.t2.into(),
            mass: c.mass,
            nc: frame.nc.into(),
            half_thickness: c.half_thickness,
            k_iso: c.k_iso,
            k_bound: c.k_bound,
            kappa_t: c.kappa_t,
            kappa_n: c.kappa_n,
            s0,
            s1,
            model,
            pad: 0,
        }
    }
}

/// `struct Bond`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct Bond {
    xi: [f32; 3],
    beta1: f32,
    curvature: [f32; 3],
    beta2: f32,
}

impl From<&BondRest<f32>> for Bond {
    fn from(b: &BondRest<f32>) -> Self {
        Self {
            xi: b.xi.into(),
            beta1: b.beta[0],
            curvature: b.curvature.into(),
            beta2: b.beta[1],
        }
    }
}

/// `struct Collider`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct GpuCollider {
    a: [f32; 3],
    b: f32,
    kind: u32,
    pad: [u32; 3],
}

impl From<&Collider> for GpuCollider {
    fn from(c: &Collider) -> Self {
        let (a, b, kind) = match c.to_real::<f32>() {
            ColliderModel::Plane { normal, offset } => (normal, offset, 0),
            ColliderModel::Sphere { center, radius } => (center, radius, 1),
        };
        Self {
            a: a.into(),
            b,
            kind,
            pad: [0; 3],
        }
    }
}

/// Bytes of `struct Response`, `struct Measure` and `struct Partial`.
pub(super) const RESPONSE_BYTES: u64 = 32;
pub(super) const MEASURE_BYTES: u64 = 16;
pub(super) const PARTIAL_BYTES: u64 = 16;
/// Bytes of one position (vec4<f32>).
pub(super) const VEC_BYTES: u64 = 16;
/// Bytes of the header of `struct Control` before `history`.
pub(super) const CONTROL_HEADER_BYTES: u64 = 16;
/// Dynamic-offset stride of the `Iter` records (wgpu's minimum uniform offset alignment).
pub(super) const ITER_STRIDE: u64 = 256;

/// A position as the shaders store it.
pub(super) fn vec4(v: &Vector3<f32>) -> [f32; 4] {
    [v.x, v.y, v.z, 0.0]
}
