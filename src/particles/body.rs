//! A particle body (He et al. 2017): reference positions and the horizons among them, the
//! material, and the state (positions, velocities, pins).

use std::sync::atomic::{AtomicU64, Ordering};

use nalgebra::Vector3;

use crate::error::{check_param, Result};
use crate::geometry::nearest::nearest_distances;
use crate::geometry::{find_horizons, Horizons};
use crate::point_state::PointState;

use super::calibration::Moduli;
use super::deformation::check_shapes;
use super::elastic::Elastic;
use super::fluid::ViscoelasticFluid;
use super::granular::Granular;
use super::plasticity::DruckerPrager;
use super::rest_bonds::RestBonds;

/// Physical parameters of a particle body (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParticleParams {
    /// Spacing of the sampling lattice (m): each particle stands for a cube of this side
    /// (volume `spacing^3`) and keeps half of it from a collider's surface.
    pub spacing: f64,
    /// Density (kg/m^3).
    pub density: f64,
    /// Horizon radius `delta` (m): the bonds of a particle reach the particles strictly
    /// closer than this in the reference configuration. `None`: [`DEFAULT_HORIZON`] spacings.
    pub horizon: Option<f64>,
    pub material: Elastic,
}

/// Default horizon in spacings: 32 neighbours on a cubic lattice (the distances 1, sqrt 2,
/// sqrt 3 and 2 spacings; the next, sqrt 5 = 2.24, stays out with a margin for jitter), near
/// the "about 30" of the paper.
pub const DEFAULT_HORIZON: f64 = 2.2;

impl ParticleParams {
    /// Checks every parameter, naming the first bad one.
    pub fn validate(&self) -> Result<()> {
        check_param(
            "spacing",
            self.spacing,
            |v| v > 0.0,
            "a finite length > 0 m",
        )?;
        check_param(
            "density",
            self.density,
            |v| v > 0.0,
            "a finite density > 0 kg/m^3",
        )?;
        if let Some(h) = self.horizon {
            check_param(
                "horizon",
                h,
                |v| v > self.spacing && (v * v).is_normal(),
                &format!(
                    "a finite length above the spacing ({} m) whose square is a finite, normal \
                     number (from 1.5e-154 to 1.3e154 m)",
                    self.spacing
                ),
            )?;
        } else {
            let delta = self.delta();
            if !(delta.is_finite() && (delta * delta).is_normal()) {
                return Err(crate::error::invalid!(
                    "spacing {} m gives the default horizon ({DEFAULT_HORIZON} spacings) {delta} \
                     m, whose square is not a finite, normal number (horizons from 1.5e-154 to \
                     1.3e154 m)",
                    self.spacing
                ));
            }
        }
        self.material.validate()
    }

    /// The horizon radius (m).
    pub fn delta(&self) -> f64 {
        self.horizon.unwrap_or(DEFAULT_HORIZON * self.spacing)
    }
}

/// A fluid body's moduli: no elastic stiffness (a Newtonian liquid).
const FLUID_MODULI: Moduli = Moduli {
    mu: 0.0,
    lam: 0.0,
    kappa: 0.0,
    bulk_moment: None,
    bulk_weight: None,
};

/// The material a Newtonian fluid's parameters carry: any valid one, for the horizon and the
/// checks of [`Particles::new`]; its moduli are replaced by [`FLUID_MODULI`], so it never acts.
pub const FLUID_PLACEHOLDER: Elastic = Elastic::Paper { mu: 1.0, lam: 0.0 };

#[path = "material_state.rs"]
mod material_state;
#[path = "transition.rs"]
mod transition;
pub use material_state::MaterialState;
pub use transition::RegionMaterial;

/// How far, as a factor either way, a body's `spacing` may be from the median distance of its
/// particles to their nearest neighbours ([`check_spacing`]). A body sampled at its spacing
/// sits well inside: a lattice at 1, a jittered lattice ([`super::sample_volume`]) and a
/// surface layer ([`super::sample_surface`], at least a spacing apart) within a few tenths of
/// it. Far outside, the spacing is not the positions' (another unit, another body's): it sets
/// each particle's volume (`spacing^3`: 64 times too much or too little at the bound) and the
/// default horizon (2.2 spacings: no neighbour at all beyond 2.2 times, thousands within at a
/// quarter), so the body would not be the material it names.
pub const SPACING_BAND: f64 = 4.0;

