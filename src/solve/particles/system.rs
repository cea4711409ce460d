//! The particle family's working set: every particle body's rest data and state concatenated
//! into one particle range, the kernel's evaluations and the global step's buffers, all
//! allocated once so that the iteration allocates nothing.

use std::time::Instant;

use nalgebra::Vector3;

use crate::error::Result;
use crate::particles::{ParticleRest, Particles};
use crate::real::Real;
use crate::solve::frame::origin_near;
use crate::solve::points::Points;
use crate::solve::SavedGrainContact;
use crate::solve::{ParticleTimings, Timings};
use crate::timing::millis;

use super::chebyshev::Chebyshev;
use super::coarse_problem::Coarse;
use super::direct::DirectSolver;
use super::evaluation::Evaluation;
use super::exact_iterate::ExactIterates;
use super::fluid::FluidStage;
use super::plastic::PlasticBodies;
use super::repulsion::Repulsion;
use super::static_friction::StaticFriction;
use super::two_level::TwoLevel;

/// The particle family's working set.
pub(crate) struct ParticleSystem<T: Real> {
    pub points: Points<T>,
    pub rest: ParticleRest<T>,
    /// The evaluation at the current iterate, and a line search's trial (between trials, the
    /// evaluation before the current one, [`Self::evaluate`]).
    pub current: Evaluation<T>,
    pub trial: Evaluation<T>,
    /// The global step's move and a Jacobi sweep's scratch (m).
    pub delta: Vec<Vector3<T>>,
    pub scratch: Vec<Vector3<T>>,
    /// The factored global matrix, once the direct solver was asked for; the particles it
    /// holds this step (pins and collider contacts, [`super::step`]), and a failure of its
    /// factorisation, reported at the end of the step.
    pub direct: Option<DirectSolver>,
    pub held: Vec<bool>,
    /// The particles a collider or the repulsion moved in the step's last trial
    /// ([`super::step`]; empty at the step's start).
    pub touched: Vec<bool>,
    /// The step's Chebyshev sequence, which the line search restarts ([`super::chebyshev`]),
    /// and its iterates before rounding ([`super::exact_iterate`]).
    pub chebyshev: Chebyshev,
    pub exact: ExactIterates,
    pub failure: Option<crate::error::Error>,
    /// The minimum distance between bodies (none for a single body).
    pub repulsion: Option<Repulsion<T>>,
    /// Partial sums of the merit (reused).
    pub chunks: Vec<f64>,
    /// Every body's bonds when some body is plastic ([`super::plastic`]).
    pub plastic: Option<PlasticBodies>,
    /// The fluid particles' density projection and viscosity ([`super::fluid`]).
    pub fluid: Option<FluidStage<T>>,
    /// The step's phases so far ([`crate::solve::StepStats::particles`]).
    pub timings: ParticleTimings,
    /// The coarse problem on the bodies' translations ([`super::coarse`], [`super::coarse_problem`]; reused).
    pub coarse: Coarse,
    /// The two-level correction of the Jacobi sweep on aggregates ([`super::two_level`]),
    /// once a step asked for it and some body takes part.
    pub two_level: Option<TwoLevel>,
    /// The granular bodies' static friction (eq. 28), if any has it.
    pub static_friction: Option<StaticFriction<T>>,
    /// Per particle, whether it yielded at the end of the last step (reused).
    yielded: Vec<bool>,
    /// Each body's [`Particles::bonds_revision`] when this working set was built.
    revisions: Vec<u64>,
    /// Each body's [`Particles::positions_revision`] when a step that succeeded loaded it
    /// ([`Self::settle`]), and when the last step did ([`Self::load`]): a failed step leaves
    /// the first, so that the next one drops the friction and takes the stiffness again.
    placements: Vec<u64>,
    loaded: Vec<u64>,
    /// Per body, whether the last [`Self::load`] found its positions replaced (reused).
    replaced: Vec<bool>,
    /// Whether the rest data was left partly built by a failed end of a step.
    stale: bool,
    /// Whether the initial guess's next evaluation at the prediction `y*` takes the energy
    /// alone ([`Self::evaluate_energy`]): it does when the last one was not kept (a resting
    /// body, whose start `y_t` has the lower energy), and it is whole when the last one was (a
    /// body in flight, which moves from `y*`).
    energy_alone: bool,
    /// Whether the evaluation at the iterate is the initial guess's at `y*`, not yet known
    /// to be kept or dropped ([`Self::evaluate`] learns which).
    probing: bool,
}

