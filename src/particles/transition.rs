//! Material transitions of a region of a particle body (He et al. 2017, section 8 and
//! Fig. 19: the bottom of a dress simulated as a viscoelastic fluid, then as an elastic shell
//! after it solidifies). [`Particles::set_material`] changes a whole body; here the given
//! particles change, and the body becomes a **mixed body**: each particle is a fluid or a solid
//! particle of the body's one fluid material and one elastic material.
//!
//! **Bonds.** A mixed body keeps its elastic bonds explicitly ([`RestBonds`]), between solid
//! particles only:
//! - a bond between two particles that did not change keeps its reference vector `X` (a
//!   solid region keeps the strain it carries);
//! - every pair of solid particles within the horizon at the current positions of which at
//!   least one changed to solid is bonded anew, born at the current positions
//!   (`X = y_j - y_i`): a region turned solid is welded, stress-free, to itself and to the
//!   solid it touches;
//! - a particle turned fluid loses its bonds.
//!
//! So a bond across the fluid-solid boundary carries no stiffness (there is none): fluid and
//! solid particles of one body meet through the fluid's density constraints, in which the
//! solid particles count as neighbours by their volume (`crate::solve::particles::fluid`),
//! and the fluid's viscosity, which they drag as a wall does. A fluid particle has no bonds
//! and its shape matrix is taken as `K^-1 = 0` (no elastic force acts on it).
//!
//! **Limits (stated).** A region changes between a Newtonian fluid (`shear_modulus = 0`) and
//! a non-plastic elastic solid; a body holds one elastic and one fluid material (a region
//! asking for another is refused: make it its own body). Shells, rods, sand and plastic
//! bodies (viscoelastic fluids among them) keep their material by region.

use nalgebra::{Matrix3, Vector3};

use crate::error::{invalid, Result};
use crate::geometry::find_horizons;

use crate::particles::deformation::{flat_neighbourhood, shape_inverse};
use crate::particles::influence::influence;
use crate::particles::plasticity::{local_strain, reanchored};
use crate::particles::{Elastic, ParticleParams, Particles, RestBonds, ViscoelasticFluid};

/// What a region becomes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RegionMaterial {
    /// A non-plastic elastic solid (Pa).
    Solid(Elastic),
    /// A Newtonian liquid.
    Fluid(ViscoelasticFluid),
}

impl Particles {
    /// Per particle, whether it is a fluid particle (see the module's doc): `None` for a body
    /// whose material is uniform (a fluid body's particles are all fluid).
    pub fn fluid_mask(&self) -> Option<&[bool]> {
        self.fluid_mask.as_deref()
    }

    /// Fails on a mixed body: plasticity, sand and bonds from outside act on a body of one
    /// material.
    pub(super) fn refuse_mixed(&self) -> Result<()> {
        match self.fluid_mask {
            Some(_) => Err(invalid!(
                "a body whose region changed material (fluid and solid particles) keeps its \
                 own bonds and takes no plasticity, granular material or bonds from outside: \
                 set_material() it whole first"
            )),
            None => Ok(()),
        }
    }

    /// Whether particle `i` is a fluid particle (the body's fluid material acts on it).
    pub fn is_fluid_particle(&self, i: usize) -> bool {
        self.fluid_mask
            .as_ref()
            .map_or(self.fluid.is_some(), |mask| mask[i])
    }