/// The most particles whose nearest distances the spacing check measures (an even stride
/// through the body's order), so that a large body's check costs its tree and 16,384 queries:
/// a lattice's median is exact on any sample, a jittered one's moves by sampling noise, which
/// the band's factor of 4 dwarfs.
const SPACING_SAMPLE: usize = 1 << 14;

/// Checks what a body is built from: the parameters, a particle mass `density volume` (kg,
/// `volume` in m^3) that is a finite, normal number, at least one particle, finite positions.
fn check_input(reference: &[Vector3<f64>], volume: f64, params: &ParticleParams) -> Result<()> {
    params.validate()?;
    let mass = params.density * volume;
    if !(mass.is_normal() && mass.is_finite()) {
        return Err(crate::error::invalid!(
            "density {} kg/m^3 times each particle's volume {volume} m^3 (from the spacing \
             {} m) gives a particle mass of {mass} kg: not a finite, normal number",
            params.density,
            params.spacing
        ));
    }
    if reference.is_empty() {
        return Err(crate::error::invalid!(
            "a particle body needs at least one particle"
        ));
    }
    if let Some(i) = reference
        .iter()
        .position(|x| !x.iter().all(|c| c.is_finite()))
    {
        return Err(crate::error::invalid!(
            "positions of particle {i} are not finite: {:?}",
            reference[i].as_slice()
        ));
    }
    Ok(())
}

/// Refuses a `spacing` (m) more than [`SPACING_BAND`] times above or below the median distance
/// (m) from the particles at `reference` (m, finite) to their nearest neighbours (the upper
/// median for an even count, over at most [`SPACING_SAMPLE`] of them; a lone particle is not
/// checked), naming both. Checked before the
/// horizons are searched: a spacing far too large would make every pair a bond.
fn check_spacing(reference: &[Vector3<f64>], spacing: f64) -> Result<()> {
    if reference.len() < 2 {
        return Ok(());
    }
    // The median of an evenly strided sample: the spacing is a property of the whole body.
    let every = reference.len().div_ceil(SPACING_SAMPLE);
    let mut nearest = nearest_distances(reference, every);
    let middle = nearest.len() / 2;
    let median = *nearest.select_nth_unstable_by(middle, f64::total_cmp).1;
    if median * SPACING_BAND >= spacing && median <= SPACING_BAND * spacing {
        return Ok(());
    }
    let (factor, side) = if median < spacing {
        (spacing / median, "above")
    } else {
        (median / spacing, "below")
    };
    Err(crate::error::invalid!(
        "spacing {spacing:e} m is {factor:.3e} times {side} the median distance between the \
         particles and their nearest neighbours, {median:e} m (at most {SPACING_BAND} times \
         either way): the spacing sets each particle's volume (spacing^3) and the default \
         horizon (2.2 spacings), so pass the spacing the positions were sampled at"
    ))
}

static NEXT_ID: AtomicU64 = AtomicU64::new(1);

