//! Phase timings: every `*_ms` figure of [`crate::solve::StepStats`] is wall-clock time in
//! milliseconds measured by [`millis`].

use std::time::Instant;

/// Wall-clock milliseconds since `since`.
pub(crate) fn millis(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}
