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
    /// Particle bodies only: the largest force imbalance per unit mass, `|r_i| / (m_i h^2)`
    /// (m/s^2), a converged step may leave, besides `tol` (docs/particles/solids.md, "Convergence
    /// measure"): particle steps stop at `min(tol, particle_tol h^2)` (m).
    pub particle_tol: f64,
    /// Cap on global iterations per step.
    pub max_iters: usize,
    /// The fastest a free point may end a step (m/s; `inf`: unchecked): a faster one makes
    /// the step an [`crate::error::Error::Diverged`] that keeps the last good state. A
    /// blown-up step can leave positions finite but absurd (1e129 m seen), which no
    /// finiteness check catches; pinned points, whose motion the user prescribes, are exempt.
    pub max_speed: f64,
    /// Apply the per-vertex step length of eq. 31-33.
    pub step_length: bool,
    /// How the stretching stiffness enters the implicit part.
    pub preconditioner: Preconditioner,
    /// Optional acceleration of the global iteration.
    pub acceleration: Acceleration,
    /// The iteration: SISSM, the descent baseline, or Newton.
    pub method: Method,
    /// Jacobi sweeps on the linear system of eq. 25 per global iteration (Fig. 6; 1 in the paper).
    pub inner_iters: usize,
    /// Record the total variational energy `E(y^k)` of every iterate in [`super::StepStats`]
    /// (one extra kernel pass per step).
    pub record_energy: bool,
    /// Contact between and within membranes (the local step of Algorithm 2); `None`: off.
    pub contact: Option<ContactParams>,
    /// How particle bodies solve the linear system of their global step (He et al. 2017,
    /// Fig. 7); membranes ignore it.
    pub global_solver: GlobalSolver,
    /// The spectral-radius estimate `rho` in (0, 1) of the particles' Chebyshev acceleration,
    /// over the `acceleration`'s (`None`: as [`GlobalSolver::acceleration`] says).
    pub particle_chebyshev_rho: Option<f64>,
    /// The plain iterations (>= 1) before the particles' Chebyshev acceleration extrapolates,
    /// over the `acceleration`'s (`None`: as [`GlobalSolver::acceleration`] says).
    pub particle_chebyshev_delay: Option<usize>,
    /// Whether particle bodies' Jacobi and Chebyshev sweeps take the two-level correction on
    /// aggregates of about 30 particles (`src/solve/particles/two_level.rs`): a sparse
    /// Cholesky factor of the coarse matrix each time the time step or the held set (pins,
    /// contacts) changes, and two passes over the bonds per iteration, for fewer iterations
    /// wherever a body's slow elastic modes hold the step (a landing, a stretched body).
    pub particle_two_level: bool,
}

/// The global solver of particle bodies (He et al. 2017, section 4.2, Fig. 7): how the move
/// of each global iteration solves `(M + h^2 L) delta = r` (eq. 12 with the local step's
/// projections held). Every one has the implicit Euler solution as its fixed point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GlobalSolver {
    /// A sparse Cholesky factor of the constant matrix, computed when the time step or the
    /// pins change: the exact solve of the linear system each iteration.
    Direct,
    /// `inner_iters` Jacobi sweeps.
    Jacobi,
    /// Jacobi sweeps with Chebyshev acceleration (the paper's default), as
    /// [`GlobalSolver::acceleration`] sets it.
    #[default]
    Chebyshev,
    /// Position-based averaging: each bond solves its own two-particle system and each
    /// particle moves by the average of its bonds' moves.
    Position,
}

impl GlobalSolver {
    /// The spectral-radius estimate of the particles' Chebyshev acceleration when neither
    /// [`SolverParams::particle_chebyshev_rho`] nor the solver's `acceleration` sets one.
    pub const CHEBYSHEV_RHO: f64 = 0.99;