/// A body of particles. Not `Clone`: its `id` is unique.
#[derive(Debug)]
pub struct Particles {
    id: u64,
    reference: Vec<Vector3<f64>>,
    horizons: Horizons,
    params: ParticleParams,
    /// What the material resolved to on this body's lattice.
    moduli: Moduli,
    /// Volume of each particle (m^3) and how far each keeps from a collider's surface (m).
    volume: f64,
    margin: f64,
    /// The owner of each ghost particle: particles `num_real..` are ghosts ([`super::thin`]),
    /// `ghost_owners[k]` the real particle that ghost `num_real + k` belongs to.
    ghost_owners: Vec<u32>,
    state: PointState,
    /// The plastic law, if the body is plastic ([`Self::set_plasticity`]).
    plasticity: Option<DruckerPrager>,
    /// A plastic body's current reference bonds once a solver has stepped it (`None`: the
    /// bonds of `reference` and `horizons`).
    rest_bonds: Option<RestBonds>,
    /// The granular material, if the body is sand ([`Self::set_granular`]).
    granular: Option<Granular>,
    /// How many times the bonds were replaced from outside ([`Self::restore_rest_bonds`]):
    /// a solver whose working set was built at another count builds it anew.
    bonds_revision: u64,
    /// How many times the positions were replaced from outside ([`Self::set_positions`]): a
    /// solver forgets what it kept of the contacts at the old ones (their friction).
    positions_revision: u64,
    /// The fluid material, if the body is a fluid ([`Self::fluid`]) or has fluid particles.
    fluid: Option<ViscoelasticFluid>,
    /// Per particle, whether it is a fluid particle, once a region changed its material
    /// ([`transition`]); `None`: the material is uniform.
    fluid_mask: Option<Vec<bool>>,
    /// A sand body's saturation per particle once a liquid wetted it
    /// ([`super::wet_sand`]); `None`: the material's everywhere.
    wetted: Option<Vec<f64>>,
    /// Per particle, the pressure of its density constraint over the last step a solver
    /// took (Pa; `solve::particles::fluid_pressure`); `None` until a step projected one.
    pressure: Option<Vec<f64>>,
}

impl Particles {
    /// Particles at rest at their reference positions `reference` (m). Fails, naming the
    /// culprit, on a bad parameter, a non-finite position, a `spacing` away from the
    /// particles' own ([`check_spacing`]), or a particle whose neighbourhood within the
    /// horizon is not three-dimensional (its shape matrix `K_i` is singular).
    pub fn new(reference: Vec<Vector3<f64>>, params: ParticleParams) -> Result<Self> {
        let (volume, margin) = (params.spacing.powi(3), 0.5 * params.spacing);
        check_input(&reference, volume, &params)?;
        check_spacing(&reference, params.spacing)?;
        Self::with_ghosts(reference, Vec::new(), volume, margin, params)
    }

    /// A body whose last `ghost_owners.len()` particles are ghosts (they take part in the
    /// elasticity but never in collisions), ghost `k` belonging to the real particle
    /// `ghost_owners[k]`; each particle stands for `volume` (m^3) and keeps `margin` (m) from
    /// a collider's surface. The shells' and rods' builders ([`super::thin`]) make these, with
    /// positions they sample at the spacing.
    pub(crate) fn with_ghosts(
        reference: Vec<Vector3<f64>>,
        ghost_owners: Vec<u32>,
        volume: f64,
        margin: f64,
        params: ParticleParams,
    ) -> Result<Self> {
        check_input(&reference, volume, &params)?;
        let delta = params.delta();
        let horizons = find_horizons(&reference, delta)?;
        let moduli = params.material.resolve(params.spacing, delta)?;
        let state = PointState::at_rest(reference.clone());
        let body = Self {
            id: NEXT_ID.fetch_add(1, Ordering::Relaxed),
            reference,
            horizons,
            params,
            moduli,
            volume,
            margin,
            ghost_owners,
            state,
            plasticity: None,
            rest_bonds: None,
            bonds_revision: 0,
            positions_revision: 0,
            fluid: None,
            fluid_mask: None,
            wetted: None,
            granular: None,
            pressure: None,
        };
        debug_assert!(body.ghost_owners.len() < body.reference.len());
        check_shapes(&body.reference, &body.horizons, delta)?;
        Ok(body)
    }

    /// Folds the deviatoric modulus of a calibrated material into the pair springs:
    /// `(mu, lam) -> (0, lam + 2 mu)` keeps `c = mu + lam / 2`, so every affine deformation
    /// stores the same energy, and drops the penalty on deformations that are not affine
    /// within a horizon, which bends a layer of particles with a stiffness set by the spacing
    /// rather than the section ([`super::thin`]). The paper's `Elastic::Paper` is kept as given.
    pub(super) fn fold_deviatoric(&mut self) {
        if self.moduli.bulk_moment.is_some() {
            self.moduli.lam += 2.0 * self.moduli.mu;
            self.moduli.mu = 0.0;
        }
    }

