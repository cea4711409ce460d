//! Solver parameters.

use crate::error::{check_param, invalid, Result};
use crate::membrane::Preconditioner;

/// Parameters of [`super::Solver`] (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverParams {
    /// Time step h (s).
    pub dt: f64,
    /// Gravitational acceleration (m/s^2).
    pub gravity: [f64; 3],
    /// Convergence threshold on `max_i |y_i^k - y_i^(k-1)|` (m); 0 runs `max_iters` iterations.
    pub tol: f64,
    /// Cap on global iterations per step.
    pub max_iters: usize,
    /// Apply the per-vertex step length of eq. 31-33.
    pub step_length: bool,
    /// How the stretching stiffness enters the implicit part.
    pub preconditioner: Preconditioner,
}

impl Default for SolverParams {
    fn default() -> Self {
        Self {
            dt: 1e-3,
            gravity: [0.0, 0.0, -9.81],
            tol: 1e-4,
            max_iters: 100,
            step_length: true,
            preconditioner: Preconditioner::Tangent,
        }
    }
}

impl SolverParams {
    /// Checks every parameter, naming the first bad one.
    pub fn validate(&self) -> Result<()> {
        check_param("dt", self.dt, |v| v > 0.0, "a finite time step > 0 s")?;
        for (k, g) in self.gravity.iter().enumerate() {
            check_param(&format!("gravity[{k}]"), *g, |_| true, "finite")?;
        }
        check_param("tol", self.tol, |v| v >= 0.0, "a finite distance >= 0 m")?;
        if self.max_iters < 1 {
            return Err(invalid!("max_iters must be >= 1, got {}", self.max_iters));
        }
        Ok(())
    }
}
