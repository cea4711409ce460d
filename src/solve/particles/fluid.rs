//! The fluid stage of a particle step (He et al. 2017, section 6; Macklin and Mueller 2013,
//! "Position Based Fluids"): before the inertial prediction, the surface tension's kick
//! ([`super::surface_tension`]) and an implicit viscosity act on the velocities with gravity's
//! kick, on neighbours searched at the step's start ([`super::fluid_viscosity`]); once the local-global iterations have finished (`t_e` of the
//! paper's Table 1), the fluid particles' neighbours are searched on their positions (`t_n`),
//! their density constraints are projected (`t_rho`), the particles are redistributed (`t_d`,
//! [`redistribution`]: a position correction held to the density constraints), and after the
//! velocities are taken, the redistribution's moves are taken out of them.
//!
//! **Why a projection stage.** The density constraints are position projections without an
//! energy: the Armijo search of [`super::step`] has no merit to ask of them, and the
//! Jacobi/Chebyshev iteration assumes the fixed global matrix of the elastic terms. So, as in
//! the paper's Table 1 (`t_rho` apart from `t_e`) and in Macklin and Mueller's Algorithm 1
//! (constraints projected on the predicted positions), they are projected after the elastic
//! solve, before the velocities `(y - y_t) / h` are taken: the projection's moves become
//! velocity, as position-based dynamics asks.
//!
//! **Constraints.** `C_i = rho_i / rho0_i - 1` with the spiky kernel's lattice-normalised
//! density ([`crate::particles::sph`], support [`FLUID_SUPPORT`] spacings; the exact
//! gradient of the same sum, so each projection is a Newton step of its constraint), one-sided:
//! only `C_i > 0` is corrected, so that the free surface (where the sum misses neighbours)
//! does not pull particles into clumps (no artificial pressure `s_corr` is needed).
//! `lambda_i = -C_i / (sum_k w_k |grad_k C_i|^2 + eps)` (Macklin and Mueller, eq. 11, with
//! the inverse-mass weights of Macklin et al. 2014, "Unified particle physics", eq. 4) with
//! `eps = relaxation * D0`, `D0` that denominator at an interior particle of the rest lattice;
//! every particle moves by `dy_k = w_k sum_i lambda_i grad_k C_i` (eq. 12, all constraints at
//! once, Jacobi). `w_k = m_ref / m_k` is the member's inverse mass relative to the first fluid
//! particle's: 1 for every particle of a single liquid (the unweighted projection), smaller for
//! a heavier member (a sand grain, a denser fluid). Since a constraint's gradients sum to zero,
//! the weighted moves conserve momentum, `sum_k m_k dy_k = m_ref sum_i lambda_i sum_k grad_k
//! C_i = 0`; with equal moves, water shoved sand grains as easily as its own particles and
//! the pair's momentum changed. Then out of the colliders (normal projection, no friction: the elastic iteration's
//! collider pass carries the friction). The iterations stop when no particle is denser than
//! `rho0 (1 + tolerance)` or after `density_iterations` (the passes and the violation left
//! are reported in the step's particle figures). Pinned particles count in the densities and
//! do not move.
//!
//! **Two solvers** (`ViscoelasticFluid::density_solver`): the Jacobi projection above, or per
//! linearisation the coupled system of the active constraints by conjugate gradients
//! ([`super::density_system`]; a member pushed out of a wall slides along it in that solve).
//!
//! **Adhesion to ghost particles (the paper's section 6: "fixed ghost particles make a fluid
//! stick to a wall or ceiling"; `ViscoelasticFluid::adhesion`).** A ghost (a pinned fluid
//! particle of the stage) with a free fluid neighbour holds a two-sided constraint on its
//! density: where the liquid rests next to it, on its plain density `rho_i` at what that is
//! there, `C_i = rho_i / rho*_i - 1` ([`super::density_rest`]: exact at the walls' edges and
//! corners too); a ghost the liquid reaches later, on its density corrected for the
//! neighbours it misses at a free surface, `C_i = rho~_i / rho0_i - 1`, `rho~_i = rho_i + k
//! |M_i|^2` ([`crate::particles::sph_deficiency`]: on the flat face of a rest lattice `rho~ =
//! rho0` where `rho` is 0.85 `rho0`); with the exact gradients. It is corrected also where
//! negative, by [`ADHESION_STEP`] of the multiplier below. The ghost does not move, so its
//! constraint moves only its liquid neighbours: when the liquid draws away from the wall the
//! ghost's density falls and its constraint pulls the liquid back, as a wetting liquid does
//! not open a gap at a wall. Why a density constraint and not an attraction force: it is the
//! incompressibility the liquid already has (no strength or range of its own to choose), and
//! it acts only within the ghosts' kernel support. Why the corrected density where the liquid
//! does not rest: a ghost on the face of its wall misses the neighbours beyond it, and a
//! two-sided constraint asking `rho0` of the plain sum pulls the liquid into the wall; asked
//! of it where the liquid rests, it misses `rho0` at the walls' edges and corners (6.6 % on a
//! column's walls' top edge) and no step met it. Tried and dropped: the two-sided constraint on the
//! liquid's particles next to the ghosts instead (a honey blob's first layer slid off its
//! ceiling with the layers below), and the corrected density for every particle (it fills a
//! flat surface exactly but over-fills a disordered one: a dam break's front ran 12 % ahead
//! of Martin and Moyce at `T = 2`).
//!
//! **Why no warm start.** Starting a step from the last step's multipliers summed over its
//! passes (as DFSPH warm-starts its pressure) made a resting column explode within 10 steps:
//! with one-sided Jacobi passes the sum holds every pass's overshoot correction, not the net
//! pressure, and applying it again overshoots; clamping the sum at zero so that a light
//! particle gives its multiplier back makes the Jacobi iteration two-sided, and it diverges
//! on the short-wavelength modes that one-sided passes only leave expanded.

