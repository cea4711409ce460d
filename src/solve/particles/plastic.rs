//! The end of a step for plastic particle bodies (He et al. 2017, section 5): once the
//! local-global solve has finished, as the paper does it, the return of eq. 18-19 moves the
//! reference bonds of the particles that yield (the kernel took the same return within the
//! iterations, from the same bonds: [`crate::particles::Cone`]; here it is stored,
//! and decides which particles static friction may hold), then the neighbours of bodies that ask for
//! it are searched on the deformed positions (eq. 20), and the rest data the next step
//! solves with is rebuilt from the new bonds, with a granular body's stiffness from its SPH
//! density on the new neighbours (eq. 25-27, [`crate::particles::Granular`]) after the water
//! its grains hold wicked along them over the step ([`crate::particles::Wicking`], timed
//! with the density). Each phase is timed (`Timings::plasticity`, `Timings::neighbours`,
//! `Timings::density`: the columns `t_p`, `t_n` and `t_d` of the paper's Table 1).
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
    density_ratios, rebuild_neighbours, wetted, ParticleRest, Particles, PlasticLaw, RestBonds,
    RestConstants, Wicking,
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
    /// A granular body's `lam` per particle (Pa) from its density at the end of the last
    /// step (empty for other bodies).
    lam: Vec<f64>,
    /// A sand body's saturation per particle once a liquid wetted it (empty before:
    /// the material's; [`crate::particles::wetted`]).
    wetted: Vec<f64>,
    /// A plastic body's volume per particle over its rest volume at the step's positions
    /// with the step's bonds ([`PlasticLaw::apply`]; reused, empty for an elastic body), which
    /// a body whose return keeps the rest volume keeps across its new bonds.
    volumes: Vec<f64>,
    /// A sand body's capillary wicking of its held water, when its diffusivity is not 0.
    wicking: Option<Wicking>,
}

impl Entry {
    /// A wetted sand body's cohesion per particle (Pa; [`crate::particles::wetted`]), or
    /// `None` for the law's own.
    fn cohesions(&self) -> Option<Vec<f64>> {
        self.constants
            .granular
            .filter(|_| !self.wetted.is_empty())
            .map(|g| g.cohesions(&self.wetted))
    }
}