    /// The acceleration particle bodies iterate with under `params`: Chebyshev with
    /// "chebyshev" or an `acceleration`, its `rho` [`SolverParams::particle_chebyshev_rho`],
    /// else the `acceleration`'s, else [`Self::CHEBYSHEV_RHO`], and its delay
    /// [`SolverParams::particle_chebyshev_delay`], else the `acceleration`'s, else
    /// [`Acceleration::DEFAULT_DELAY`]; else none.
    pub fn acceleration(self, params: &SolverParams) -> Acceleration {
        let (rho, delay) = match (self, params.acceleration) {
            (_, Acceleration::Chebyshev { rho, delay }) => (rho, delay),
            (Self::Chebyshev, Acceleration::None) => {
                (Self::CHEBYSHEV_RHO, Acceleration::DEFAULT_DELAY)
            }
            (_, Acceleration::None) => return Acceleration::None,
        };
        Acceleration::Chebyshev {
            rho: params.particle_chebyshev_rho.unwrap_or(rho),
            delay: params.particle_chebyshev_delay.unwrap_or(delay),
        }
    }
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
    /// Newton steps on the implicit Euler energy with a projected Hessian model, solved by
    /// block-Jacobi preconditioned conjugate gradients, and an energy line search; see
    /// `solve/membranes/newton.rs`.
    Newton,
    /// SISSM or Newton, chosen at each step from `tol`, the mesh and the stiffness
    /// `h^2 k / m` (membranes only; SISSM with particle bodies and on the GPU); see
    /// `solve/membranes/auto.rs`. A Chebyshev acceleration applies where SISSM is chosen.
    Auto,
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
    /// Default spectral-radius estimate: the fastest of 0.9 / 0.95 / 0.99 / 0.999 to
    /// `eta < 1e-3` on the moderate cloth of `benches/convergence.py`.
    ///
    /// Chebyshev is not the solver's default although it wins on iterations to a tight
    /// tolerance: with a small fixed budget of iterations it ends a step farther from the
    /// solution than plain iterations (and amplifies f32 round-off); with membrane contact
    /// the best `rho` is lower, near the plain iteration's decay per iteration; and at a
    /// tolerance it stops elsewhere than plain iterations. docs/performance.md ("Chebyshev:
    /// when it helps") has the figures.
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
            particle_tol: Self::DEFAULT_PARTICLE_TOL,
            max_iters: 100,
            max_speed: Self::DEFAULT_MAX_SPEED,
            step_length: true,
            preconditioner: Preconditioner::Tangent,
            acceleration: Acceleration::None,
            method: Method::Sissm,
            inner_iters: 1,
            record_energy: false,
            contact: None,
            global_solver: GlobalSolver::default(),
            particle_chebyshev_rho: None,
            particle_chebyshev_delay: None,
            particle_two_level: true,
        }
    }
}

impl SolverParams {
    /// The default [`Self::particle_tol`] (m/s^2): a hundredth of the gravity of Earth.
    pub const DEFAULT_PARTICLE_TOL: f64 = 0.0981;

    /// The default [`Self::max_speed`] (m/s): 10 km/s, some 30 times the speed of sound in
    /// air and well above any bullet, far beyond what a cloth, a solid or a liquid reaches
    /// here by falling or being thrown.
    pub const DEFAULT_MAX_SPEED: f64 = 1e4;

    /// The convergence threshold (m) of particle bodies' measure: `min(tol, particle_tol
    /// dt^2)`, so that a step of any length stops where its accelerations meet Newton's law
    /// within `particle_tol`, and within `tol` of the implicit Euler solution.
    pub fn particle_threshold(&self) -> f64 {
        self.tol.min(self.particle_tol * self.dt * self.dt)
    }

    /// Checks every parameter, naming the first bad one.
    pub fn validate(&self) -> Result<()> {
        check_param("dt", self.dt, |v| v > 0.0, "a finite time step > 0 s")?;
        for (k, g) in self.gravity.iter().enumerate() {
            check_param(&format!("gravity[{k}]"), *g, |_| true, "finite")?;
        }
        check_param("tol", self.tol, |v| v >= 0.0, "a finite distance >= 0 m")?;
        check_param(
            "particle_tol",
            self.particle_tol,
            |v| v > 0.0,
            "a finite acceleration > 0 m/s^2",
        )?;
        if self.max_speed != f64::INFINITY {
            check_param(
                "max_speed",
                self.max_speed,
                |v| v > 0.0,
                "a speed > 0 m/s, or inf to leave speeds unchecked",
            )?;
        }
        if let Acceleration::Chebyshev { rho, delay } = self.acceleration {
            check_param("chebyshev_rho", rho, |v| v > 0.0 && v < 1.0, "in (0, 1)")?;
            if delay < 1 {
                return Err(invalid!(
                    "chebyshev_delay must be >= 1 iteration, got {delay}"
                ));
            }
        }
        if let Some(rho) = self.particle_chebyshev_rho {
            check_param("chebyshev_rho", rho, |v| v > 0.0 && v < 1.0, "in (0, 1)")?;
        }
        if let Some(delay) = self.particle_chebyshev_delay {
            if delay < 1 {
                return Err(invalid!(
                    "chebyshev_delay must be >= 1 iteration, got {delay}"
                ));
            }
        }
        if self.method == Method::Newton && self.acceleration != Acceleration::None {
            return Err(invalid!(
                "chebyshev acceleration needs method='sissm' or 'descent': newton steps are \
                 not a fixed-point iteration; use acceleration=None"
            ));
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