use std::time::Instant;

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::collider::{push_out_of_colliders, ColliderModel, MoveStart};
use crate::error::Result;
use crate::geometry::bounds::nan_max;
use crate::geometry::find_horizons;
use crate::parallel::for_each_vertex;
use crate::particles::redistribution::Redistribution;
use crate::particles::sph::{Kernel, Sph};
use crate::particles::sph_deficiency::Deficiency;
use crate::particles::{lattice_sum, DensitySolver, Particles, ViscoelasticFluid, FLUID_SUPPORT};
use crate::real::Real;
use crate::solve::points::Points;
use crate::solve::Timings;
use crate::timing::millis;

use super::density_rest::{adhered, GhostRest};
use super::density_system::{ConjugateGradients, DensitySystem};
use super::density_walls::{add_wall, none, release, slide, touching, Walls};
use super::fluid_viscosity::{lattice_laplacian_scale, Fluid, Viscosity};
use super::surface_tension::{gamma_per_tension, SurfaceTension};

#[path = "fluid_partners.rs"]
mod partners;
#[path = "fluid_pressure.rs"]
mod pressure;
#[path = "fluid_redistribution.rs"]
mod redistribution;

/// The fluid particles of a particle family and their constants.
pub(crate) struct FluidStage<T: Real> {
    /// The family index of each fluid particle.
    members: Vec<u32>,
    /// Per fluid particle: mass (kg), rest density `rho0` (kg/m^3), kinematic viscosity
    /// (m^2/s), `eps` (1/m^2) and the kernel of its body.
    mass: Vec<T>,
    rest_density: Vec<T>,
    nu: Vec<T>,
    eps: Vec<T>,
    sph: Sph,
    /// The free-surface correction of the constraints' densities.
    deficiency: Deficiency,
    iterations: usize,
    tolerance: f64,
    /// The density solver (conjugate gradients when a fluid of the stage asks for them).
    solver: DensitySolver,
    /// Neighbour lists of the last search (CSR over the members), and per entry `(i, j)` the
    /// index of the entry `(j, i)`.
    offsets: Vec<u32>,
    indices: Vec<u32>,
    mirror: Vec<u32>,
    /// Working positions (and the next ones), densities, multipliers and gradients of the
    /// members.
    y: Vec<Vector3<T>>,
    next: Vec<Vector3<T>>,
    density: Vec<T>,
    /// Each member's first moment `M_i` (kg/m^2, [`Deficiency::moment`]).
    moment: Vec<Vector3<T>>,
    /// Per member, whether its constraint is two-sided (adhesion: a ghost with a free fluid
    /// neighbour, see the module's doc), from the last search.
    adhered: Vec<bool>,
    /// Whether a fluid of the stage asks for adhesion to its ghosts.
    adhesion: bool,
    /// The adhered ghosts' rest densities ([`super::density_rest`]).
    ghost_rest: GhostRest<T>,
    /// Per member, the rest density its constraint asks for (kg/m^3): `rho0_i`, or the
    /// `rho*_i` of a ghost adhered now and at rest; and whether its constraint is on the
    /// corrected density `rho~_i` (a ghost adhered now but not at rest).
    target: Vec<T>,
    corrected: Vec<bool>,
    lambda: Vec<T>,
    /// Per member, its multipliers summed over the step's projection passes (m^2): each pass
    /// linearises at the moved positions and solves for the rest of the violation, so a
    /// pass's multipliers are an increment and the step's moves `W J^T sum lambda`. Not the
    /// redistribution's hold: its moves are taken out of the velocities. See [`pressure`].
    impulse: Vec<T>,
    /// The kernel's gradient consistency on the rest lattice (dimensionless,
    /// [`pressure::gradient_scale`]).
    pressure_scale: f64,
    /// Per member of the last linearisation: whether its constraint is active, the
    /// right-hand side `b_i` (relative density; 0 when inactive), the fraction `ask_i` of the
    /// violation it asks (`b_i = -ask_i C_i`: 1, or [`ADHESION_STEP`]) and the diagonal `A_ii`
    /// (1/m^2; the Jacobi's, with the pinned members' shares).
    active: Vec<bool>,
    rhs: Vec<T>,
    ask: Vec<T>,
    diagonal: Vec<T>,
    /// Per member, its mobility: its share, 0 when pinned (dimensionless).
    mobility: Vec<T>,
    /// Per member, the walls its conjugate-gradient moves slide on during this step
    /// ([`super::density_walls`]; found anew at each step's start, so nothing of them
    /// carries over to the next step or needs saving with a state).
    walls: Vec<Walls<T>>,
    /// The conjugate gradients' work vectors.
    cg: ConjugateGradients<T>,
    /// Projections of the last step and the violation they left ([`Self::violation`],
    /// relative).
    pub passes: usize,
    pub error: f64,
    grads: Vec<Vector3<T>>,
    own: Vec<Vector3<T>>,
    /// The time step of the current step (s).
    h: T,
    /// The neighbour search's and the viscosity's ms in [`Self::start_step`], which
    /// [`Self::project`] adds to the step's timings.
    start_millis: (f64, f64),
    viscosity: Viscosity<T>,
    /// Per member, the surface tension's coefficient `gamma` (N m^3/kg^2; 0: none, as for
    /// partners) until the stage is built, then the surface tension itself
    /// ([`super::surface_tension`]).
    gamma: Vec<f64>,
    tension: SurfaceTension<T>,
    /// Redistribution strength and passes (the largest asked by a fluid of the family), its
    /// buffers and each member's pin.
    redistribution: f64,
    redistribution_iterations: usize,
    redistributor: Redistribution<T>,
    fixed: Vec<bool>,
    /// Each member's displacement by the last redistribution (m; empty without).
    shift: Vec<Vector3<T>>,
    /// Per member, whether it is a partner: a solid particle the fluids meet
    /// ([`partners`]), in the density sums, without a constraint of its own.
    partner: Vec<bool>,
    /// Per member, its share of a constraint's correction: its inverse mass relative to the
    /// first fluid particle's, `w_k = m_ref / m_k` (dimensionless; 1 for every particle of a
    /// single fluid). Until the stage is built, the members' masses (kg).
    share: Vec<T>,
    /// Per member, the density (kg/m^3) the redistribution's hold bounds it by,
    /// `max(rho0_i, rho_i)` before the redistribution (`rho~_i` if adhered; see
    /// [`Self::hold_densities`]).
    ceiling: Vec<T>,
}