impl<T: Real> ParticleSystem<T> {
    /// The working set of `bodies`, their rest data computed here (state is loaded by
    /// [`Points::load`]).
    pub fn build(bodies: &[&mut Particles]) -> Result<Self> {
        let shared: Vec<&Particles> = bodies.iter().map(|b| &**b).collect();
        let rest = ParticleRest::<T>::of_bodies(&shared)?;
        let (n, bonds) = (rest.len(), rest.indices.len());
        let mut points = Points::new(bodies, rest.mass.clone(), rest.margin.clone());
        points.collides.clone_from(&rest.collides);
        let within = bodies.iter().map(|b| b.granular().is_some()).collect();
        let fluid: Vec<bool> = bodies
            .iter()
            .flat_map(|b| {
                let mixed = b.fluid_mask().is_some();
                (0..b.num_particles()).map(move |i| mixed && b.is_fluid_particle(i))
            })
            .collect();
        let friction: Vec<f64> = bodies
            .iter()
            .map(|b| b.granular().map_or(0.0, |g| g.contact_friction))
            .collect();
        let rolling: Vec<Option<f64>> = bodies
            .iter()
            .map(|b| b.granular().and_then(|g| g.rolling_resistance))
            .collect();
        let solid: Vec<bool> = bodies
            .iter()
            .map(|b| {
                b.granular().is_none() && !(0..b.num_particles()).any(|i| b.is_fluid_particle(i))
            })
            .collect();
        let repulsion = Repulsion::of(&points, within, &fluid).map(|r| {
            r.with_friction(&friction)
                .with_rolling(&rolling)
                .with_solid(&solid)
        });
        Ok(Self {
            points,
            rest,
            current: Evaluation::new(n, bonds),
            trial: Evaluation::new(n, bonds),
            delta: vec![Vector3::zeros(); n],
            scratch: vec![Vector3::zeros(); n],
            repulsion,
            direct: None,
            held: vec![false; n],
            touched: vec![false; n],
            chebyshev: Chebyshev::default(),
            exact: ExactIterates::new(n),
            failure: None,
            chunks: Vec::new(),
            plastic: PlasticBodies::of(bodies),
            fluid: FluidStage::of(bodies)?,
            static_friction: StaticFriction::of(bodies),
            coarse: Coarse::new(solid),
            two_level: None,
            yielded: vec![false; n],
            timings: ParticleTimings::default(),
            revisions: bodies.iter().map(|b| b.bonds_revision()).collect(),
            placements: bodies.iter().map(|b| b.positions_revision()).collect(),
            loaded: bodies.iter().map(|b| b.positions_revision()).collect(),
            replaced: vec![false; bodies.len()],
            stale: false,
            energy_alone: false,
            probing: false,
        })
    }

    /// True when the working set was built for exactly these bodies ([`Self::holds`]) with
    /// the bonds they have (none was given bonds from outside since), and the rest data is
    /// whole.
    pub fn matches(&self, bodies: &[&mut Particles]) -> bool {
        !self.stale
            && self.holds(bodies)
            && self
                .revisions
                .iter()
                .zip(bodies)
                .all(|(&r, b)| r == b.bonds_revision())
    }

    /// True when the working set was built for exactly these bodies (whatever their bonds
    /// and its rest data since).
    pub fn holds(&self, bodies: &[&mut Particles]) -> bool {
        self.points.matches(bodies)
    }

    /// Takes over `old`'s record of the positions the last step that succeeded loaded
    /// ([`Self::settle`]), `old` built for the same bodies ([`Self::holds`]): a working set
    /// built anew for them still drops the friction of a body whose positions were replaced
    /// since (a restored state's, [`Self::load`]).
    pub fn keep_placements(&mut self, old: &Self) {
        self.placements.clone_from(&old.placements);
    }

