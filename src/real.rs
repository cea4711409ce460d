//! The floating-point types the solver runs in: one generic code path for `f32` (the fast
//! path) and `f64` (the reference).

use nalgebra::RealField;

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
}