    /// Changes the material of the particles `indices` only (see the module's doc): positions,
    /// velocities and pins are kept; solvers stepping the body build its working set anew at
    /// their next step. Fails, changing nothing, naming the culprit, on an index out of
    /// `[0, n)` or an empty list, a shell, rod, sand or plastic body, a viscoelastic fluid, a
    /// material other than the body's elastic or fluid one, or a solid particle left without
    /// a three-dimensional neighbourhood among its bonds.
    pub fn set_material_of(&mut self, indices: &[i64], material: RegionMaterial) -> Result<()> {
        let n = self.num_particles();
        if indices.is_empty() {
            return Err(invalid!("indices: no particle given"));
        }
        if let Some((k, &i)) = indices
            .iter()
            .enumerate()
            .find(|(_, &i)| i < 0 || i as usize >= n)
        {
            return Err(invalid!(
                "indices[{k}] = {i} is not a particle of this body (0 to {})",
                n - 1
            ));
        }
        if !self.ghost_owners.is_empty() || self.granular.is_some() || self.plasticity.is_some() {
            return Err(invalid!(
                "only a solid or Newtonian fluid body changes its material by region: a shell, \
                 rod, sand or plastic body (a viscoelastic fluid among them) keeps its own"
            ));
        }
        let mut mask = self
            .fluid_mask
            .clone()
            .unwrap_or_else(|| vec![self.fluid.is_some(); n]);
        let any_solid = mask.iter().any(|&f| !f);
        let to_fluid = match material {
            RegionMaterial::Solid(elastic) => {
                elastic.validate()?;
                if any_solid && elastic != self.params.material {
                    return Err(invalid!(
                        "a body holds one elastic material ({:?}): a region cannot become {:?}; \
                         make it its own body",
                        self.params.material,
                        elastic
                    ));
                }
                false
            }
            RegionMaterial::Fluid(fluid) => {
                fluid.validate()?;
                if fluid.shear_modulus != 0.0 {
                    return Err(invalid!(
                        "shear_modulus = {}: a region becomes a Newtonian fluid only \
                         (shear_modulus 0); make a viscoelastic region its own body",
                        fluid.shear_modulus
                    ));
                }
                if self.fluid.is_some_and(|f| f != fluid) {
                    return Err(invalid!(
                        "a body holds one fluid material ({:?}): a region cannot become {:?}; \
                         make it its own body",
                        self.fluid,
                        fluid
                    ));
                }
                true
            }
        };
        let old_bonds = match (&self.fluid_mask, &self.rest_bonds) {
            (Some(_), Some(bonds)) => bonds.clone(),
            _ if any_solid => self.current_rest_bonds(),
            _ => RestBonds {
                offsets: vec![0; n + 1],
                indices: Vec::new(),
                xi: Vec::new(),
                born: Vec::new(),
                plastic_strain: vec![0.0; n],
                volume: vec![1.0; n],
            },
        };
        let mut changed = vec![false; n];
        for &i in indices {
            changed[i as usize] = true;
            mask[i as usize] = to_fluid;
        }
        // The body's horizon: its own (a fluid body's parameters carry the default), kept by
        // the new parameters below.
        let delta = self.params.delta();
        let bonds = self.region_bonds(&old_bonds, &mask, &changed, delta)?;
        // Every check passed: commit.
        match material {
            RegionMaterial::Solid(elastic) => {
                if !any_solid {
                    // The body keeps its horizon (the one its bonds were just found within).
                    let params = ParticleParams {
                        material: elastic,
                        ..self.params
                    };
                    self.moduli = elastic.resolve(params.spacing, params.delta())?;
                    self.params = params;
                }
            }
            RegionMaterial::Fluid(fluid) => self.fluid = Some(fluid),
        }
        self.fluid_mask = Some(mask);
        self.rest_bonds = Some(bonds);
        self.bonds_revision += 1;
        Ok(())
    }

    /// The bonds after a change (see the module's doc): `old` kept between unchanged solid
    /// particles, new ones born at the current positions for every solid pair within `delta`
    /// (m) with a changed end; each solid particle's shape matrix checked. An unchanged
    /// particle keeps its plastic strain (from a plasticity it had before) and its volume
    /// ratio [`RestBonds::volume`], re-anchored as the neighbour rebuild does where its bonds
    /// changed (its volume `R_i det F_i` kept across them: [`reanchored`]); a changed particle
    /// starts anew (no plastic strain, its current volume its rest volume).
    fn region_bonds(
        &self,
        old: &RestBonds,
        fluid: &[bool],
        changed: &[bool],
        delta: f64,
    ) -> Result<RestBonds> {
        let y = &self.state.positions;
        let now = find_horizons(y, delta)?;
        let n = y.len();
        let mut out = RestBonds {
            offsets: vec![0],
            indices: Vec::new(),
            xi: Vec::new(),
            born: Vec::new(),
            plastic_strain: (0..n)
                .map(|i| {
                    if changed[i] {
                        0.0
                    } else {
                        old.plastic_strain[i]
                    }
                })
                .collect(),
            volume: (0..n)
                .map(|i| if changed[i] { 1.0 } else { old.volume[i] })
                .collect(),
        };
        // The unchanged particles whose bonds change.
        let mut touched = vec![false; n];
        let mut row: Vec<(u32, Vector3<f64>, f64)> = Vec::new();
        for i in 0..n {
            row.clear();
            if !fluid[i] {
                if !changed[i] {
                    row.extend(
                        old.row(i)
                            .filter(|&b| {
                                let j = old.indices[b] as usize;
                                !fluid[j] && !changed[j]
                            })
                            .map(|b| (old.indices[b], old.xi[b], old.born[b])),
                    );
                }
                let kept = row.len();
                row.extend(
                    now.of(i)
                        .iter()
                        .filter(|&&j| !fluid[j as usize] && (changed[i] || changed[j as usize]))
                        .map(|&j| {
                            let xi = y[j as usize] - y[i];
                            (j, xi, xi.norm())
                        }),
                );
                touched[i] = !changed[i] && (kept < old.of(i).len() || row.len() > kept);
                row.sort_by_key(|e| e.0);
            }
            for (j, xi, born) in &row {
                out.indices.push(*j);
                out.xi.push(*xi);
                out.born.push(*born);
            }
            out.offsets.push(out.indices.len() as u32);
        }
        check_region_bonds(&out, fluid, delta)?;
        let det = |bonds: &RestBonds, i: usize| {
            local_strain(bonds, i, y, delta, self.volume()).map_or(0.0, |l| l.f.determinant())
        };
        for i in (0..n).filter(|&i| touched[i]) {
            let volume = old.volume[i] * det(old, i);
            out.volume[i] = reanchored(old.volume[i], volume, det(&out, i));
        }
        Ok(out)
    }
}