    /// A fluid body (He et al. 2017, section 6) of particles at `reference` (m) on a lattice of
    /// `spacing` (m) with the rest density `density` (kg/m^3): no elastic bonds' stiffness (a
    /// Newtonian liquid) or, with a shear modulus, the elastoplastic bonds of a viscoelastic
    /// fluid ([`ViscoelasticFluid::elastoplastic`]), the density constraints and viscosity of
    /// `fluid` applied by the solver. Fails, naming the culprit, as [`Self::new`] does or on a bad fluid parameter.
    pub fn fluid(
        reference: Vec<Vector3<f64>>,
        spacing: f64,
        density: f64,
        fluid: ViscoelasticFluid,
    ) -> Result<Self> {
        fluid.validate()?;
        let elastoplastic = fluid.elastoplastic();
        let material = elastoplastic.map_or(FLUID_PLACEHOLDER, |(m, _)| m);
        let params = ParticleParams {
            spacing,
            density,
            horizon: None,
            material,
        };
        let mut body = Self::new(reference, params)?;
        match elastoplastic {
            Some((_, law)) => body.plasticity = Some(law),
            None => body.moduli = FLUID_MODULI,
        }
        body.fluid = Some(fluid);
        Ok(body)
    }
    /// The fluid material of a fluid body.
    pub fn fluid_material(&self) -> Option<&ViscoelasticFluid> {
        self.fluid.as_ref()
    }

    pub fn id(&self) -> u64 {
        self.id
    }
    pub fn params(&self) -> &ParticleParams {
        &self.params
    }
    pub fn num_particles(&self) -> usize {
        self.reference.len()
    }
    /// Reference positions (m).
    pub fn reference(&self) -> &[Vector3<f64>] {
        &self.reference
    }
    pub fn horizons(&self) -> &Horizons {
        &self.horizons
    }
    /// Horizon radius (m).
    pub fn horizon(&self) -> f64 {
        self.params.delta()
    }
    /// The paper's `mu`, `lam` and the dilatation modulus `kappa` (Pa) of the body.
    pub fn moduli(&self) -> Moduli {
        self.moduli
    }
    /// Volume of each particle (m^3): `spacing^3` for a solid, the share of the section for a
    /// shell or a rod ([`super::thin`]).
    pub fn volume(&self) -> f64 {
        self.volume
    }
    pub fn density(&self) -> f64 {
        self.params.density
    }
    /// Mass of each particle (kg).
    pub fn particle_mass(&self) -> f64 {
        self.params.density * self.volume()
    }
    /// How far a particle keeps from a collider's surface (m): half the spacing for a solid,
    /// half the thickness of a shell, the radius of a rod. Ghosts keep none (they never collide).
    pub fn margin(&self) -> f64 {
        self.margin
    }
    /// The particles that are not ghosts: `0..num_real()`.
    pub fn num_real(&self) -> usize {
        self.reference.len() - self.ghost_owners.len()
    }
    /// The real particle each ghost belongs to (ghost `k` is particle `num_real() + k`).
    pub fn ghost_owners(&self) -> &[u32] {
        &self.ghost_owners
    }
    /// True for a ghost particle (index `>= num_real()`).
    pub fn is_ghost(&self, i: usize) -> bool {
        i >= self.num_real()
    }

