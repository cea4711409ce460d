//! The end of a step for plastic particle bodies (He et al. 2017, section 5): once the
//! local-global solve has finished, as the paper does it, the return of eq. 18-19 moves the
//! reference bonds of the particles that yield, then the neighbours of bodies that ask for
//! it are searched on the deformed positions (eq. 20), and the rest data the next step
//! solves with is rebuilt from the new bonds. Each phase is timed (`Timings::plasticity`,
//! `Timings::neighbours`: the columns `t_p` and `t_n` of the paper's Table 1).
//!
//! The bonds of every body of the family are kept here in f64 (the master copy, whatever the
//! solver's precision), and the plastic bodies' go back into the bodies with their state
//! ([`PlasticBodies::store`]). An elastic body's bonds are never changed: its rest data comes
//! out of the rebuild bit for bit as before.

use std::ops::Range;
use std::time::Instant;

use nalgebra::Vector3;

use crate::error::Result;
use crate::particles::{
    rebuild_neighbours, ParticleRest, Particles, PlasticLaw, RestBonds, RestConstants,
};
use crate::real::Real;
use crate::solve::Timings;
use crate::timing::millis;

/// One body of the family as the plastic end of a step sees it.
struct Entry {
    bonds: RestBonds,
    constants: RestConstants,
    /// `None` for an elastic body.
    law: Option<PlasticLaw>,
    /// The body's particles in the family.
    range: Range<usize>,
}

/// Every body's bonds, when at least one body of the family is plastic.
pub(crate) struct PlasticBodies {
    entries: Vec<Entry>,
    /// The family's positions in f64 (reused).
    y: Vec<Vector3<f64>>,
}

impl PlasticBodies {
    /// The bonds of `bodies`, or `None` when none is plastic (nothing to do at a step's end).
    pub fn of(bodies: &[&mut Particles]) -> Option<Self> {
        if bodies.iter().all(|b| b.plasticity().is_none()) {
            return None;
        }
        let mut start = 0;
        let entries = bodies
            .iter()
            .map(|b| {
                let range = start..start + b.num_particles();
                start = range.end;
                Entry {
                    bonds: b.current_rest_bonds(),
                    constants: RestConstants::of(b),
                    law: PlasticLaw::of(b),
                    range,
                }
            })
            .collect();
        Some(Self {
            entries,
            y: vec![Vector3::zeros(); start],
        })
    }

    /// The plastic end of a step at the finished positions `y` (m; see the module's doc): the
    /// family's new rest data, and whether some neighbourhood changed (then the bond count
    /// and the global matrix's pattern may have too); `None` when no particle yielded and no
    /// neighbourhood changed, so the rest data at hand stands.
    pub fn end_step<T: Real>(
        &mut self,
        y: &[Vector3<T>],
        timings: &mut Timings,
    ) -> Result<Option<(ParticleRest<T>, bool)>> {
        let t = Instant::now();
        for (mine, p) in self.y.iter_mut().zip(y) {
            *mine = p.map(|c| c.to_f64());
        }
        let y = &self.y;
        let mut yielded = 0;
        for entry in &mut self.entries {
            if let Some(law) = &entry.law {
                yielded += law.apply(&mut entry.bonds, &y[entry.range.clone()]);
            }
        }
        timings.plasticity += millis(t);
        let t = Instant::now();
        let mut changed = false;
        for entry in &mut self.entries {
            let Some(law) = entry.law.filter(|l| l.law.rebuild_neighbours) else {
                continue;
            };
            let y = &y[entry.range.clone()];
            if let Some(bonds) = rebuild_neighbours(&entry.bonds, y, law.delta, law.volume)? {
                entry.bonds = bonds;
                changed = true;
            }
        }
        timings.neighbours += millis(t);
        if yielded == 0 && !changed {
            return Ok(None);
        }
        let t = Instant::now();
        let sources: Vec<(&RestBonds, RestConstants)> = self
            .entries
            .iter()
            .map(|e| (&e.bonds, e.constants))
            .collect();
        let rest = ParticleRest::of_bonds(&sources)?;
        timings.plasticity += millis(t);
        Ok(Some((rest, changed)))
    }

    /// Writes the plastic bodies' bonds back into them.
    pub fn store(&self, bodies: &mut [&mut Particles]) {
        for (entry, body) in self.entries.iter().zip(bodies) {
            if entry.law.is_some() {
                body.set_rest_bonds(entry.bonds.clone());
            }
        }
    }
}