/// Every body's bonds, when at least one body of the family is plastic.
pub(crate) struct PlasticBodies {
    entries: Vec<Entry>,
    /// The family's positions in f64 (reused).
    y: Vec<Vector3<f64>>,
    /// The time step (s) the wicking moves the held water over ([`Self::start_step`]).
    dt: f64,
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
                    lam: Vec::new(),
                    wetted: b.wetted().map_or_else(Vec::new, <[f64]>::to_vec),
                    volumes: Vec::new(),
                    wicking: b
                        .granular()
                        .and_then(|g| Wicking::new(g.wicking, b.horizon(), b.params().spacing)),
                }
            })
            .collect();
        Some(Self {
            entries,
            y: vec![Vector3::zeros(); start],
            dt: 0.0,
        })
    }

    /// Readies the step of `dt` (s), the laws' returns too.
    pub fn start_step(&mut self, dt: f64) {
        self.dt = dt;
        for entry in &mut self.entries {
            entry.law = entry.law.map(|law| law.at_step(dt));
        }
    }

    /// Whether body `b` of the family is plastic (has a yield law).
    pub fn is_plastic(&self, b: usize) -> bool {
        self.entries[b].law.is_some()
    }

    /// The returns of eq. 18-19 at the solved positions `y` (m), the first half of the
    /// plastic end of a step: marks in `yielded` (one flag per particle of the family) the
    /// particles that yielded, and returns how many did.
    pub fn returns<T: Real>(
        &mut self,
        y: &[Vector3<T>],
        yielded: &mut [bool],
        timings: &mut Timings,
    ) -> usize {
        let t = Instant::now();
        self.copy_positions(y);
        let mut count = 0;
        for entry in &mut self.entries {
            if let Some(law) = &entry.law {
                let (y, marks) = (
                    &self.y[entry.range.clone()],
                    &mut yielded[entry.range.clone()],
                );
                let cohesion = entry.cohesions();
                count += law.apply(
                    &mut entry.bonds,
                    y,
                    marks,
                    cohesion.as_deref(),
                    &mut entry.volumes,
                );
            }
        }
        timings.plasticity += millis(t);
        count
    }

    fn copy_positions<T: Real>(&mut self, y: &[Vector3<T>]) {
        for (mine, p) in self.y.iter_mut().zip(y) {
            *mine = p.map(|c| c.to_f64());
        }
    }

    /// The second half of the plastic end of a step, at the step's final positions `y` (m;
    /// see the module's doc), after `yielded` particles yielded in [`Self::returns`]: the
    /// family's new rest data, refilled into `rest` in place, and whether some neighbourhood
    /// changed (then the bond count and the global matrix's pattern may have too; otherwise
    /// the bonds are the same pairs in the same order, and only values changed); `None`
    /// when no particle yielded, no neighbourhood changed and no body is granular, so the rest
    /// data at hand stands. On an error `rest` is partly filled and must be built anew.
    pub fn rebuild<T: Real>(
        &mut self,
        y: &[Vector3<T>],
        yielded: usize,
        rest: &mut ParticleRest<T>,
        timings: &mut Timings,
    ) -> Result<Option<bool>> {
        self.copy_positions(y);
        let y = &self.y;
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
        let t = Instant::now();
        let mut granular = false;
        for entry in &mut self.entries {
            if let Some(material) = entry.constants.granular {
                let y = &y[entry.range.clone()];
                if let (Some(wicking), false) = (&mut entry.wicking, entry.wetted.is_empty()) {
                    wicking.wick(&entry.bonds, y, &mut entry.wetted, self.dt)?;
                }
                let ratios = density_ratios(
                    &entry.bonds,
                    y,
                    entry.constants.delta,
                    entry.constants.volume,
                )?;
                entry.lam = match entry.wetted.as_slice() {
                    [] => material.stiffness_of(&ratios),
                    theta => material.wet_stiffness_of(&ratios, theta),
                };
                granular = true;
            }
        }
        timings.density += millis(t);
        if yielded == 0 && !changed && !granular {
            return Ok(None);
        }
        let t = Instant::now();
        for entry in &mut self.entries {
            if let Some(law) = entry.law.filter(|l| l.anchored) {
                let y = &y[entry.range.clone()];
                // Bonds born anew change the springs, and with them the global matrix's values
                // (its pattern only where the neighbourhood changed, above).
                law.reanchor(&mut entry.bonds, y, &mut entry.volumes);
            }
        }
        self.refill(rest)?;
        timings.plasticity += millis(t);
        Ok(Some(changed))
    }

    /// Takes the stiffness (eq. 25-27) of every granular body whose positions were replaced
    /// from outside (`replaced`, per body) from its density at its own positions in `bodies`
    /// (m, f64, in the world frame), as building the working set from the bodies does (a
    /// solver given these bodies afresh, a restored run, takes the same bits), and refills
    /// `rest` with it: the stiffness the last step ended with belongs to other positions. The
    /// other bodies keep the stiffness the last step ended with. `false` (nothing changed)
    /// when no replaced body is granular. On an error `rest` may be partly filled and must
    /// be built anew.
    pub fn restiffen<T: Real>(
        &mut self,
        bodies: &[&mut Particles],
        replaced: &[bool],
        rest: &mut ParticleRest<T>,
    ) -> Result<bool> {
        let mut granular = false;
        for ((entry, body), _) in self
            .entries
            .iter_mut()
            .zip(bodies)
            .zip(replaced)
            .filter(|(_, &replaced)| replaced)
        {
            let Some(material) = entry.constants.granular else {
                continue;
            };
            let (delta, volume) = (entry.constants.delta, entry.constants.volume);
            let ratios = density_ratios(&entry.bonds, body.positions(), delta, volume)?;
            entry.lam = match entry.wetted.as_slice() {
                [] => material.stiffness_of(&ratios),
                theta => material.wet_stiffness_of(&ratios, theta),
            };
            granular = true;
        }
        if granular {
            self.refill(rest)?;
        }
        Ok(granular)
    }

    /// Refills `rest` from every body's bonds (a granular body's with its stiffness `lam`)
    /// and sets the plastic bodies' cones.
    fn refill<T: Real>(&self, rest: &mut ParticleRest<T>) -> Result<()> {
        let sources: Vec<(&RestBonds, RestConstants, Option<&[f64]>)> = self
            .entries
            .iter()
            .map(|e| {
                let lam = e.constants.granular.map(|_| e.lam.as_slice());
                (&e.bonds, e.constants, lam)
            })
            .collect();
        rest.refill(&sources)?;
        for entry in &self.entries {
            // Every plastic body returns within the local step (`particles::cone`).
            if let Some(law) = entry.law {
                let cohesion = entry.cohesions();
                rest.set_cones(entry.range.start, &law, &entry.bonds, cohesion.as_deref());
            }
        }
        Ok(())
    }

    /// Writes the plastic bodies' bonds (into the bodies' own allocations), and the wetted
    /// sand's saturations, back into them.
    pub fn store(&self, bodies: &mut [&mut Particles]) {
        for (entry, body) in self.entries.iter().zip(bodies) {
            if entry.law.is_some() {
                body.set_rest_bonds(&entry.bonds);
            }
            if !entry.wetted.is_empty() {
                body.set_wetted(entry.wetted.clone());
            }
        }
    }

    /// Wets the sand (see [`crate::particles::wetted`]) at the liquid volume fractions
    /// `fractions` (family index, fraction) around its grains; other particles are left.
    pub fn wet(&mut self, fractions: impl Iterator<Item = (usize, f64)>) {
        for (k, phi) in fractions {
            let Some(entry) = self.entries.iter_mut().find(|e| e.range.contains(&k)) else {
                continue;
            };
            let Some(material) = entry.constants.granular else {
                continue;
            };
            if entry.wetted.is_empty() {
                entry.wetted = vec![material.saturation; entry.range.len()];
            }
            let theta = &mut entry.wetted[k - entry.range.start];
            *theta = wetted(*theta, phi);
        }
    }
}
