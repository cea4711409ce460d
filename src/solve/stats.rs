//! What a step reports.

use crate::contact::ContactStats;

/// Wall-clock milliseconds per phase of a step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Timings {
    /// Loading state and computing the inertial target y*.
    pub predict: f64,
    /// Global steps (vertex kernel and Jacobi update).
    pub global: f64,
    /// Of `global`: the vertex kernel (bond gradients, energies and preconditioner blocks of
    /// every vertex); the rest of `global` is the per-vertex move. CPU SISSM only (0 on the GPU,
    /// whose kernels are not timed apart, and for the descent baseline).
    pub kernel: f64,
    /// Collider projection (local step).
    pub colliders: f64,
    /// Velocity update and write-back (with the plastic phases below).
    pub finish: f64,
    /// Of `finish`: the plastic return of particle bodies stored at the step's end and the
    /// rebuild of their rest data (`t_p` of He et al. 2017, Table 1; 0 without plastic
    /// bodies). A granular body's return within the iterations is part of its kernel passes,
    /// in `global` ([`crate::particles::Cone`]).
    pub plasticity: f64,
    /// The neighbour searches of particle bodies (`t_n` of Table 1; 0 without): of plastic
    /// bodies on their deformed positions (of `finish`), and of fluids at the step's start
    /// and before their density projection (not in `predict`).
    pub neighbours: f64,
    /// The SPH density and what follows from it: the density constraints' projection of fluid
    /// particles (`t_rho`), the density of granular bodies and their stiffness from it (`t_d`,
    /// He et al. 2017 eq. 25-27); 0 without fluids or sand (their neighbour search counts in
    /// `neighbours`).
    pub density: f64,
    /// The particle redistribution of fluids (`t_d` of Table 1; 0 without).
    pub redistribution: f64,
    /// The implicit viscosity of fluid particles, at the step's start (not in `predict`; 0
    /// without).
    pub viscosity: f64,
    /// The coupling of particles with membrane triangles: its pairs, its projections after
    /// every iteration and at the end (0 without both families).
    pub coupling: f64,
    /// The membrane contact local step (Lu et al. 2023, Algorithm 2) after each global
    /// iteration, whole: its broad phase, CCD and descent (the times of
    /// [`StepStats::contact`]) and what those leave out, the proximal metric (eq. 47's
    /// Jacobi blocks), the per-vertex set-up passes and the realised reaction of the
    /// convergence measure (0 without contact).
    pub contact: f64,
    /// The whole step.
    pub total: f64,
}

/// The particle family's share of a step (all zero without particle bodies): milliseconds
/// per phase of its work, counted from the start of the step (the initial guess's kernel
/// passes included), and counts.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ParticleTimings {
    /// The kernel (He et al. 2017, eq. 8-11: deformation gradients, the bonds' local step and
    /// forces, gathered per particle) at the iterates, line search trials aside.
    pub kernel: f64,
    /// The residual of eq. 12 and its merit at the iterates.
    pub residual: f64,
    /// The global solver's move (Jacobi sweeps, averaging, or the direct solve with its
    /// refactorisations).
    pub solve: f64,
    /// Of `solve`: the bodies' coarse translation (`src/solve/particles/coarse.rs`) and the
    /// two-level correction, its held set and refactorisations included
    /// (`src/solve/particles/two_level.rs`).
    pub coarse: f64,
    pub two_level: f64,
    /// The line search's trials (eq. 13), each a kernel pass and a residual.
    pub line_search: f64,
    /// Of `line_search`: the trials' kernel passes (the rest gathers the particles' forces
    /// and forms the residuals and merits).
    pub trial_kernel: f64,
    /// The move's collider projection with friction, Chebyshev extrapolation and measures.
    pub project: f64,
    /// Kernel passes of the step (at the iterates and at the line search's trials).
    pub evaluations: usize,
    /// Numeric factorisations of the direct solver's matrix or of the two-level correction's
    /// coarse matrix (`src/solve/particles/two_level.rs`); a change of values alone (a sand's
    /// stiffness from its density, a flowing body's re-born bonds) refactors on the pattern at
    /// hand.
    pub factorizations: usize,
    /// Symbolic analyses of those matrices (the pattern, its fill-reducing ordering and
    /// symbolic factor): on the first step that asks for the solver, and after a plastic
    /// body's neighbourhoods changed. Not a subset of `factorizations`: each analysis is
    /// followed by a factorisation, counted there.
    pub analyses: usize,
    /// Particles of granular bodies that static friction held at the end of the step (He et
    /// al. 2017, eq. 28).
    pub held_static: usize,
    /// Density projections of the fluids' step, and the largest relative excess density
    /// `rho / rho0 - 1` they left (`src/solve/particles/fluid.rs`).
    pub density_passes: usize,
    pub density_error: f64,
    /// The step's last convergence measure against f32/f64 round-off
    /// (`src/solve/particles/roundoff.rs`, docs/particles/solids.md "Convergence measure"): the
    /// largest round-off floor `nu_i = eps |y_i| D_i / m_i` (m) that the measure subtracts, and the
    /// particle (body, index in the body) holding the largest `|r_i| / m_i - nu_i`, `None`
    /// when every particle is within its floor. A floor above the tolerance means the step's
    /// "converged" is "within the tolerance of what the precision resolves at these
    /// coordinates" (it grows with the distance from the family's frame origin, near its
    /// bodies; from the world origin when membranes share the step).
    pub roundoff_floor: f64,
    pub worst_particle: Option<(usize, usize)>,
}

