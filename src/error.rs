//! Errors of the core. The Python edge turns [`Error::InvalidInput`] into `ValueError`,
//! [`Error::Diverged`] into `peridyn.DivergenceError` and [`Error::Gpu`] into `RuntimeError`.

/// What can go wrong in the core.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// An input violates a documented requirement; the message names the offending index or value.
    #[error("{0}")]
    InvalidInput(String),
    /// A time step produced non-finite positions, or a point faster than the solver's
    /// `max_speed`; the bodies keep their last good state.
    #[error("step {step} diverged at iteration {iteration}: vertex {vertex} of body {body} {cause}; the bodies were left at their last good state (try a smaller dt, more iterations, or check the material parameters)")]
    Diverged {
        step: u64,
        iteration: usize,
        body: usize,
        vertex: usize,
        cause: Divergence,
    },
    /// The GPU backend is unavailable (no adapter, missing capability) or the device failed.
    #[error("{0}")]
    Gpu(String),
}

/// What a diverged step's point did ([`Error::Diverged`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Divergence {
    /// A coordinate became infinite or NaN.
    NonFinite,
    /// Its predicted move in the step, `|h v_t + h^2 g|` (m), has no finite square: no
    /// distance can measure where it goes, though every number is finite.
    UnboundedMove,
    /// Its new velocity's magnitude `speed` (m/s) exceeded the solver's `limit` (m/s):
    /// positions still finite but running away (a blown-up step can reach 1e129 m).
    TooFast { speed: f64, limit: f64 },
}

impl std::fmt::Display for Divergence {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NonFinite => write!(f, "became non-finite"),
            Self::UnboundedMove => write!(
                f,
                "has a predicted move in the step (velocity and gravity) without a finite square \
                 (above 1.3e154 m)"
            ),
            Self::TooFast { speed, limit } => write!(
                f,
                "reached {speed:.3e} m/s, above the solver's max_speed of {limit:.3e} m/s \
                 (raise max_speed if the scene is meant to move that fast)"
            ),
        }
    }
}

/// Result with the core's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

/// Shorthand for an [`Error::InvalidInput`] built with `format!`.
macro_rules! invalid {
    ($($arg:tt)*) => { $crate::error::Error::InvalidInput(format!($($arg)*)) };
}
pub(crate) use invalid;

/// Checks that a scalar parameter is finite and satisfies `ok`, else names it.
pub fn check_param(
    name: &str,
    value: f64,
    ok: impl Fn(f64) -> bool,
    requirement: &str,
) -> Result<f64> {
    if value.is_finite() && ok(value) {
        Ok(value)
    } else {
        Err(invalid!("{name} must be {requirement}, got {value}"))
    }
}