/// The fraction of its Newton step an adhered member's constraint takes where its density is
/// below rest (dimensionless; see the module's doc): two-sided constraints corrected at once
/// overshoot one another as one-sided ones do not; at the full step (tried on the liquid's
/// particles beside the ghosts) a hanging blob's constraints diverged within 10 steps, at
/// 0.25 a resting column between ghost walls and a blob under a ghost ceiling stay stable.
const ADHESION_STEP: f64 = 0.25;

/// The conjugate gradients stop once every linearised constraint is within this fraction of
/// the density tolerance (dimensionless): the relinearisation then sees the kernel's
/// nonlinearity and the colliders, not the linear solve's remainder.
const CG_RESIDUAL: f64 = 0.5;

/// The most conjugate-gradient iterations per linearisation (an inexact Newton step): the
/// active set, the walls and the kernel's curvature change as the liquid moves, so a
/// relinearisation gains more than a further iteration on the old system.
const CG_ITERATIONS: usize = 10;

/// How far (in spacings) beyond its collider margin a member counts as touching a wall at a
/// step's start ([`touching`]).
const WALL_PROBE: f64 = 0.01;

/// The denominator `sum_k |grad_k C_i|^2` (1/m^2) of an interior particle of the simple cubic
/// lattice of `spacing` (m) for the kernel `sph`: `sum_p |m grad W(p)|^2 / rho0^2` with
/// `m / rho0 = spacing^3` (the particle's own gradient is zero by symmetry).
fn lattice_denominator(sph: &Sph, spacing: f64) -> f64 {
    lattice_sum(sph.radius, spacing, |p| {
        (sph.gradient(&p) * spacing.powi(3)).norm_squared()
    })
}

