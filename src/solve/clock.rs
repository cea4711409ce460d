//! The simulation clock every solver keeps.

use crate::error::{check_param, Result};

/// Simulation time and steps taken.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Clock {
    /// Simulation time (s).
    pub time: f64,
    /// Steps taken so far.
    pub steps: u64,
}

impl Clock {
    /// A clock at `time` (s, finite) after `steps` steps, e.g. when restoring a saved simulation.
    pub fn at(time: f64, steps: u64) -> Result<Self> {
        Ok(Self {
            time: check_param("time", time, |_| true, "finite")?,
            steps,
        })
    }

    /// Advances by one step of `dt` (s).
    pub fn tick(&mut self, dt: f64) {
        self.time += dt;
        self.steps += 1;
    }
}
