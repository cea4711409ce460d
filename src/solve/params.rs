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
    /// [`super::StepStats::error_estimate`]); 0 runs `max_iters` iterations.
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
    /// What the numbers favour ([`Acceleration::resolve`]): Chebyshev with the default `rho`
    /// and `delay` for SISSM without membrane contact, plain iterations otherwise.
    #[default]
    Auto,
    /// Plain SISSM iterations.
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
    /// With membrane contact its extrapolation undoes the local step's separation (it is
    /// refused there). Where the stopping test ends a step, Chebyshev's iterate lies elsewhere
    /// within the tolerance than the plain one (a hanging strip at rest, tol = 1e-6 m, lies
    /// 5e-4 m from its exact equilibrium against 3e-4 m for plain SISSM, in 3x fewer
    /// iterations), and f32 follows f64 less closely (7e-5 m against 8e-6 m).
    pub const DEFAULT_RHO: f64 = 0.99;
    /// Default number of plain iterations before extrapolating.
    pub const DEFAULT_DELAY: usize = 3;

    /// The acceleration [`Acceleration::Auto`] stands for, given the method and whether
    /// membrane contact is on; any other choice is returned as it is.
    ///
    /// Chebyshev cuts the iterations to a tolerance 3-5x (`benches/convergence.py`: 36 instead
    /// of more than 300 to eta 1e-4 on the moderate cloth; a stiff 40x40 cloth at h = 1e-3 and
    /// tol = 1e-6 m needs 25 iterations per step instead of 117), so it is the default where it
    /// applies. With contact its extrapolation would undo the local step's separation, and the
    /// descent baseline restarts it on its own line search, so `Auto` is plain there. At the
    /// default tolerance most steps converge within `delay` iterations, before it acts.
    pub fn resolve(self, method: Method, contact: bool) -> Self {
        match self {
            Self::Auto if method == Method::Sissm && !contact => Self::Chebyshev {
                rho: Self::DEFAULT_RHO,
                delay: Self::DEFAULT_DELAY,
            },
            Self::Auto => Self::None,
            chosen => chosen,
        }
    }

    /// The extrapolation weight of iteration `k` (0-based) given the previous one; `None`
    /// means a plain iteration. `Auto` must be [resolved](Acceleration::resolve) first.
    pub fn omega(&self, k: usize, previous: f64) -> Option<f64> {
        match *self {
            Self::None | Self::Auto => None,
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
            acceleration: Acceleration::Auto,
            method: Method::Sissm,
            inner_iters: 1,
            record_energy: false,
            contact: None,
        }
    }
}

impl SolverParams {
    /// The acceleration the iteration runs with ([`Acceleration::resolve`]).
    pub fn effective_acceleration(&self) -> Acceleration {
        self.acceleration
            .resolve(self.method, self.contact.is_some())
    }

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
            if let Acceleration::Chebyshev { .. } = self.acceleration {
                return Err(invalid!(
                    "chebyshev acceleration cannot be combined with contact: its extrapolation \
                     moves vertices across the separation the contact local step just restored; \
                     use acceleration=None"
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::ContactParams;

    /// `Auto` is Chebyshev for SISSM without contact and plain otherwise; an explicit choice
    /// stays, and only an explicit Chebyshev is refused with contact.
    #[test]
    fn auto_acceleration_resolves_by_method_and_contact() {
        let chebyshev = Acceleration::Chebyshev {
            rho: Acceleration::DEFAULT_RHO,
            delay: Acceleration::DEFAULT_DELAY,
        };
        let auto = Acceleration::Auto;
        assert_eq!(auto.resolve(Method::Sissm, false), chebyshev);
        assert_eq!(auto.resolve(Method::Sissm, true), Acceleration::None);
        assert_eq!(auto.resolve(Method::Descent, false), Acceleration::None);
        assert_eq!(
            Acceleration::None.resolve(Method::Sissm, false),
            Acceleration::None
        );
        let with_contact = SolverParams {
            contact: Some(ContactParams::default()),
            ..SolverParams::default()
        };
        assert!(with_contact.validate().is_ok());
        assert_eq!(with_contact.effective_acceleration(), Acceleration::None);
        let refused = SolverParams {
            acceleration: chebyshev,
            ..with_contact
        };
        assert!(refused.validate().is_err());
        assert_eq!(SolverParams::default().effective_acceleration(), chebyshev);
    }
}