    /// Copies the bodies' positions, velocities and pins in ([`Points::load`]), in the
    /// family's own frame when `own_frame` ([`origin_near`] the bodies), else in the world's
    /// (the coupling with membranes measures both families' positions from one origin); the
    /// contact friction of a body whose positions were replaced since the last step that
    /// succeeded starts from 0 ([`Repulsion::forget_friction`], after a restored state's is
    /// set), and such a granular body's stiffness is taken anew at the positions loaded
    /// ([`PlasticBodies::restiffen`]; an error leaves the working set to be built anew).
    pub fn load(&mut self, bodies: &[&mut Particles], own_frame: bool) -> Result<()> {
        self.points.origin = if own_frame {
            let positions = bodies.iter().flat_map(|b| b.positions().iter());
            origin_near(positions)
        } else {
            Vector3::zeros()
        };
        self.points.load(bodies);
        for ((((placed, loaded), replaced), body), range) in self
            .placements
            .iter()
            .zip(&mut self.loaded)
            .zip(&mut self.replaced)
            .zip(bodies)
            .zip(&self.points.ranges)
        {
            *loaded = body.positions_revision();
            *replaced = *placed != *loaded;
            if let (true, Some(repulsion)) = (*replaced, &mut self.repulsion) {
                repulsion.forget_friction(range.clone());
            }
        }
        let any = self.replaced.contains(&true);
        if let (true, Some(plastic)) = (any, self.plastic.as_mut()) {
            let restiffened = plastic.restiffen(bodies, &self.replaced, &mut self.rest);
            if restiffened.is_err() {
                self.stale = true;
            }
            if restiffened? {
                self.rest_values_changed();
            }
        }
        Ok(())
    }

    /// Records the positions the step loaded as the ones a step that succeeded took.
    pub fn settle(&mut self) {
        self.placements.copy_from_slice(&self.loaded);
    }

    /// The grains' contact friction the next step starts from ([`Repulsion::saved_friction`]).
    pub fn saved_friction(&self) -> Vec<SavedGrainContact> {
        self.repulsion
            .as_ref()
            .map_or_else(Vec::new, Repulsion::saved_friction)
    }

    /// Drops from `contacts` those of a body whose positions were replaced since the last
    /// step that succeeded, `revisions` each body's [`Particles::positions_revision`] now:
    /// the next step starts them from 0 ([`Self::load`]). Nothing when `revisions` is not
    /// one per body (a body list the next step builds anew for).
    pub fn forget_replaced(&self, revisions: &[u64], contacts: &mut Vec<SavedGrainContact>) {
        if revisions.len() != self.placements.len() {
            return;
        }
        let replaced = |i: u32| {
            let body = self.points.locate(i as usize).0;
            self.placements[body] != revisions[body]
        };
        contacts.retain(|c| !c.particles.iter().any(|&i| replaced(i)));
    }

    /// Whether some body has contact friction between its grains.
    pub fn has_friction(&self) -> bool {
        self.repulsion.as_ref().is_some_and(Repulsion::has_friction)
    }

    /// Restores the grains' contact friction of [`Self::saved_friction`] (checked beforehand:
    /// distinct pairs of this family's particles).
    pub fn restore_friction(&mut self, contacts: &[SavedGrainContact]) {
        if let Some(repulsion) = &mut self.repulsion {
            repulsion.restore_friction(contacts);
        }
    }

    /// The kernel at the current iterate `y`, unless one of the two evaluations held is there
    /// already: the current one (a line search's accepted trial), or the other, which keeps
    /// the one before it. The other serves the initial guess ([`crate::solve::sissm`]), which
    /// evaluates the prediction `y*` first and then the step's start `y_t`, where the last
    /// step's accepted trial was taken (the positions' bits are the key, and the kernel
    /// depends on nothing else but the rest data, whose changes clear both). An evaluation
    /// at `y` that holds the energy alone ([`Self::evaluate_energy`]) is completed.
    pub fn evaluate(&mut self) {
        if std::mem::take(&mut self.probing) {
            self.energy_alone = !self.current.holds_energy_at(&self.points.y);
        }
        if self.current.is_at(&self.points.y) {
            return;
        }
        std::mem::swap(&mut self.current, &mut self.trial);
        if self.current.is_at(&self.points.y) {
            return;
        }
        let started = Instant::now();
        self.current.at.copy_from_slice(&self.points.y);
        self.current.run(&self.rest);
        self.timings.kernel += millis(started);
        self.timings.evaluations += 1;
    }

    /// The energies at the current iterate, for a caller that reads
    /// [`crate::solve::family::Family::total_energy`] before it evaluates elsewhere or moves
    /// (the initial guess at `y*`): the energy alone ([`Evaluation::run_energy`], no bond
    /// force written, bit for bit the whole kernel's energies) when the last such evaluation
    /// was not kept and no body has cones, else the whole kernel ([`Self::evaluate`]). The
    /// next [`Self::evaluate`] or [`Self::complete`] completes it if it is kept.
    pub fn evaluate_energy(&mut self) {
        let y = &self.points.y;
        let alone = self.energy_alone
            && self.rest.cones.is_empty()
            && !self.current.is_at(y)
            && !self.trial.is_at(y);
        if alone {
            std::mem::swap(&mut self.current, &mut self.trial);
            let started = Instant::now();
            self.current.at.copy_from_slice(&self.points.y);
            self.current.run_energy(&self.rest);
            self.timings.kernel += millis(started);
            self.timings.evaluations += 1;
        } else {
            self.evaluate();
        }
        self.probing = true;
    }