impl<T: Real> FluidStage<T> {
    /// The fluid stage of the family of `bodies` (None when no body is a fluid). The bodies
    /// share one kernel: the first fluid's; a fluid of another spacing is refused.
    pub fn of(bodies: &[&mut Particles]) -> Result<Option<Self>> {
        let mut stage: Option<Self> = None;
        let mut start = 0u32;
        let mut spacing = 0.0;
        for body in bodies {
            let n = body.num_particles() as u32;
            if let Some(fluid) = body.fluid_material() {
                let s = body.params().spacing;
                let stage = match &mut stage {
                    Some(stage) => {
                        if s != spacing {
                            return Err(crate::error::invalid!(
                                "fluids in one solver must share a spacing: {s} m against {spacing} m"
                            ));
                        }
                        stage
                    }
                    None => {
                        spacing = s;
                        let sph = Sph::on_lattice(Kernel::Spiky, FLUID_SUPPORT * s, s)?;
                        let deficiency = Deficiency::on_lattice(&sph, s, body.particle_mass());
                        stage.insert(Self::new(sph, deficiency, s))
                    }
                };
                let fluid_particles =
                    (start..start + n).filter(|&k| body.is_fluid_particle((k - start) as usize));
                stage.add(body, fluid, fluid_particles);
            }
            start += n;
        }
        if let Some(stage) = &mut stage {
            stage.add_partners(bodies, spacing)?;
            if let Some(&reference) = stage.share.first() {
                for share in &mut stage.share {
                    *share = reference / *share;
                }
            }
            let reference: Vec<Vector3<f64>> = bodies
                .iter()
                .flat_map(|b| b.reference().iter().copied())
                .collect();
            let members = stage.members.iter().map(|&k| reference[k as usize]);
            stage.ghost_rest = GhostRest::new(members.collect());
            stage.target.clone_from(&stage.rest_density);
            let n = stage.members.len();
            stage.y = vec![Vector3::zeros(); n];
            stage.next = vec![Vector3::zeros(); n];
            stage.density = vec![T::zero(); n];
            stage.moment = vec![Vector3::zeros(); n];
            stage.lambda = vec![T::zero(); n];
            stage.impulse = vec![T::zero(); n];
            stage.active = vec![false; n];
            stage.rhs = vec![T::zero(); n];
            stage.ask = vec![T::one(); n];
            stage.diagonal = vec![T::zero(); n];
            stage.mobility = vec![T::zero(); n];
            stage.walls = vec![none(); n];
            stage.cg.resize(n);
            stage.own = vec![Vector3::zeros(); n];
            stage.viscosity = Viscosity::new(n, lattice_laplacian_scale(&stage.sph, spacing));
            let mut gamma = std::mem::take(&mut stage.gamma);
            gamma.resize(n, 0.0);
            stage.tension = SurfaceTension::new(gamma);
        }
        Ok(stage)
    }

    fn new(sph: Sph, deficiency: Deficiency, spacing: f64) -> Self {
        Self {
            pressure_scale: pressure::gradient_scale(&sph, spacing),
            members: Vec::new(),
            mass: Vec::new(),
            rest_density: Vec::new(),
            nu: Vec::new(),
            eps: Vec::new(),
            sph,
            deficiency,
            iterations: 1,
            tolerance: 1.0,
            solver: DensitySolver::Jacobi,
            offsets: vec![0],
            indices: Vec::new(),
            mirror: Vec::new(),
            y: Vec::new(),
            next: Vec::new(),
            density: Vec::new(),
            moment: Vec::new(),
            adhered: Vec::new(),
            adhesion: false,
            ghost_rest: GhostRest::default(),
            target: Vec::new(),
            corrected: Vec::new(),
            lambda: Vec::new(),
            impulse: Vec::new(),
            active: Vec::new(),
            rhs: Vec::new(),
            ask: Vec::new(),
            diagonal: Vec::new(),
            mobility: Vec::new(),
            walls: Vec::new(),
            cg: ConjugateGradients::default(),
            passes: 0,
            error: 0.0,
            grads: Vec::new(),
            own: Vec::new(),
            h: T::zero(),
            start_millis: (0.0, 0.0),
            viscosity: Viscosity::new(0, 1.0),
            gamma: Vec::new(),
            tension: SurfaceTension::new(Vec::new()),
            redistribution: 0.0,
            redistribution_iterations: 0,
            redistributor: Redistribution::default(),
            fixed: Vec::new(),
            shift: Vec::new(),
            partner: Vec::new(),
            share: Vec::new(),
            ceiling: Vec::new(),
        }
    }