/// `method="newton"`: milliseconds per phase of its iterations, summed over the step, and
/// counts (all zero for the other methods). The phases partition the Newton iterations'
/// share of [`Timings::global`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct NewtonTimings {
    /// SISSM's Jacobi systems and residual at the iterate, and the held vertices.
    pub jacobi: f64,
    /// The per-vertex Hessian models.
    pub models: f64,
    /// The coarse matrix's assembly (`P^T K P`).
    pub coarse_assembly: f64,
    /// The coarse matrix's numeric factorisation.
    pub coarse_factor: f64,
    /// The conjugate-gradient iterations (Hessian products and preconditioner).
    pub cg: f64,
    /// The line search's trials (a kernel pass and an energy each), collider projection
    /// included.
    pub line_search: f64,
    /// Numeric factorisations of the coarse matrix.
    pub factorizations: usize,
    /// Line-search trials (kernel passes).
    pub trials: usize,
}

impl NewtonTimings {
    /// Adds `other`'s times and counts to these.
    pub fn accumulate(&mut self, other: &Self) {
        self.jacobi += other.jacobi;
        self.models += other.models;
        self.coarse_assembly += other.coarse_assembly;
        self.coarse_factor += other.coarse_factor;
        self.cg += other.cg;
        self.line_search += other.line_search;
        self.factorizations += other.factorizations;
        self.trials += other.trials;
    }
}

/// Statistics of one time step.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StepStats {
    /// 0-based index of the step.
    pub step: u64,
    /// Simulation time after the step (s).
    pub time: f64,
    /// Global iterations performed.
    pub iterations: usize,
    /// Whether [`StepStats::residual`] fell below `tol` (never when `tol == 0`).
    pub converged: bool,
    /// The convergence measure after each iteration (m): `max_i |r_i| / m_i` at the iterate
    /// the kernel evaluated, without the contact reactions (colliders, and the barrier push of
    /// the contact local step), an upper bound on the mass-weighted RMS distance to the exact
    /// implicit Euler solution where the energy is convex. How it fell, or stalled. With
    /// contact, the first iteration's measures the whole residual, contacts included (no local
    /// step has run before it), and does not decide convergence.
    pub residuals: Vec<f64>,
    /// `max_i |y_i^k - y_i^(k-1)|` after each iteration `k` (m).
    pub moves: Vec<f64>,
    /// Total variational energy `E(y^k)` of eq. 2 without the barrier (J) for `k = 0..=iterations`,
    /// when the solver records it (else empty).
    pub energies: Vec<f64>,
    /// Milliseconds per phase.
    pub timings: Timings,
    /// Contact local steps of this time step, summed over the global iterations (all zero when
    /// contact is off): candidate triangle pairs (largest), active primitive pairs (last),
    /// descent iterations and milliseconds in broad phase, CCD and descent.
    pub contact: ContactStats,
    /// Newton: Hessian products of its conjugate-gradient solves, summed over the step (0 for
    /// the other methods).
    pub linear_products: usize,
    /// Newton: its phases (zero for the other methods).
    pub newton: NewtonTimings,
    /// The particle family's phases and counts.
    pub particles: ParticleTimings,
}

impl StepStats {
    /// The last iteration's `max_i |y_i^k - y_i^(k-1)|` (m; 0 before any iteration).
    pub fn last_move(&self) -> f64 {
        self.moves.last().copied().unwrap_or(0.0)
    }

    /// The last iteration's convergence measure (m; see [`StepStats::residuals`]; 0 before any
    /// iteration).
    pub fn residual(&self) -> f64 {
        self.residuals.last().copied().unwrap_or(0.0)
    }
}