    /// Positions (m).
    pub fn positions(&self) -> &[Vector3<f64>] {
        &self.state.positions
    }
    /// Velocities (m/s).
    pub fn velocities(&self) -> &[Vector3<f64>] {
        &self.state.velocities
    }
    /// Replaces the positions (m); every value must be finite. The last step's pressure,
    /// which was of other positions, reads zeros until the next step.
    pub fn set_positions(&mut self, positions: Vec<Vector3<f64>>) -> Result<()> {
        self.state
            .check_field("positions", "particle", &positions)?;
        self.state.positions = positions;
        self.positions_revision += 1;
        // The last step's pressure was of other positions: zeros until the next step.
        self.pressure = None;
        Ok(())
    }
    /// See [`Self::set_positions`].
    pub fn positions_revision(&self) -> u64 {
        self.positions_revision
    }
    /// Counts the positions as replaced without changing them, as [`Self::set_positions`]
    /// does: for a solver whose body another solver stepped in between (the Python edge's
    /// hand-over), whose record of it (grain friction, stiffness) is then of other positions.
    pub fn mark_positions_replaced(&mut self) {
        self.positions_revision += 1;
        self.pressure = None;
    }
    /// Replaces the velocities (m/s); every value must be finite.
    pub fn set_velocities(&mut self, velocities: Vec<Vector3<f64>>) -> Result<()> {
        self.state
            .check_field("velocities", "particle", &velocities)?;
        self.state.velocities = velocities;
        Ok(())
    }
    /// Pins particles at `targets` (m; default: where they are). A real particle's ghosts are
    /// pinned with it, each at its place moved as its owner is moved to its target, so a
    /// clamped shell or rod is clamped in rotation too.
    pub fn pin(&mut self, indices: &[i64], targets: Option<&[Vector3<f64>]>) -> Result<()> {
        self.state.check_pins("particle", indices, targets)?;
        self.state.insert_pins(indices, targets);
        let (ghosts, ghost_targets) = self.ghosts_of(indices, targets);
        self.state.insert_pins(&ghosts, Some(&ghost_targets));
        Ok(())
    }
    /// Releases the given particles (all when `None`), a real particle's ghosts with it;
    /// unknown indices are an error.
    pub fn unpin(&mut self, indices: Option<&[i64]>) -> Result<()> {
        self.state.unpin("particle", indices)?;
        if let Some(list) = indices {
            let (ghosts, _) = self.ghosts_of(list, None);
            let pinned: Vec<i64> = ghosts
                .into_iter()
                .filter(|&g| self.state.pins.contains_key(&(g as u32)))
                .collect();
            self.state.unpin("particle", Some(&pinned))?;
        }
        Ok(())
    }
    /// The ghosts of the real particles among `indices` (checked) and their positions moved
    /// by their owners' moves to `targets` (m; none: where they are).
    fn ghosts_of(
        &self,
        indices: &[i64],
        targets: Option<&[Vector3<f64>]>,
    ) -> (Vec<i64>, Vec<Vector3<f64>>) {
        if self.ghost_owners.is_empty() {
            return (Vec::new(), Vec::new());
        }
        let x = &self.state.positions;
        let first = self.num_real();
        let mut moves = std::collections::HashMap::new();
        for (k, &i) in indices.iter().enumerate() {
            let i = i as usize;
            if i < first {
                moves.insert(i as u32, targets.map_or(Vector3::zeros(), |t| t[k] - x[i]));
            }
        }
        self.ghost_owners
            .iter()
            .enumerate()
            .filter_map(|(k, owner)| {
                let shift = moves.get(owner)?;
                Some(((first + k) as i64, x[first + k] + shift))
            })
            .unzip()
    }
    /// Pinned particles and their targets (m), in ascending particle order.
    pub fn pins(&self) -> &std::collections::BTreeMap<u32, Vector3<f64>> {
        &self.state.pins
    }
    /// Moves the pinned particles' targets (m, in ascending particle order).
    pub fn set_pin_targets(&mut self, targets: &[Vector3<f64>]) -> Result<()> {
        self.state.set_pin_targets(targets)
    }
    /// Solver write-back of a finished step.
    pub(crate) fn state_mut(&mut self) -> (&mut [Vector3<f64>], &mut [Vector3<f64>]) {
        (&mut self.state.positions, &mut self.state.velocities)
    }