    fn add(
        &mut self,
        body: &Particles,
        fluid: &ViscoelasticFluid,
        range: impl Iterator<Item = u32>,
    ) {
        let rho0 = body.density();
        let spacing = body.params().spacing;
        let eps = fluid.relaxation * lattice_denominator(&self.sph, spacing);
        let gamma = fluid.surface_tension
            * gamma_per_tension(self.sph.radius, spacing, body.particle_mass());
        for i in range {
            self.members.push(i);
            self.mass.push(T::of(body.particle_mass()));
            self.rest_density.push(T::of(rho0));
            self.nu.push(T::of(fluid.viscosity / rho0));
            self.eps.push(T::of(eps));
            self.partner.push(false);
            self.share.push(T::of(body.particle_mass()));
            self.gamma.push(gamma);
        }
        self.iterations = self.iterations.max(fluid.density_iterations);
        self.tolerance = self.tolerance.min(fluid.density_tolerance);
        self.redistribution = self.redistribution.max(fluid.redistribution);
        self.adhesion |= fluid.adhesion;
        if fluid.density_solver == DensitySolver::ConjugateGradients {
            self.solver = DensitySolver::ConjugateGradients;
        }
        if fluid.redistribution > 0.0 {
            self.redistribution_iterations = self
                .redistribution_iterations
                .max(fluid.redistribution_iterations);
        }
    }

    /// The stage's work before the prediction (see the module's doc): the neighbour search on
    /// the start positions `points.y_start`, the surface tension's kick `h f_i / m_i`
    /// ([`super::surface_tension`], when a fluid has one) and the implicit viscosity on the
    /// velocities with gravity's kick `h g` (`h` the step in s, `gravity` in m/s^2). The
    /// velocity stored is `u - h g`, so that the prediction `y_t + h v + h^2 g` that follows is
    /// `y_t + h u`. The surface tension is timed with the viscosity.
    pub fn start_step(&mut self, points: &mut Points<T>, h: T, gravity: Vector3<T>) -> Result<()> {
        self.h = h;
        let started = Instant::now();
        self.search(&points.y_start)?;
        self.start_millis.0 = millis(started);
        let started = Instant::now();
        let fluid = Fluid {
            sph: &self.sph,
            offsets: &self.offsets,
            indices: &self.indices,
            y: &self.y,
            mass: &self.mass,
            rest_density: &self.rest_density,
            nu: &self.nu,
            members: &self.members,
            partner: &self.partner,
            h,
        };
        if self.tension.any() {
            self.tension.apply(&fluid, points);
        }
        self.viscosity.apply(&fluid, points, gravity * h);
        self.start_millis.1 = millis(started);
        Ok(())
    }

    /// The ms of the last [`Self::start_step`] (neighbour search and viscosity), which
    /// [`Self::project`] reports under those phases.
    pub fn start_millis(&self) -> f64 {
        self.start_millis.0 + self.start_millis.1
    }

    /// The members' positions of `from` into `self.y` and their neighbour lists (CSR).
    fn search(&mut self, from: &[Vector3<T>]) -> Result<()> {
        for (y, &k) in self.y.iter_mut().zip(&self.members) {
            *y = from[k as usize];
        }
        let found = find_horizons(&self.y, self.sph.radius)?;
        found.mirrors_into(&mut self.mirror);
        self.offsets = found.offsets;
        self.indices = found.indices;
        self.grads.resize(self.indices.len(), Vector3::zeros());
        Ok(())
    }