    /// Readies the evaluation at the current iterate for a move: completes one that holds the
    /// energy alone ([`Self::evaluate_energy`]); nothing otherwise.
    pub fn complete(&mut self) {
        if self.probing || !self.current.has_forces() {
            self.evaluate();
        }
    }

    /// The plastic end of a step ([`super::plastic`]): the rest data rebuilt from the returned
    /// bonds; the evaluations start afresh. When a neighbourhood changed, the bonds are
    /// renumbered and the global matrix's pattern may have changed: the direct solver and the
    /// two-level correction are built anew. Otherwise only values did (a granular body's
    /// stiffness, eq. 25-27; a flowing body's re-anchored bonds): the direct solver refactors
    /// numerically on its pattern ([`DirectSolver::values_changed`]), and the two-level
    /// correction stands, since no plastic, granular or fluid body takes part in it and an
    /// elastic body's rest data comes out of the rebuild bit for bit ([`super::two_level`],
    /// "Aggregates"). Nothing when no body is plastic, or no particle yielded, no
    /// neighbourhood changed and no body is granular.
    ///
    /// Between the returns and the rebuild, the static friction of granular bodies (eq. 28,
    /// [`super::static_friction`]) holds the particles that did not yield or whose contacts
    /// can hold them.
    pub(crate) fn plastic_end_step(&mut self, timings: &mut Timings) -> Result<()> {
        let Some(plastic) = self.plastic.as_mut() else {
            return Ok(());
        };
        self.yielded.fill(false);
        let yielded = plastic.returns(&self.points.y, &mut self.yielded, timings);
        if let Some(friction) = &self.static_friction {
            let repulsion = self.repulsion.as_ref();
            let sticks = |margin: &[T], i: usize, moved: &Vector3<T>, inertial: T| {
                repulsion.is_some_and(|r| r.sticks(margin, i, moved, inertial))
            };
            self.timings.held_static = friction.apply(&mut self.points, &self.yielded, &sticks);
        }
        let rebuilt = plastic.rebuild(&self.points.y, yielded, &mut self.rest, timings);
        // A failed refill leaves the rest data partly built: the next step builds the
        // working set anew from the bodies, which kept their bonds.
        self.stale = rebuilt.is_err();
        let Some(changed) = rebuilt? else {
            return Ok(());
        };
        if changed {
            let bonds = self.rest.indices.len();
            self.current.resize_bonds(bonds);
            self.trial.resize_bonds(bonds);
            // The step's counts, before the solvers that hold them go.
            self.count_factorizations();
            self.direct = None;
            self.two_level = None;
        } else {
            self.rest_values_changed();
        }
        Ok(())
    }

    /// After the rest data's values changed on the same bonds: the evaluations cached at the
    /// old values go, and the direct solver refactors ([`DirectSolver::values_changed`]).
    fn rest_values_changed(&mut self) {
        self.current.valid = false;
        self.trial.valid = false;
        if let Some(direct) = &mut self.direct {
            direct.values_changed();
        }
    }

    /// Adds the direct solver's and the two-level correction's symbolic analyses and numeric
    /// factorisations since the last call to the step's counts.
    pub fn count_factorizations(&mut self) {
        let direct = self.direct.as_mut().map(DirectSolver::take_counts);
        let two_level = self.two_level.as_mut().map(TwoLevel::take_counts);
        for (analyses, factorizations) in direct.into_iter().chain(two_level) {
            self.timings.analyses += analyses;
            self.timings.factorizations += factorizations;
        }
    }

    /// Leaves the rest data as a failed end of a step does ([`Self::plastic_end_step`]): the
    /// next step builds the working set anew.
    #[cfg(test)]
    pub(crate) fn make_stale(&mut self) {
        self.stale = true;
    }

    /// The Jacobi diagonal `D_i = m_i + h^2 L_ii` (kg) of particle `i` ([`ParticleRest::diagonal`]).
    #[inline(always)]
    pub fn diagonal(&self, i: usize, h2: T) -> T {
        self.rest.diagonal(i, h2)
    }
}
