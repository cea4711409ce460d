//! Solver parameters.

use crate::contact::ContactParams;
use crate::error::{check_param, invalid, Result};
use crate::membrane::Preconditioner;

/// Parameters of [`super::Solver`] (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverParams {
    /// Time step h (s).
    pub dt: f64,
    /// Gravitational acceleration (m/s^2).
    pub gravity: [f64; 3],
    /// Convergence threshold on the error bound `max_i |r_i| / m_i` (m, see
    /// [`super::StepStats::residual`]); 0 runs `max_iters` iterations.
    pub tol: f64,
    /// Cap on global iterations per step.
    pub max_iters: usize,
    /// Apply the per-vertex step length of eq. 31-33.
    pub step_length: bool,
    /// How the stretching stiffness enters the implicit part.
    pub preconditioner: Preconditioner,
    /// Optional acceleration of the global iteration.
    pub acceleration: Acceleration,
    /// The iteration: SISSM, or the descent baseline.
    pub method: Method,
    /// Jacobi sweeps on the linear system of eq. 25 per global iteration (Fig. 6; 1 in the paper).
    pub inner_iters: usize,
    /// Record the total variational energy `E(y^k)` of every iterate in [`super::StepStats`]
    /// (one extra kernel pass per step).
    pub record_energy: bool,
    /// Contact between and within membranes (the local step of Algorithm 2); `None`: off.
    pub contact: Option<ContactParams>,
}

/// The global iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// The semi-implicit successive substitution method (Lu et al. 2023).
    #[default]
    Sissm,
    /// Gradient descent on the variational energy preconditioned by the diagonal of its
    /// Hessian, with a step length halved on every energy rise (Wang and Yang 2016), the
    /// baseline of the paper's Fig. 13; see `solve/descent.rs`.
    Descent,
}

/// Acceleration of the global iteration.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Acceleration {
    /// Plain SISSM iterations.
    #[default]
    None,
    /// Chebyshev semi-iterative acceleration (Wang 2015): from iteration `delay` on,
    /// `y^{k+1} = omega_{k+1} (y_hat^{k+1} - y^{k-1}) + y^{k-1}` with
    /// `omega = 2 / (2 - rho^2)` first, then `omega_{k+1} = 4 / (4 - rho^2 omega_k)`.
    /// `rho` in (0, 1) estimates the spectral radius of the plain iteration: too high
    /// oscillates, too low wastes the acceleration.
    Chebyshev { rho: f64, delay: usize },
}

impl Acceleration {
    /// Default spectral-radius estimate: the fastest of 0.9 / 0.95 / 0.99 / 0.999 on the
    /// moderate cloth of `benches/convergence.py` (25 iterations to eta < 1e-3 against 223
    /// without acceleration).
    ///
    /// Chebyshev is not the solver's default although it wins on iterations to a tight
    /// tolerance (a stiff 40x40 cloth at h = 1e-3 s and tol = 1e-6 m: 25 iterations per step
    /// against 117):
    /// - with a small fixed budget it is worse: a 120x120 cloth (s0 = 1e6 Pa, 10 iterations per
    ///   step, `benches/peer_newton.py`) ends its steps with an error bound of 7e-4 m in f64
    ///   (plain: 9e-5 m), and in f32 it sags 9 mm instead of the 21 mm of f64 (plain f32: 21 mm);
    /// - with membrane contact it extrapolates the local step's result, global and local step
    ///   together (see `extrapolate_local_step` in `sissm.rs`), and the safe positions stay the
    ///   local step's: on six 80 x 80 layers landing (steps 391-395 from a saved state, tol =
    ///   1e-4 m) plain iterations converge at about 0.8 per iteration and take 17-28
    ///   iterations; with `rho = 0.85`, 13-23 (98 against 78 in all);
    /// - at a tolerance it stops elsewhere than plain iterations (a hanging strip at rest,
    ///   tol = 1e-6 m: 5e-4 m from its exact equilibrium against 3e-4 m), and f32 follows f64
    ///   less closely (7e-5 m against 8e-6 m).
    pub const DEFAULT_RHO: f64 = 0.99;
    /// Default number of plain iterations before extrapolating.
    pub const DEFAULT_DELAY: usize = 3;

    /// The extrapolation weight of iteration `k` (0-based) given the previous one; `None`
    /// means a plain iteration.
    pub fn omega(&self, k: usize, previous: f64) -> Option<f64> {
        match *self {
            Self::None => None,
            Self::Chebyshev { rho, delay } => {
                let r2 = rho * rho;
                match k.cmp(&delay) {
                    std::cmp::Ordering::Less => None,
                    std::cmp::Ordering::Equal => Some(2.0 / (2.0 - r2)),
                    std::cmp::Ordering::Greater => Some(4.0 / (4.0 - r2 * previous)),
                }
            }
        }
    }
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
            acceleration: Acceleration::None,
            method: Method::Sissm,
            inner_iters: 1,
            record_energy: false,
            contact: None,
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
        if let Acceleration::Chebyshev { rho, delay } = self.acceleration {
            check_param("chebyshev rho", rho, |v| v > 0.0 && v < 1.0, "in (0, 1)")?;
            if delay < 1 {
                return Err(invalid!(
                    "chebyshev delay must be >= 1 iteration, got {delay}"
                ));
            }
        }
        if let Some(contact) = &self.contact {
            contact.validate()?;
            if self.acceleration != Acceleration::None && self.method == Method::Descent {
                return Err(invalid!(
                    "chebyshev acceleration with contact needs method='sissm': the descent \
                     baseline extrapolates inside its line search; use acceleration=None"
                ));
            }
        }
        if self.inner_iters < 1 {
            return Err(invalid!(
                "inner_iters must be >= 1, got {}",
                self.inner_iters
            ));
        }
        if self.max_iters < 1 {
            return Err(invalid!("max_iters must be >= 1, got {}", self.max_iters));
        }
        Ok(())
    }
}