    /// The stage's work before the velocities are taken (see the module's doc): the
    /// neighbour search and the density projections on `points.y`, `h` the step (s).
    pub fn project(
        &mut self,
        points: &mut Points<T>,
        h: T,
        colliders: &[ColliderModel<T>],
        timings: &mut Timings,
    ) -> Result<()> {
        self.h = h;
        let (search, viscosity) = std::mem::take(&mut self.start_millis);
        timings.viscosity += viscosity;
        let started = Instant::now();
        self.search(&points.y)?;
        self.find_adhered(&points.pinned);
        self.find_targets(&points.pinned)?;
        timings.neighbours += search + millis(started);
        let started = Instant::now();
        for ((w, &k), &share) in self.mobility.iter_mut().zip(&self.members).zip(&self.share) {
            *w = if points.pinned[k as usize] {
                T::zero()
            } else {
                share
            };
        }
        if self.solver == DensitySolver::ConjugateGradients {
            self.find_walls(points, colliders);
        }
        self.passes = 0;
        self.impulse.fill(T::zero());
        self.project_passes(points, colliders, self.iterations, self.solver, true);
        timings.density += millis(started);
        if self.redistribution > 0.0 {
            let started = Instant::now();
            self.redistribute(points, colliders)?;
            timings.redistribution += millis(started);
        }
        for (y, &k) in self.y.iter().zip(&self.members) {
            points.y[k as usize] = *y;
        }
        Ok(())
    }

    /// The density projection's passes from `self.passes` up to `self.iterations`, in at most
    /// `linearisations` linearisations by `solver`: linearise, solve for the multipliers, move,
    /// until the violation `self.error` is within the tolerance. (A Jacobi linearisation is one
    /// pass, a conjugate-gradient one up to [`CG_ITERATIONS`].) Each linearisation's
    /// multipliers add to `self.impulse` when `impulse` (the step's projection, not the
    /// redistribution's hold).
    fn project_passes(
        &mut self,
        points: &Points<T>,
        colliders: &[ColliderModel<T>],
        linearisations: usize,
        solver: DensitySolver,
        impulse: bool,
    ) {
        self.error = self.violation();
        let mut linearised = 0;
        while self.error > self.tolerance
            && self.passes < self.iterations
            && linearised < linearisations
        {
            self.linearise();
            linearised += 1;
            // At least one: a linearisation entered above the tolerance always iterates
            // (`ConjugateGradients::solve`), and the count bounds this loop regardless.
            self.passes += self.multipliers(solver).max(1);
            if impulse {
                (self.impulse.par_iter_mut().zip(&self.lambda)).for_each(|(sum, &l)| *sum += l);
            }
            self.take_moves(points, colliders, solver);
            self.error = self.violation();
        }
    }

    /// Marks the adhered members (see the module's doc) when a fluid of the stage asks for
    /// adhesion: ghosts (pinned members that are not partners) with a free fluid member
    /// (neither pinned nor a partner) among their neighbours of the last search.
    fn find_adhered(&mut self, pinned: &[bool]) {
        let (members, partner) = (&self.members, &self.partner);
        let (offsets, indices) = (&self.offsets, &self.indices);
        let wall = |i: usize| pinned[members[i] as usize] && !partner[i];
        let adhesion = self.adhesion;
        self.adhered.clear();
        self.adhered.extend(
            (0..members.len()).map(|i| adhesion && adhered(i, (offsets, indices), wall, partner)),
        );
    }

    /// Each member's constraint: its rest density `self.target` and whether it is on the
    /// corrected density (`self.corrected`): an adhered member asks its rest density `rho*_i`
    /// of its plain density if it is adhered at rest ([`super::density_rest`], found anew
    /// when the pins changed), else `rho0_i` of `rho~_i`; every other member `rho0_i` of
    /// `rho_i`.
    fn find_targets(&mut self, pinned: &[bool]) -> Result<()> {
        self.target.clone_from(&self.rest_density);
        self.corrected.clone_from(&self.adhered);
        if !self.adhesion {
            return Ok(());
        }
        let pins = self.members.iter().map(|&k| pinned[k as usize]);
        let (sph, mass) = (&self.sph, &self.mass);
        (self.ghost_rest).update(pins, sph, mass, &self.rest_density, &self.partner)?;
        let at_rest = self.ghost_rest.density().iter().zip(&self.adhered);
        let constraints = self.target.iter_mut().zip(&mut self.corrected);
        for ((target, corrected), (rest, _)) in constraints
            .zip(at_rest)
            .filter(|(_, (_, &adhered))| adhered)
        {
            if let Some(rest) = rest {
                (*target, *corrected) = (*rest, false);
            }
        }
        Ok(())
    }