/// Checks a mixed body's bonds against its fluid mask `fluid` for the horizon `delta` (m):
/// bonds join solid particles only, and every solid particle's bonds make a three-dimensional
/// neighbourhood (its shape matrix invertible). Fails naming the first culprit.
pub(super) fn check_region_bonds(bonds: &RestBonds, fluid: &[bool], delta: f64) -> Result<()> {
    for (i, &is_fluid) in fluid.iter().enumerate() {
        let row = bonds.offsets[i] as usize..bonds.offsets[i + 1] as usize;
        if let Some(b) = row
            .clone()
            .find(|&b| is_fluid || fluid[bonds.indices[b] as usize])
        {
            return Err(invalid!(
                "bond {b} joins particles {i} and {}, one of them fluid: a mixed body's bonds \
                 join solid particles only",
                bonds.indices[b]
            ));
        }
        if is_fluid {
            continue;
        }
        let mut shape = Matrix3::<f64>::zeros();
        for b in row.clone() {
            shape += bonds.xi[b] * bonds.xi[b].transpose() * influence(bonds.born[b], delta);
        }
        if shape_inverse(&shape).is_none() {
            return Err(flat_neighbourhood(i, row.len(), delta));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::tests::lattice;

    /// A 6 x 3 x 3 water body on a 1 cm lattice, its positions moved by `shift` (m).
    fn water() -> Particles {
        Particles::fluid(
            lattice([6, 3, 3], 0.01),
            0.01,
            1000.0,
            ViscoelasticFluid::default(),
        )
        .unwrap()
    }

    /// The particles of the half `x < 2.5 cm` (a 3 x 3 x 3 block).
    fn half(body: &Particles) -> Vec<i64> {
        let x = body.positions();
        (0..x.len() as i64)
            .filter(|&i| x[i as usize].x < 0.025)
            .collect()
    }

    fn solid() -> RegionMaterial {
        RegionMaterial::Solid(Elastic::Paper { mu: 1e3, lam: 1e3 })
    }

    /// Bonds only between solid particles, born at the positions of the change; a later
    /// change keeps the bonds between unchanged particles as they were (their `X`, not the
    /// moved positions) and drops those of a particle turned fluid.
    #[test]
    fn region_bonds_join_solid_particles_only_and_keep_unchanged_ones() {
        let mut body = water();
        let n = body.num_particles();
        let half = half(&body);
        let solid_at = |i: usize| half.contains(&(i as i64));
        body.set_material_of(&half, solid()).unwrap();
        let bonds = body.rest_bonds().unwrap().clone();
        let y = body.positions().to_vec();
        for i in 0..n {
            for b in bonds.row(i) {
                let j = bonds.indices[b] as usize;
                assert!(
                    solid_at(i) && solid_at(j),
                    "bond {i}-{j} leaves the solid half"
                );
                assert_eq!(bonds.xi[b], y[j] - y[i]);
            }
        }
        // Move everything, then turn particle 0 (a corner of the half) fluid: it loses its
        // bonds, the others keep X.
        assert!(solid_at(0));
        let moved: Vec<_> = y.iter().map(|p| p * 1.1).collect();
        body.set_positions(moved).unwrap();
        body.set_material_of(&[0], RegionMaterial::Fluid(ViscoelasticFluid::default()))
            .unwrap();
        let after = body.rest_bonds().unwrap();
        assert!(after.of(0).is_empty());
        for i in (1..n).filter(|&i| solid_at(i)) {
            let kept: Vec<_> = bonds.row(i).filter(|&b| bonds.indices[b] != 0).collect();
            assert_eq!(after.of(i).len(), kept.len());
            for (a, b) in after.row(i).zip(kept) {
                assert_eq!(after.xi[a], bonds.xi[b]);
            }
        }
        assert!((0..n).all(|i| body.is_fluid_particle(i) == (i == 0 || !solid_at(i))));
    }

    /// A mixed body refuses plasticity, sand and bonds from outside, by name.
    #[test]
    fn a_mixed_body_takes_no_plasticity_sand_or_bonds() {
        let mut body = water();
        body.set_material_of(&half(&body), solid()).unwrap();
        let refused = |r: Result<()>| {
            let message = r.unwrap_err().to_string();
            assert!(message.contains("region changed material"), "{message}");
        };
        refused(body.set_granular(crate::particles::Granular::new(30.0, 0.0)));
        refused(body.set_plasticity(None));
        refused(body.restore_rest_bonds(None));
    }

    /// A solid body of its own horizon turned all fluid and then solid again keeps that
    /// horizon: its parameters and its bonds (found within it) agree.
    #[test]
    fn a_body_turned_fluid_and_back_keeps_its_horizon() {
        let spacing = 0.01;
        let horizon = 3.1 * spacing;
        let elastic = Elastic::Paper { mu: 1e3, lam: 1e3 };
        let params = ParticleParams {
            spacing,
            density: 1000.0,
            horizon: Some(horizon),
            material: elastic,
        };
        let mut body = Particles::new(lattice([6, 3, 3], spacing), params).unwrap();
        let all: Vec<i64> = (0..body.num_particles() as i64).collect();
        body.set_material_of(&all, RegionMaterial::Fluid(ViscoelasticFluid::default()))
            .unwrap();
        body.set_material_of(&all, RegionMaterial::Solid(elastic))
            .unwrap();
        assert_eq!(body.params().delta(), horizon);
        let bonds = body.rest_bonds().unwrap();
        let longest = bonds.born.iter().cloned().fold(0.0, f64::max);
        // Bonds of 3 spacings (beyond the default 2.2) exist, none beyond the horizon.
        assert!(longest > 2.9 * spacing && longest <= horizon, "{longest}");
    }

    /// A region change keeps what an unchanged particle's bonds carry from a plasticity the
    /// body had: a solid body given returned bonds (every particle with the plastic strain
    /// 0.2 and the volume ratio 1.1), made elastic, bent (`z += 2 mm sin(x / 2 cm)`) and its
    /// particle 0 (a corner) made fluid. A particle beyond the horizon of particle 0 keeps its
    /// strain and ratio exactly; a neighbour of it, which lost its bond to it, keeps its
    /// strain and its volume `R det F` (1e-12) with a new ratio; particle 0 starts anew.
    #[test]
    fn a_region_change_keeps_the_plastic_strain_and_volume_of_unchanged_particles() {
        let spacing = 0.01;
        let params = ParticleParams {
            spacing,
            density: 1000.0,
            horizon: None,
            material: Elastic::Paper { mu: 1e3, lam: 1e3 },
        };
        let mut body = Particles::new(lattice([6, 3, 3], spacing), params).unwrap();
        let n = body.num_particles();
        body.set_plasticity(Some(crate::particles::DruckerPrager {
            friction_angle: 0.0,
            cohesion: 300.0,
            hardening: 0.0,
            rebuild_neighbours: false,
        }))
        .unwrap();
        let mut bonds = body.current_rest_bonds();
        bonds.plastic_strain = vec![0.2; n];
        bonds.volume = vec![1.1; n];
        body.restore_rest_bonds(Some(bonds.clone())).unwrap();
        body.set_plasticity(None).unwrap();
        let bent: Vec<_> = body
            .positions()
            .iter()
            .map(|p| p + Vector3::z() * 0.002 * (p.x / 0.02).sin())
            .collect();
        body.set_positions(bent).unwrap();
        body.set_material_of(&[0], RegionMaterial::Fluid(ViscoelasticFluid::default()))
            .unwrap();
        let after = body.rest_bonds().unwrap();
        let (y, delta, volume) = (body.positions(), body.params().delta(), body.volume());
        let det = |b: &RestBonds, i: usize| {
            local_strain(b, i, y, delta, volume)
                .unwrap()
                .f
                .determinant()
        };
        let far = (0..n).find(|&i| (y[i] - y[0]).norm() > 0.03).unwrap();
        assert_eq!((after.plastic_strain[far], after.volume[far]), (0.2, 1.1));
        let near = bonds.indices[bonds.row(0).start] as usize;
        assert!(after.of(near).len() < bonds.of(near).len());
        assert_eq!(after.plastic_strain[near], 0.2);
        assert_ne!(after.volume[near], 1.1);
        let (kept, was) = (
            after.volume[near] * det(after, near),
            1.1 * det(&bonds, near),
        );
        assert!((kept - was).abs() < 1e-12, "{kept} {was}");
        assert_eq!((after.plastic_strain[0], after.volume[0]), (0.0, 1.0));
    }
}
