//! The families of one body list, one per body kind present, in a fixed order.

use crate::error::Result;
use crate::real::Real;

use super::body::ByKind;
use super::family::Family;
use super::membranes::MembraneSystem;

/// The families of one body list.
pub(crate) struct Families<T: Real> {
    pub membranes: Option<MembraneSystem<T>>,
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
        Ok(Self { membranes })
    }

    /// True when the families were built from exactly these bodies.
    pub fn matches(&self, bodies: &ByKind<'_>) -> bool {
        match &self.membranes {
            Some(m) => m.points.matches(&bodies.membranes),
            None => bodies.membranes.is_empty(),
        }
    }

    /// Copies the bodies' positions, velocities and pins into their families.
    pub fn load(&mut self, bodies: &ByKind<'_>) {
        if let Some(m) = &mut self.membranes {
            m.points.load(&bodies.membranes);
        }
    }

    /// Copies the families' state back into the bodies (in f64).
    pub fn store(&self, bodies: &mut ByKind<'_>) {
        if let Some(m) = &self.membranes {
            m.points.store(&mut bodies.membranes);
        }
    }

    /// Every family, in a fixed order.
    pub fn each(&mut self) -> impl Iterator<Item = &mut dyn Family<T>> {
        self.membranes
            .as_mut()
            .map(|m| m as &mut dyn Family<T>)
            .into_iter()
    }
}