    /// Makes the body plastic with `law` (or elastic with `None`), from its current reference
    /// bonds on. Fails, naming the parameter, on a bad law.
    pub fn set_plasticity(&mut self, law: Option<DruckerPrager>) -> Result<()> {
        self.refuse_mixed()?;
        if self.granular.is_some() {
            return Err(crate::error::invalid!(
                "a granular body yields by its material's friction angle: it takes no other \
                 plasticity"
            ));
        }
        if let Some(law) = &law {
            law.validate()?;
        }
        self.plasticity = law;
        Ok(())
    }
    /// Makes the body granular with `material` ([`super::granular`]): its yield law is the
    /// material's, its stiffness follows its density. Fails, naming the parameter, on a bad
    /// material.
    pub fn set_granular(&mut self, material: Granular) -> Result<()> {
        self.refuse_mixed()?;
        material.validate()?;
        self.plasticity = Some(material.yield_law());
        self.granular = Some(material);
        self.wetted = None;
        Ok(())
    }
    /// A sand body's water saturation per particle (dimensionless), or `None` for a body
    /// that is not sand.
    pub fn saturation(&self) -> Option<Vec<f64>> {
        let g = self.granular.as_ref()?;
        Some(
            self.wetted
                .clone()
                .unwrap_or_else(|| vec![g.saturation; self.num_particles()]),
        )
    }
    /// A sand body's saturation per particle once a liquid wetted it ([`super::wet_sand`]).
    pub fn wetted(&self) -> Option<&[f64]> {
        self.wetted.as_deref()
    }
    /// Solver write-back of a sand body's saturations after a step.
    pub(crate) fn set_wetted(&mut self, theta: Vec<f64>) {
        self.wetted = Some(theta);
    }
    /// Per particle, the pressure of its density constraint over the last step a solver took
    /// (Pa; `solve::particles::fluid_pressure`): zeros before any step, after positions were
    /// set ([`Self::set_positions`]) and for a particle without one (a solid, a partner).
    pub fn pressure(&self) -> Vec<f64> {
        (self.pressure.clone()).unwrap_or_else(|| vec![0.0; self.num_particles()])
    }
    /// Zeros the pressures a solver wrote, if any (before it writes the next step's).
    pub(crate) fn clear_pressure(&mut self) {
        if let Some(p) = &mut self.pressure {
            p.fill(0.0);
        }
    }
    /// Solver write-back of the pressures: the field to fill (zeros the first time).
    pub(crate) fn pressure_mut(&mut self) -> &mut [f64] {
        let n = self.num_particles();
        self.pressure.get_or_insert_with(|| vec![0.0; n])
    }
    /// The granular material, or `None` for a body that is not sand.
    pub fn granular(&self) -> Option<&Granular> {
        self.granular.as_ref()
    }
    pub fn plasticity(&self) -> Option<&DruckerPrager> {
        self.plasticity.as_ref()
    }
    /// The relaxation time `tau` (s) of the body's plastic return: the fluid material's
    /// `eta_p / G` ([`ViscoelasticFluid::relaxation_time`]) for a viscoelastic fluid, 0 (the
    /// rate-independent return of eq. 18) for every other body. The plastic law reads it here,
    /// so that it does not depend on the fluid material.
    pub fn relaxation_time(&self) -> f64 {
        self.fluid
            .as_ref()
            .map_or(0.0, ViscoelasticFluid::relaxation_time)
    }
    /// The current reference bonds of a plastic body that a solver has stepped (`None`
    /// before: the bonds are those of [`Self::reference`] and [`Self::horizons`]).
    pub fn rest_bonds(&self) -> Option<&RestBonds> {
        self.rest_bonds.as_ref()
    }
    /// The reference bonds as they are now, whichever holds them.
    pub fn current_rest_bonds(&self) -> RestBonds {
        self.rest_bonds
            .clone()
            .unwrap_or_else(|| RestBonds::from_reference(&self.reference, &self.horizons))
    }
    /// Replaces a plastic body's reference bonds (a restored state: `None` goes back to the
    /// bonds of the reference positions), checked against the body; solvers stepping the
    /// body take them from their next step on. Fails, naming the culprit, on bad bonds or
    /// bonds given to an elastic body (which keeps its reference bonds for ever).
    pub fn restore_rest_bonds(&mut self, bonds: Option<RestBonds>) -> Result<()> {
        self.refuse_mixed()?;
        if let Some(bonds) = &bonds {
            if self.plasticity.is_none() {
                return Err(crate::error::invalid!(
                    "an elastic particle body keeps the bonds of its reference positions: \
                     only a plastic body takes bonds"
                ));
            }
            bonds.check(self.num_particles())?;
        }
        self.rest_bonds = bonds;
        self.bonds_revision += 1;
        Ok(())
    }
    /// See [`Self::restore_rest_bonds`].
    pub fn bonds_revision(&self) -> u64 {
        self.bonds_revision
    }
    /// Solver write-back of a plastic body's bonds after a step.
    pub(crate) fn set_rest_bonds(&mut self, bonds: &RestBonds) {
        match &mut self.rest_bonds {
            Some(mine) => mine.clone_from(bonds),
            None => self.rest_bonds = Some(bonds.clone()),
        }
    }

