//! What a particle body's material has become during a run, taken and restored whole: the
//! state a saved simulation needs beyond positions and velocities to continue bit for bit.
//!
//! A run changes a body's material in three ways: [`Particles::set_material`] (the whole body
//! melts or solidifies; its reference becomes the positions of that moment),
//! [`Particles::set_material_of`] (a region changes; the body keeps a fluid mask and explicit
//! bonds) and a liquid wetting sand (the grains' saturations rise, [`super::wet_sand`]). A body
//! built anew from its set-up has none of it, so a restore must carry it; a plastic body's
//! returned bonds travel separately ([`Particles::restore_rest_bonds`], after this).

use nalgebra::Vector3;

use crate::error::{invalid, Result};

use super::transition::check_region_bonds;
use super::{Elastic, ParticleParams, Particles, RestBonds, ViscoelasticFluid};

/// A body's material as a run has left it (see the module's doc).
#[derive(Debug, Clone, PartialEq)]
pub struct MaterialState {
    /// The elastic material (Pa); a fluid body's placeholder or a viscoelastic fluid's own.
    pub elastic: Elastic,
    /// The fluid material, for a fluid body or a mixed body's fluid particles.
    pub fluid: Option<ViscoelasticFluid>,
    /// The horizon (m); `None`: the default multiple of the spacing.
    pub horizon: Option<f64>,
    /// The reference positions (m) the bonds of a body of one material are measured from,
    /// ghosts included.
    pub reference: Vec<Vector3<f64>>,
    /// Per particle, whether it is a fluid particle, for a mixed body (`None`: one material).
    pub fluid_mask: Option<Vec<bool>>,
    /// A mixed body's bonds (between its solid particles); `None` for a body of one material.
    pub region_bonds: Option<RestBonds>,
    /// A sand body's saturation per particle once a liquid wetted it (`None`: the material's).
    pub wetted: Option<Vec<f64>>,
}

impl Particles {
    /// The body's material as it stands (see the module's doc).
    pub fn material_state(&self) -> MaterialState {
        MaterialState {
            elastic: self.params.material,
            fluid: self.fluid,
            horizon: self.params.horizon,
            reference: self.reference.clone(),
            fluid_mask: self.fluid_mask.clone(),
            region_bonds: self
                .fluid_mask
                .as_ref()
                .and_then(|_| self.rest_bonds.clone()),
            wetted: self.wetted.clone(),
        }
    }

    /// Makes the body's material `state` (one taken by [`Self::material_state`] from a body
    /// set up as this one). Parts equal to the body's own are left alone, so a body that never
    /// changed takes its own state without a rebuild; otherwise solvers stepping the body build
    /// its working set anew at their next step. Fails, changing nothing, naming the culprit, on
    /// a count that is not the body's, a non-finite reference position, a saturation outside
    /// [0, 1] or given to a body that is not sand, a fluid mask without bonds (or bonds without
    /// a mask), a mask on a body that cannot be mixed, or a material the body cannot take
    /// ([`Self::set_material`]'s refusals).
    pub fn restore_material_state(&mut self, state: MaterialState) -> Result<()> {
        let n = self.reference.len();
        if state.reference.len() != n {
            return Err(invalid!(
                "the material state holds {} reference positions, the body has {n} particles",
                state.reference.len()
            ));
        }
        if let Some(i) = state
            .reference
            .iter()
            .position(|x| !x.iter().all(|c| c.is_finite()))
        {
            return Err(invalid!(
                "reference position {i} is {:?}, not finite",
                state.reference[i]
            ));
        }
        self.check_wetted(state.wetted.as_deref())?;
        match (&state.fluid_mask, &state.region_bonds) {
            (Some(mask), Some(bonds)) => {
                if mask.len() != n {
                    return Err(invalid!(
                        "the fluid mask holds {} particles, the body has {n}",
                        mask.len()
                    ));
                }
                if !self.ghost_owners.is_empty() || self.granular.is_some() {
                    return Err(invalid!(
                        "a shell, rod or sand keeps one material: it takes no fluid mask"
                    ));
                }
                if state.fluid.is_none_or(|f| f.shear_modulus != 0.0) {
                    return Err(invalid!(
                        "a fluid mask needs the body's Newtonian fluid (shear_modulus 0), got {:?}",
                        state.fluid
                    ));
                }
                bonds.check(n)?;
                let delta = ParticleParams {
                    horizon: state.horizon,
                    ..self.params
                }
                .delta();
                check_region_bonds(bonds, mask, delta)?;
            }
            (None, None) => {}
            (Some(_), None) => return Err(invalid!("a fluid mask comes with its bonds")),
            (None, Some(_)) => return Err(invalid!("bonds come with a fluid mask")),
        }
        let same_material = state.elastic == self.params.material
            && state.fluid == self.fluid
            && state.horizon == self.params.horizon
            && state.reference == self.reference;
        let own_plasticity = self.plasticity.is_some() && self.fluid.is_none();
        if state.fluid_mask.is_some() && own_plasticity {
            return Err(invalid!(
                "a plastic body keeps one material: it takes no fluid mask"
            ));
        }
        // A mixed body's parameters hold its solid particles' material (a fluid body's
        // placeholder until a region first turned solid), resolved before anything changes
        // where a solid particle needs it.
        let mixed_moduli = match &state.fluid_mask {
            Some(mask) => {
                let params = ParticleParams {
                    horizon: state.horizon,
                    material: state.elastic,
                    ..self.params
                };
                params.validate()?;
                match mask.iter().any(|&f| !f) {
                    true => Some(state.elastic.resolve(params.spacing, params.delta())?),
                    false => None,
                }
            }
            None => None,
        };
        if !same_material {
            // Checks (and refuses) before it changes anything.
            self.adopt_material(state.elastic, state.fluid, state.horizon, state.reference)?;
        }
        if state.fluid_mask.is_some() {
            self.params.material = state.elastic;
        }
        if let Some(moduli) = mixed_moduli {
            self.moduli = moduli;
        }
        let region = self.fluid_mask.as_ref().and(self.rest_bonds.as_ref());
        if state.fluid_mask != self.fluid_mask || state.region_bonds.as_ref() != region {
            self.fluid_mask = state.fluid_mask;
            self.rest_bonds = state.region_bonds;
            self.bonds_revision += 1;
        }
        if state.wetted != self.wetted {
            self.wetted = state.wetted;
            self.bonds_revision += 1;
        }
        Ok(())
    }

