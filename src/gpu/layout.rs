//! Host mirrors of the structs in `shaders/common.wgsl` for each scalar type (same field
//! order; explicit padding reproduces WGSL's alignment: 16 bytes for `vec3<f32>`, 32 for
//! `vec3<f64>`), and their conversion from the CPU solver's data.

use bytemuck::Pod;
use nalgebra::{Matrix3, Vector3};

use crate::collider::{ColliderModel, ShapeModel};
use crate::material::MaterialModel;
use crate::membrane::{BondRest, Frame, VertexConstants};
use crate::real::Real;

/// `struct Params` without the scalar-dependent layout: see [`GpuReal::params`].
#[doc(hidden)]
pub struct ParamValues {
    pub gravity: [f64; 3],
    pub h: f64,
    pub n: u32,
    pub n_colliders: u32,
    pub step_length: u32,
    pub preconditioner: u32,
    pub tol: f64,
    pub groups: u32,
    pub accelerated: u32,
    /// `max_speed h` (m), the farthest a free vertex may move in a step; `inf` unchecked.
    pub max_move: f64,
}

/// `struct Iter` values.
#[derive(Clone, Copy, Default)]
#[doc(hidden)]
pub struct IterValues {
    pub iteration: u32,
    pub slot: u32,
    pub lane: u32,
    pub extrapolate: u32,
    pub omega: f64,
}

/// A scalar type the kernels run in, with its WGSL prelude and buffer layouts.
pub trait GpuReal: Real + Pod {
    /// `shaders/real_f32.wgsl` or `shaders/real_f64.wgsl`.
    #[doc(hidden)]
    const PRELUDE: &'static str;
    /// Device features the kernels need (SHADER_F64 for f64).
    #[doc(hidden)]
    const FEATURES: wgpu::Features;
    #[doc(hidden)]
    type Params: Pod;
    #[doc(hidden)]
    type Iter: Pod;
    #[doc(hidden)]
    type Vertex: Pod;
    #[doc(hidden)]
    type Bond: Pod;
    #[doc(hidden)]
    type Collider: Pod;
    /// Bytes of `vec4<real>`, `struct Response`, `struct Measure`, `struct Partial`, and of the
    /// header of `struct Control` before `history` (which is aligned like `vec4<real>`).
    #[doc(hidden)]
    const VEC_BYTES: u64;
    #[doc(hidden)]
    const RESPONSE_BYTES: u64;
    #[doc(hidden)]
    const MEASURE_BYTES: u64;
    #[doc(hidden)]
    const PARTIAL_BYTES: u64;
    #[doc(hidden)]
    const CONTROL_HEADER_BYTES: u64;
    #[doc(hidden)]
    fn params(p: &ParamValues) -> Self::Params;
    #[doc(hidden)]
    fn iter(i: &IterValues) -> Self::Iter;
    #[doc(hidden)]
    fn vertex(frame: &Frame<Self>, c: &VertexConstants<Self>) -> Self::Vertex;
    #[doc(hidden)]
    fn bond(b: &BondRest<Self>) -> Self::Bond;
    #[doc(hidden)]
    fn collider(c: &ColliderModel<Self>) -> Self::Collider;
}