    /// The largest violation of the constraints at `self.y` (relative): `C_i` where positive,
    /// and its magnitude at an adhered member; it also leaves the constraints' densities in
    /// `self.density` (`rho~_i` where [`Self::find_targets`] asks for it, else `rho_i`) and
    /// those members' moments in `self.moment`.
    fn violation(&mut self) -> f64 {
        let (sph, deficiency, y, mass) = (&self.sph, &self.deficiency, &self.y, &self.mass);
        let csr = (&self.offsets[..], &self.indices[..]);
        let corrected = &self.corrected;
        self.density
            .par_iter_mut()
            .zip(self.moment.par_iter_mut())
            .enumerate()
            .for_each(|(i, (rho, m))| {
                *rho = sph.density(i, y, csr.0, csr.1, mass);
                if corrected[i] {
                    *m = deficiency.moment(sph, i, y, csr, mass);
                    *rho = deficiency.corrected(*rho, m, mass[i]);
                }
            });
        let (density, rest, partner) = (&self.density, &self.target, &self.partner);
        let adhered = &self.adhered;
        (0..density.len())
            .into_par_iter()
            .map(|i| {
                let c = (density[i] / rest[i] - T::one()).to_f64();
                if partner[i] {
                    0.0
                } else if adhered[i] {
                    c.abs()
                } else {
                    c.max(0.0)
                }
            })
            .reduce(|| 0.0, nan_max)
    }

    /// The constraints linearised at `self.y` and the densities [`Self::violation`] left:
    /// each member's own gradient and its neighbours' (`own`, `grads`: of `rho_i` or `rho~_i`,
    /// not yet divided by the rest density), which constraints are active (`C_i > 0`, or adhered; partners
    /// carry none) and their right-hand sides `b_i = -ask_i C_i`: `ask_i` is 1, or
    /// [`ADHESION_STEP`] for an adhered member below rest.
    fn linearise(&mut self) {
        let (sph, deficiency, y, mass) = (&self.sph, &self.deficiency, &self.y, &self.mass);
        let (offsets, indices) = (&self.offsets, &self.indices);
        let (corrected, moment) = (&self.corrected, &self.moment);
        for_each_vertex(offsets, &mut self.grads, &mut self.own, &|i, row| {
            if corrected[i] {
                let csr = (&offsets[..], &indices[..]);
                deficiency.gradient(sph, i, y, csr, mass, &moment[i], row)
            } else {
                sph.density_gradient(i, y, offsets, indices, mass, row)
            }
        });
        let (density, rest, partner) = (&self.density, &self.target, &self.partner);
        let adhered = &self.adhered;
        (self.active.par_iter_mut())
            .zip(self.rhs.par_iter_mut().zip(self.ask.par_iter_mut()))
            .enumerate()
            .for_each(|(i, (active, (b, ask)))| {
                let c = density[i] / rest[i] - T::one();
                *active = (c > T::zero() || adhered[i]) && !partner[i];
                *ask = if *active && c <= T::zero() {
                    T::of(ADHESION_STEP)
                } else {
                    T::one()
                };
                *b = if *active { -c * *ask } else { T::zero() };
            });
    }

    /// The multipliers `lambda` of the last linearisation by `solver` ([`DensitySolver`]),
    /// and the passes they took: Jacobi, `lambda_i = b_i / A_ii` (Macklin and Mueller 2013,
    /// eq. 11, every member's share in `A_ii`), one pass; or the conjugate gradients on the
    /// coupled system ([`super::density_system`]) to within [`CG_RESIDUAL`] of the tolerance
    /// or [`CG_ITERATIONS`], one pass per iteration, then no pull beside a partner
    /// ([`Self::no_pull_beside_partners`]).
    fn multipliers(&mut self, solver: DensitySolver) -> usize {
        let mut lambda = std::mem::take(&mut self.lambda);
        let passes = if solver == DensitySolver::ConjugateGradients {
            let most = (self.iterations - self.passes).min(CG_ITERATIONS);
            let bound = CG_RESIDUAL * self.tolerance;
            let mut cg = std::mem::take(&mut self.cg);
            let rhs = (&self.rhs[..], &self.ask[..]);
            let done = cg.solve(&self.system(), rhs, &mut lambda, bound, most);
            self.cg = cg;
            self.no_pull_beside_partners(&mut lambda);
            done
        } else {
            let mut diagonal = std::mem::take(&mut self.diagonal);
            self.system().diagonal(&self.share, &mut diagonal);
            (lambda.par_iter_mut())
                .zip(self.rhs.par_iter().zip(&diagonal))
                .for_each(|(lambda, (&b, &d))| *lambda = b / d);
            self.diagonal = diagonal;
            1
        };
        self.lambda = lambda;
        passes
    }