    /// Changes the body's material during a run (He et al. 2017, section 8 and Fig. 19: a
    /// fluid that becomes an elastic solid, or a solid that melts): the particles keep their
    /// positions, velocities and pins, and the bonds are born at the current positions, which
    /// become the reference. `Some(fluid)` makes a fluid body (as [`Self::fluid`]: no elastic
    /// stiffness, or a viscoelastic fluid's elastoplastic bonds; the default horizon), `None` an
    /// elastic one (a viscoelastic fluid leaves its yield law behind) of `elastic` (Pa) with the
    /// default horizon. Solvers stepping the body build its working set anew at their next
    /// step. Fails, changing nothing, on a bad material, a shell or rod (ghosts), sand or a
    /// plastic body made fluid, or a particle whose neighbourhood at the current positions is
    /// not three-dimensional (naming it).
    pub fn set_material(
        &mut self,
        elastic: Elastic,
        fluid: Option<ViscoelasticFluid>,
    ) -> Result<()> {
        let reference = self.state.positions.clone();
        self.adopt_material(elastic, fluid, None, reference)
    }

    /// [`Self::set_material`] with the body's horizon `horizon` (m; `None`: the default) and
    /// `reference` positions (m) for its bonds: also the restore of a saved material state
    /// ([`MaterialState`]).
    pub(super) fn adopt_material(
        &mut self,
        elastic: Elastic,
        fluid: Option<ViscoelasticFluid>,
        horizon: Option<f64>,
        reference: Vec<Vector3<f64>>,
    ) -> Result<()> {
        if !self.ghost_owners.is_empty() || self.granular.is_some() {
            return Err(crate::error::invalid!(
                "only a solid or fluid body changes its material: a shell, rod or sand keeps its own"
            ));
        }
        // A viscoelastic fluid's plasticity is its own (its yield law); a solid's is the user's.
        let own_plasticity = self.plasticity.is_some() && self.fluid.is_none();
        if let Some(fluid) = &fluid {
            fluid.validate()?;
            if own_plasticity {
                return Err(crate::error::invalid!(
                    "a plastic body cannot become a fluid: set its plasticity to None first"
                ));
            }
        }
        let elastoplastic = fluid.as_ref().and_then(ViscoelasticFluid::elastoplastic);
        let params = ParticleParams {
            horizon,
            material: match (&fluid, elastoplastic) {
                (_, Some((material, _))) => material,
                (Some(_), None) => FLUID_PLACEHOLDER,
                (None, None) => elastic,
            },
            ..self.params
        };
        params.validate()?;
        let delta = params.delta();
        let horizons = find_horizons(&reference, delta)?;
        check_shapes(&reference, &horizons, delta)?;
        let moduli = match (&fluid, elastoplastic) {
            (Some(_), None) => FLUID_MODULI,
            _ => params.material.resolve(params.spacing, delta)?,
        };
        if let Some((_, law)) = elastoplastic {
            self.plasticity = Some(law);
        } else if !own_plasticity {
            self.plasticity = None;
        }
        self.reference = reference;
        self.horizons = horizons;
        self.params = params;
        self.moduli = moduli;
        self.fluid = fluid;
        self.fluid_mask = None;
        self.rest_bonds = None;
        self.bonds_revision += 1;
        Ok(())
    }

    /// Kinetic energy `sum m v^2 / 2` (J).
    pub fn kinetic_energy(&self) -> f64 {
        let m = self.particle_mass();
        self.state
            .velocities
            .iter()
            .map(|v| 0.5 * m * v.norm_squared())
            .sum()
    }
}