/// Defines the layout structs of one scalar type; the pads are the u32 words WGSL's
/// alignment adds at the end of `Params`, `Iter` and `Vertex`, after `Collider::kind` and at
/// the end of `Collider`.
macro_rules! layout {
    ($module:ident, $t:ty, $prelude:literal, $features:expr, vec = $vec:literal,
     pads = ($pp:literal, $ip:literal, $vp:literal, $kp:literal, $cp:literal),
     response = $rb:literal, measure = $mb:literal, partial = $pb:literal, header = $hb:literal) => {
        mod $module {
            use bytemuck::{Pod, Zeroable};

            #[repr(C)]
            #[derive(Clone, Copy, Pod, Zeroable)]
            pub struct Params {
                pub gravity: [$t; 3],
                pub h: $t,
                pub n: u32,
                pub n_colliders: u32,
                pub step_length: u32,
                pub preconditioner: u32,
                pub tol: $t,
                pub min_stretch: $t,
                pub groups: u32,
                pub accelerated: u32,
                pub max_move: $t,
                pub pad: [u32; $pp],
            }

            #[repr(C)]
            #[derive(Clone, Copy, Pod, Zeroable)]
            pub struct Iter {
                pub iteration: u32,
                pub slot: u32,
                pub lane: u32,
                pub extrapolate: u32,
                pub omega: $t,
                pub pad: [u32; $ip],
            }

            #[repr(C)]
            #[derive(Clone, Copy, Pod, Zeroable)]
            pub struct Vertex {
                pub t1: [$t; 3],
                pub volume: $t,
                pub t2: [$t; 3],
                pub mass: $t,
                pub nc: [$t; 3],
                pub half_thickness: $t,
                pub k_iso: $t,
                pub k_bound: $t,
                pub kappa_t: $t,
                pub kappa_n: $t,
                pub s0: $t,
                pub s1: $t,
                pub model: u32,
                pub pad: [u32; $vp],
            }

            #[repr(C)]
            #[derive(Clone, Copy, Pod, Zeroable)]
            pub struct Bond {
                pub xi: [$t; 3],
                pub beta1: $t,
                pub curvature: [$t; 3],
                pub beta2: $t,
            }

            #[repr(C)]
            #[derive(Clone, Copy, Pod, Zeroable)]
            pub struct Collider {
                pub a: [$t; 3],
                pub b: $t,
                pub c: [$t; 3],
                pub friction: $t,
                pub axes: [[$t; 4]; 3],
                pub offset: [$t; 3],
                pub kind: u32,
                pub kind_pad: [u32; $kp],
                pub displacement: [$t; 3],
                pub pad: [u32; $cp],
            }
        }

        impl GpuReal for $t {
            const PRELUDE: &'static str = include_str!($prelude);
            const FEATURES: wgpu::Features = $features;
            type Params = $module::Params;
            type Iter = $module::Iter;
            type Vertex = $module::Vertex;
            type Bond = $module::Bond;
            type Collider = $module::Collider;
            const VEC_BYTES: u64 = $vec;
            const RESPONSE_BYTES: u64 = $rb;
            const MEASURE_BYTES: u64 = $mb;
            const PARTIAL_BYTES: u64 = $pb;
            const CONTROL_HEADER_BYTES: u64 = $hb;

            fn params(p: &ParamValues) -> Self::Params {
                $module::Params {
                    gravity: p.gravity.map(|g| g as $t),
                    h: p.h as $t,
                    n: p.n,
                    n_colliders: p.n_colliders,
                    step_length: p.step_length,
                    preconditioner: p.preconditioner,
                    tol: p.tol as $t,
                    min_stretch: <$t as Real>::min_stretch(),
                    groups: p.groups,
                    accelerated: p.accelerated,
                    // a finite sentinel for "unchecked": WGSL need not honour inf
                    max_move: if p.max_move < <$t>::MAX as f64 {
                        p.max_move as $t
                    } else {
                        <$t>::MAX
                    },
                    pad: [0; $pp],
                }
            }

            fn iter(i: &IterValues) -> Self::Iter {
                $module::Iter {
                    iteration: i.iteration,
                    slot: i.slot,
                    lane: i.lane,
                    extrapolate: i.extrapolate,
                    omega: i.omega as $t,
                    pad: [0; $ip],
                }
            }

            fn vertex(frame: &Frame<Self>, c: &VertexConstants<Self>) -> Self::Vertex {
                let (model, s0, s1) = match c.material {
                    MaterialModel::StretchA3 { s0 } => (0, s0, 0.0),
                    MaterialModel::NeoHookean { s0, s1 } => (1, s0, s1),
                };
                $module::Vertex {
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
                    pad: [0; $vp],
                }
            }

            fn bond(b: &BondRest<Self>) -> Self::Bond {
                $module::Bond {
                    xi: b.xi.into(),
                    beta1: b.beta[0],
                    curvature: b.curvature.into(),
                    beta2: b.beta[1],
                }
            }

            fn collider(c: &ColliderModel<Self>) -> Self::Collider {
                let zero = Vector3::zeros();
                let mut axes = Matrix3::identity();
                debug_assert!(
                    c.translates_only(),
                    "the GPU backend refuses collider poses"
                );
                let (a, b, c3, kind) = match *c.shape() {
                    ShapeModel::Plane { normal, offset } => (normal, offset, zero, 0),
                    ShapeModel::Sphere { center, radius } => (center, radius, zero, 1),
                    ShapeModel::Box {
                        center,
                        half_extents,
                        axes: rotation,
                    } => {
                        axes = rotation;
                        (center, 0.0, half_extents, 2)
                    }
                    ShapeModel::Capsule { a, b, radius } => (a, radius, b, 3),
                    ShapeModel::Mesh(..) => unreachable!("GpuSolver::add_collider refuses meshes"),
                };
                let column = |k: usize| vec4(&axes.column(k).into_owned());
                $module::Collider {
                    a: a.into(),
                    b,
                    c: c3.into(),
                    friction: c.friction,
                    axes: [column(0), column(1), column(2)],
                    offset: c.translation().into(),
                    kind,
                    kind_pad: [0; $kp],
                    displacement: c.displacement(&Vector3::zeros()).into(),
                    pad: [0; $cp],
                }
            }
        }
    };
}

layout!(
    single,
    f32,
    "../../shaders/real_f32.wgsl",
    wgpu::Features::empty(),
    vec = 16,
    pads = (3, 3, 1, 0, 1),
    response = 32,
    measure = 16,
    partial = 16,
    header = 16
);
layout!(
    double,
    f64,
    "../../shaders/real_f64.wgsl",
    wgpu::Features::SHADER_F64,
    vec = 32,
    pads = (4, 2, 3, 1, 2),
    response = 64,
    measure = 24,
    partial = 32,
    header = 32
);

/// Dynamic-offset stride of the `Iter` records (wgpu's largest uniform offset alignment).
pub(super) const ITER_STRIDE: u64 = 256;

/// A position as the shaders store it (`vec4<real>`, w unused).
pub(super) fn vec4<T: Real>(v: &Vector3<T>) -> [T; 4] {
    [v.x, v.y, v.z, T::zero()]
}