    /// Checks saturations `wetted` for this body (see [`Self::restore_material_state`]).
    fn check_wetted(&self, wetted: Option<&[f64]>) -> Result<()> {
        let Some(theta) = wetted else {
            return Ok(());
        };
        if self.granular.is_none() {
            return Err(invalid!(
                "saturations are a sand body's: this body is not sand"
            ));
        }
        if theta.len() != self.num_particles() {
            return Err(invalid!(
                "the saturations hold {} particles, the body has {}",
                theta.len(),
                self.num_particles()
            ));
        }
        match theta.iter().position(|t| !(0.0..=1.0).contains(t)) {
            Some(i) => Err(invalid!("saturation {i} is {}, outside [0, 1]", theta[i])),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::tests::lattice;
    use crate::particles::{Granular, RegionMaterial};

    const SPACING: f64 = 0.01;

    fn water() -> Particles {
        Particles::fluid(
            lattice([5, 4, 4], SPACING),
            SPACING,
            1000.0,
            ViscoelasticFluid::default(),
        )
        .unwrap()
    }

    fn solid() -> Elastic {
        Elastic::Young { e: 1e4, nu: 0.3 }
    }

    /// Moves every particle a little (m), as a step would, before a transition.
    fn stir(body: &mut Particles) {
        let y: Vec<_> = body
            .positions()
            .iter()
            .enumerate()
            .map(|(i, p)| p + Vector3::new(1e-4 * (i % 3) as f64, 0.0, -2e-4 * (i % 2) as f64))
            .collect();
        body.set_positions(y).unwrap();
    }

    /// Water moved as by a step, then solidified whole.
    fn solidified() -> Particles {
        let mut run = water();
        stir(&mut run);
        run.set_material(solid(), None).unwrap();
        run
    }

    /// Water moved as by a step, then its first 40 particles turned to `elastic`.
    fn mixed(elastic: Elastic) -> Particles {
        let mut run = water();
        stir(&mut run);
        let region: Vec<i64> = (0..40).collect();
        run.set_material_of(&region, RegionMaterial::Solid(elastic))
            .unwrap();
        run
    }

    #[test]
    fn a_body_that_solidified_whole_is_restored_into_a_fresh_one() {
        let run = solidified();
        let mut fresh = water();
        fresh.restore_material_state(run.material_state()).unwrap();
        assert_eq!(fresh.material_state(), run.material_state());
        assert_eq!(fresh.moduli(), run.moduli());
        assert!(!fresh.is_fluid_particle(0));
    }

    #[test]
    fn a_mixed_body_is_restored_with_its_mask_and_bonds() {
        let run = mixed(solid());
        let state = run.material_state();
        assert!(state.fluid_mask.is_some() && state.region_bonds.is_some());
        let mut fresh = water();
        fresh.restore_material_state(state).unwrap();
        assert_eq!(fresh.material_state(), run.material_state());
        assert_eq!(fresh.fluid_mask(), run.fluid_mask());
        assert_eq!(fresh.moduli(), run.moduli());
        // And back: a body mixed after the save returns to one material.
        let mut later = run;
        later
            .restore_material_state(water().material_state())
            .unwrap();
        assert_eq!(later.material_state(), water().material_state());
    }

    #[test]
    fn a_mixed_body_of_any_elastic_material_keeps_its_moduli() {
        // The paper's parameters mu = 1 Pa, lam = 0 (a fluid body's placeholder material).
        let weak = Elastic::Paper { mu: 1.0, lam: 0.0 };
        let run = mixed(weak);
        assert!(run.moduli().mu > 0.0);
        let mut fresh = water();
        fresh.restore_material_state(run.material_state()).unwrap();
        assert_eq!(fresh.moduli(), run.moduli());
    }

    #[test]
    fn region_bonds_that_do_not_fit_the_mask_are_refused() {
        let run = mixed(solid());
        let state = run.material_state();
        let bonded = state.region_bonds.as_ref().unwrap().indices[0] as usize;
        let mut wet = state.clone();
        wet.fluid_mask.as_mut().unwrap()[bonded] = true;
        let err = water().restore_material_state(wet).unwrap_err().to_string();
        assert!(err.contains("one of them fluid"), "{err}");
        let mut dry = state;
        dry.fluid_mask = Some(vec![false; run.num_particles()]);
        let err = water().restore_material_state(dry).unwrap_err().to_string();
        assert!(err.contains("three-dimensional"), "{err}");
    }

    #[test]
    fn a_body_given_its_own_state_is_not_rebuilt() {
        let mut body = water();
        let revision = body.bonds_revision();
        body.restore_material_state(body.material_state()).unwrap();
        assert_eq!(body.bonds_revision(), revision);
    }

    #[test]
    fn wetted_sand_takes_its_saturations_and_bad_ones_are_refused() {
        let x = lattice([4, 4, 4], SPACING);
        let params = ParticleParams {
            spacing: SPACING,
            density: 1600.0,
            horizon: None,
            material: solid(),
        };
        let mut sand = Particles::new(x, params).unwrap();
        sand.set_granular(Granular::new(30.0, 0.0)).unwrap();
        let n = sand.num_particles();
        let mut state = sand.material_state();
        state.wetted = Some((0..n).map(|i| i as f64 / n as f64).collect());
        let revision = sand.bonds_revision();
        sand.restore_material_state(state.clone()).unwrap();
        assert_eq!(sand.wetted(), state.wetted.as_deref());
        assert!(
            sand.bonds_revision() > revision,
            "the solvers must see the new saturations"
        );

        state.wetted.as_mut().unwrap()[7] = 1.5;
        let err = sand.restore_material_state(state).unwrap_err().to_string();
        assert!(err.contains("saturation 7") && err.contains("1.5"), "{err}");
        let mut liquid = water();
        let mut state = liquid.material_state();
        state.wetted = Some(vec![0.5; liquid.num_particles()]);
        let err = liquid
            .restore_material_state(state)
            .unwrap_err()
            .to_string();
        assert!(err.contains("not sand"), "{err}");
    }

    #[test]
    fn a_refused_state_changes_nothing() {
        let run = solidified();
        let mut body = water();
        let before = body.material_state();
        let revision = body.bonds_revision();

        let mut short = run.material_state();
        short.reference.pop();
        let err = body.restore_material_state(short).unwrap_err().to_string();
        assert!(err.contains("reference positions"), "{err}");

        let mut flat = run.material_state();
        for x in &mut flat.reference {
            x.z = 0.0; // a neighbourhood that is not three-dimensional
        }
        assert!(body.restore_material_state(flat).is_err());

        let mut unbonded = run.material_state();
        unbonded.fluid_mask = Some(vec![true; body.num_particles()]);
        let err = body
            .restore_material_state(unbonded)
            .unwrap_err()
            .to_string();
        assert!(err.contains("comes with its bonds"), "{err}");

        let mut nan = run.material_state();
        nan.reference[3].y = f64::NAN;
        let err = body.restore_material_state(nan).unwrap_err().to_string();
        assert!(err.contains("reference position 3"), "{err}");

        assert_eq!(body.material_state(), before);
        assert_eq!(body.bonds_revision(), revision);
    }
}
