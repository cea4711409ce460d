//! The floating-point types the solver runs in: one generic code path for `f32` (the fast
//! path) and `f64` (the reference).

use nalgebra::{RealField, Vector3};

/// A scalar the simulation can run in (`f32` or `f64`).
pub trait Real: RealField + Copy + Send + Sync + Default + std::fmt::Debug + 'static {
    /// Converts from `f64` (rounding for `f32`).
    fn of(x: f64) -> Self;
    /// Converts to `f64` exactly.
    fn to_f64(self) -> f64;
    /// Smallest principal stretch used when evaluating energies and stresses, so that a
    /// vertex whose neighbourhood has collapsed gets a very large but finite restoring force.
    fn min_stretch() -> Self;
    /// Name used in reprs and benchmarks.
    const NAME: &'static str;
    /// The SIMD pack of this scalar that the vertex kernel runs on.
    type Pack: Lanes<Scalar = Self>;
    /// `sum[k] += add[k]` for the eight entries of a gathered record, as wide additions (the
    /// per-vertex move sums eight-entry records of its neighbours; left to itself, the compiler
    /// adds them one entry at a time).
    fn add_eight(sum: &mut [Self; 8], add: &[Self; 8]);
}

impl Real for f64 {
    fn of(x: f64) -> Self {
        x
    }
    fn to_f64(self) -> f64 {
        self
    }
    fn min_stretch() -> Self {
        1e-6
    }
    const NAME: &'static str = "f64";
    type Pack = F64Pack;
    #[inline(always)]
    fn add_eight(sum: &mut [Self; 8], add: &[Self; 8]) {
        for (s, a) in sum.chunks_exact_mut(4).zip(add.chunks_exact(4)) {
            let half = |x: &[f64]| F64Pack::from([x[0], x[1], x[2], x[3]]);
            s.copy_from_slice(&(half(s) + half(a)).0.to_array());
        }
    }
}

impl Real for f32 {
    fn of(x: f64) -> Self {
        x as f32
    }
    fn to_f64(self) -> f64 {
        self as f64
    }
    fn min_stretch() -> Self {
        1e-4
    }
    const NAME: &'static str = "f32";
    type Pack = F32Pack;
    #[inline(always)]
    fn add_eight(sum: &mut [Self; 8], add: &[Self; 8]) {
        *sum = (F32Pack::from(*sum) + F32Pack::from(*add)).0.to_array();
    }
}

/// A pack of [`LANES`](nalgebra::SimdValue::LANES) scalars computed on in lock step: a scalar [`Real`] itself (one
/// lane) or a SIMD vector of them. The per-vertex kernels are written once over `Lanes`, so the
/// same code runs one vertex at a time or [`LANES`](nalgebra::SimdValue::LANES) vertices at a time (one per lane).
///
/// Every lane performs exactly the IEEE operations the scalar code performs, in the same order
/// (no fused multiply-add, no approximate reciprocals), so a pack's lanes are bit-identical to
/// the scalar results: the SIMD path changes the speed, never the numbers.
pub trait Lanes:
    nalgebra::SimdRealField<Element = <Self as Lanes>::Scalar> + Copy + Send + Sync + 'static
{
    /// The scalar of one lane.
    type Scalar: Real;

    /// `x` (converted to the scalar type) in every lane.
    #[inline(always)]
    fn lit(x: f64) -> Self {
        Self::splat(Self::Scalar::of(x))
    }

    /// [`Real::min_stretch`] in every lane.
    #[inline(always)]
    fn stretch_floor() -> Self {
        Self::splat(<Self::Scalar as Real>::min_stretch())
    }

    /// The pack whose lane `l` is `lane(l)`.
    fn gather(lane: impl FnMut(usize) -> Self::Scalar) -> Self;
}

impl<T: Real> Lanes for T {
    type Scalar = T;

    #[inline(always)]
    fn gather(mut lane: impl FnMut(usize) -> T) -> Self {
        lane(0)
    }
}

/// Eight `f32` lanes (one AVX register, or two SSE registers on CPUs without AVX).
pub type F32Pack = simba::simd::WideF32x8;
/// Four `f64` lanes.
pub type F64Pack = simba::simd::WideF64x4;

impl Lanes for F32Pack {
    type Scalar = f32;

    #[inline(always)]
    fn gather(lane: impl FnMut(usize) -> f32) -> Self {
        Self(array_from_fn::<f32, 8>(lane).into())
    }
}

impl Lanes for F64Pack {
    type Scalar = f64;

    #[inline(always)]
    fn gather(lane: impl FnMut(usize) -> f64) -> Self {
        Self(array_from_fn::<f64, 4>(lane).into())
    }
}

/// `[f(0), f(1), ..., f(N - 1)]`, as `std::array::from_fn` but always inlined: the standard one
/// can stay out of line in the kernel's loops, a call per gathered pack.
#[inline(always)]
pub fn array_from_fn<T: Copy + Default, const N: usize>(mut f: impl FnMut(usize) -> T) -> [T; N] {
    let mut out = [T::default(); N];
    for (i, x) in out.iter_mut().enumerate() {
        *x = f(i);
    }
    out
}

/// `a` in the lanes where `mask` holds, else `b`.
#[inline(always)]
pub fn select<S: Lanes>(mask: S::SimdBool, a: Vector3<S>, b: Vector3<S>) -> Vector3<S> {
    Vector3::new(
        a.x.select(mask, b.x),
        a.y.select(mask, b.y),
        a.z.select(mask, b.z),
    )
}