    /// A conjugate-gradient multiplier that pulls (`lambda_i > 0`: the moves `W J^T lambda`
    /// draw row `i`'s neighbours towards it) set to 0 where a partner is among the
    /// neighbours (an adhered member's two-sided constraint aside). Why: a one-sided
    /// constraint `C_i <= 0` never pulls (its multiplier is a pressure; Jacobi's never does),
    /// but the solve holds its active set as equalities, and a row whose neighbours' pushes
    /// overshoot it pulls them back. A liquid neighbour so pulled is held by its own row; a
    /// partner has none, so nothing in the system answers the pull: liquid poured on a sand
    /// bed drew the bed's grains into itself and opened gaps in the bottom layer, down which
    /// water reached the ground (docs/particles/fluids.md). Rows among liquid alone keep their
    /// pulls: clamped everywhere, a deep liquid's solve no longer converged within its passes
    /// (docs/particles/performance.md).
    fn no_pull_beside_partners(&self, lambda: &mut [T]) {
        if !self.partner.contains(&true) {
            return;
        }
        let (offsets, indices, partner) = (&self.offsets, &self.indices, &self.partner);
        let adhered = &self.adhered;
        lambda.par_iter_mut().enumerate().for_each(|(i, lambda)| {
            let row = &indices[offsets[i] as usize..offsets[i + 1] as usize];
            if *lambda > T::zero() && !adhered[i] && row.iter().any(|&j| partner[j as usize]) {
                *lambda = T::zero();
            }
        });
    }

    /// The constraints linearised by [`Self::linearise`] (see [`super::density_system`]).
    fn system(&self) -> DensitySystem<'_, T> {
        DensitySystem {
            offsets: &self.offsets,
            indices: &self.indices,
            own: &self.own,
            grads: &self.grads,
            mirror: &self.mirror,
            rest: &self.target,
            eps: &self.eps,
            mobility: &self.mobility,
            walls: &self.walls,
            active: &self.active,
        }
    }

    /// Every member moved by `dy = W J^T lambda` (Macklin and Mueller 2013, eq. 12, with the
    /// mobilities), then out of the colliders. With the conjugate gradients (`solver`), first
    /// each wall the member's move leaves is released and the move slides along the others
    /// ([`super::density_walls`]); each collider that then pushes the move back adds a wall.
    fn take_moves(
        &mut self,
        points: &Points<T>,
        colliders: &[ColliderModel<T>],
        solver: DensitySolver,
    ) {
        let mut next = std::mem::take(&mut self.next);
        let mut walls = std::mem::take(&mut self.walls);
        let (system, lambda) = (self.system(), &self.lambda);
        let (y, members) = (&self.y, &self.members);
        let conjugate = solver == DensitySolver::ConjugateGradients;
        (next.par_iter_mut().zip(walls.par_iter_mut()))
            .enumerate()
            .for_each(|(i, (next, walls))| {
                let k = members[i] as usize;
                if points.pinned[k] {
                    *next = y[i];
                    return;
                }
                let mut dy = system.unslid(i, lambda);
                if conjugate {
                    release(walls, &dy);
                    dy = slide(walls, dy);
                }
                // Collider by collider, as `push_out_of_colliders` takes them, so that each
                // push's direction joins the member's walls.
                *next = dy + y[i];
                for c in Points::colliders_of(&points.collides, k, colliders) {
                    let free = *next;
                    let one = std::slice::from_ref(c);
                    *next = push_out_of_colliders(
                        one,
                        MoveStart::Now(y[i]),
                        free,
                        points.margin[k],
                        None,
                    );
                    if conjugate && *next != free {
                        add_wall(walls, *next - free);
                    }
                }
            });
        self.next = next;
        self.walls = walls;
        std::mem::swap(&mut self.y, &mut self.next);
    }

    /// Each member's walls at the step's start: those it touches ([`touching`], within
    /// [`WALL_PROBE`] spacings of its margin), found anew every step.
    fn find_walls(&mut self, points: &Points<T>, colliders: &[ColliderModel<T>]) {
        let depth = T::of(WALL_PROBE * self.sph.radius / FLUID_SUPPORT);
        let (y, members) = (&self.y, &self.members);
        (self.walls.par_iter_mut().enumerate()).for_each(|(i, walls)| {
            let k = members[i] as usize;
            let mine = Points::colliders_of(&points.collides, k, colliders);
            *walls = touching(mine, &y[i], points.margin[k], depth);
        });
    }
}
