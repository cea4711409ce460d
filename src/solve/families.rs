//! The families of one body list, one per body kind present, in a fixed order.

use crate::error::{invalid, Result};
use crate::real::Real;

use super::body::ByKind;
use super::family::Family;
use super::membranes::MembraneSystem;
use super::particles::ParticleSystem;
use super::SolverState;

/// The families of one body list: membranes first, then particles (the order of
/// [`Self::each`], of [`ByKind::list_indices`], of the updates and of the contact reactions).
pub(crate) struct Families<T: Real> {
    pub membranes: Option<MembraneSystem<T>>,
    pub particles: Option<ParticleSystem<T>>,
}

impl<T: Real> Families<T> {
    /// The families of `bodies`, their rest data in SIMD packs for the host kernel when
    /// `packed` (the CPU solver), else plain (for upload to a GPU).
    pub fn build(bodies: &ByKind<'_>, packed: bool) -> Result<Self> {
        let membranes = if bodies.membranes.is_empty() {
            None
        } else {
            Some(MembraneSystem::build(&bodies.membranes, packed)?)
        };
        let particles = if bodies.particles.is_empty() {
            None
        } else {
            Some(ParticleSystem::build(&bodies.particles)?)
        };
        Ok(Self {
            membranes,
            particles,
        })
    }

    /// True when the families were built from exactly these bodies ([`Self::hold`]) and the
    /// particles' rest data still serves them ([`ParticleSystem::matches`]).
    pub fn matches(&self, bodies: &ByKind<'_>) -> bool {
        self.hold(bodies)
            && self
                .particles
                .as_ref()
                .is_none_or(|p| p.matches(&bodies.particles))
    }

    /// True when the families were built from exactly these bodies, whatever their rest data
    /// since (a working set left stale by a failed step, bonds given from outside).
    pub fn hold(&self, bodies: &ByKind<'_>) -> bool {
        let membranes = match &self.membranes {
            Some(m) => m.points.matches(&bodies.membranes),
            None => bodies.membranes.is_empty(),
        };
        let particles = match &self.particles {
            Some(p) => p.holds(&bodies.particles),
            None => bodies.particles.is_empty(),
        };
        membranes && particles
    }

    /// Takes over the record of `old`, built for the same bodies ([`Self::hold`]), of the
    /// positions the last step that succeeded loaded ([`ParticleSystem::keep_placements`]).
    pub fn keep_placements(&mut self, old: &Self) {
        if let (Some(p), Some(old)) = (&mut self.particles, &old.particles) {
            p.keep_placements(old);
        }
    }

    /// Records the positions the step loaded as a step that succeeded's
    /// ([`ParticleSystem::settle`]).
    pub fn settle(&mut self) {
        if let Some(p) = &mut self.particles {
            p.settle();
        }
    }

    /// Checks a restored state's grain contacts against the particle family: some body must
    /// have contact friction to hold them (the rest is [`SolverState::check_against`]).
    pub fn check_restored(&self, state: &SolverState) -> Result<()> {
        let frictional = self
            .particles
            .as_ref()
            .is_some_and(ParticleSystem::has_friction);
        if state.grain_contacts.is_empty() || frictional {
            return Ok(());
        }
        Err(invalid!(
            "the restored state holds {} grain contacts with friction, but no particle body has \
             contact friction",
            state.grain_contacts.len()
        ))
    }

    /// Sets the grains' contact friction of a restored state (checked by
    /// [`Self::check_restored`]), before [`Self::load`], which drops the friction of a body
    /// whose positions were replaced: the next step starts from it.
    pub fn restore(&mut self, state: &SolverState) {
        if let Some(p) = &mut self.particles {
            p.restore_friction(&state.grain_contacts);
        }
    }

    /// Copies the bodies' positions, velocities and pins into their families (forgetting the
    /// grains' contact friction of a particle body whose positions were replaced, and taking
    /// a granular body's stiffness anew there): the
    /// particles in their own frame, unless membranes share the step with them (the
    /// coupling's pairs are measured in the world frame).
    pub fn load(&mut self, bodies: &ByKind<'_>) -> Result<()> {
        if let Some(m) = &mut self.membranes {
            m.points.load(&bodies.membranes);
        }
        if let Some(p) = &mut self.particles {
            p.load(&bodies.particles, self.membranes.is_none())?;
        }
        Ok(())
    }

    /// Copies the families' state back into the bodies (in f64), and the liquids' pressures.
    pub fn store(&self, bodies: &mut ByKind<'_>) {
        if let Some(m) = &self.membranes {
            m.points.store(&mut bodies.membranes);
        }
        if let Some(p) = &self.particles {
            p.points.store(&mut bodies.particles);
            if let Some(plastic) = &p.plastic {
                plastic.store(&mut bodies.particles);
            }
            if let Some(fluid) = &p.fluid {
                fluid.store_pressures(&p.points.ranges, &mut bodies.particles);
            }
        }
    }

    /// Every family, in a fixed order.
    pub fn each(&mut self) -> impl Iterator<Item = &mut dyn Family<T>> {
        let membranes = self.membranes.as_mut().map(|m| m as &mut dyn Family<T>);
        let particles = self.particles.as_mut().map(|p| p as &mut dyn Family<T>);
        membranes.into_iter().chain(particles)
    }
}
