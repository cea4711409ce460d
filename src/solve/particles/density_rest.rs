//! The rest densities of the adhered ghosts' constraints (beyond the paper; issue 40; the
//! adhesion of [`super::fluid`]).
//!
//! **Why.** An adhered ghost held a two-sided constraint asking `rho0` of its density
//! corrected for the neighbours it misses, `rho~_i = rho_i + k |M_i|^2` ([`crate::particles::sph_deficiency`]),
//! whose `k` makes the flat face of a rest lattice exactly `rho0`. Where faces meet, the
//! missing neighbours are not two half-spaces' sum (their overlap is missed once, not twice)
//! and `rho~` misses `rho0` on the rest lattice itself: 0.934 `rho0` on the outer top edge of
//! a column's ghost walls (spiky kernel, support 2.2 spacings), 0.960 on the rim of a ceiling
//! one spacing wider than the blob under it, 0.846 at its corners. No position of the liquid
//! met those constraints, so every projection of an adhesion scene ran to its pass cap, and
//! their pull, not the constraint, held the liquid at the edges.
//!
//! **The rest density.** A ghost that is adhered ([`adhered`]) where the liquid rests holds
//! its plain SPH density at what it is there:
//!
//! `C_i = rho_i / rho*_i - 1`, `rho*_i = min(rho_i(X), rho0_i)`,
//!
//! `rho_i(X)` at the members' reference positions `X` (the positions their bodies were made
//! with; the liquid is taken to rest there), with the pins of the step. It holds exactly on
//! the rest configuration, edges and corners included, and it sees the liquid leave: a column's
//! top layer sunk by half a spacing lowers its wall's edge ghosts' `rho` by 3.2 %, where `rho~`
//! moves by 0.08 % (its `k |M|^2` fills in for liquid that leaves as for air). The cap keeps a
//! ghost from asking the liquid to be denser than rest (a liquid made overlapping). A ghost
//! the liquid does not touch at rest (a wall it reaches later) has no rest with it and keeps
//! `rho~_i / rho0_i - 1`, which a flat face meets exactly. Found from the reference positions
//! and the pins alone, the rest densities need no saving with a state.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::error::Result;
use crate::geometry::find_horizons;
use crate::particles::sph::Sph;
use crate::real::Real;

/// Whether member `i` is an adhered ghost: a wall member (`wall(i)`: pinned, not a partner)
/// with a free fluid member (neither a wall nor a partner) among its neighbours
/// `indices[offsets[i]..offsets[i + 1]]`.
pub(super) fn adhered(
    i: usize,
    (offsets, indices): (&[u32], &[u32]),
    wall: impl Fn(usize) -> bool,
    partner: &[bool],
) -> bool {
    let row = &indices[offsets[i] as usize..offsets[i + 1] as usize];
    wall(i)
        && row
            .iter()
            .any(|&j| !wall(j as usize) && !partner[j as usize])
}

/// The rest densities `rho*_i` (kg/m^3; see the module's doc) of the ghosts adhered at rest.
#[derive(Debug, Default)]
pub(super) struct GhostRest<T: Real> {
    /// The members' reference positions (m).
    reference: Vec<Vector3<f64>>,
    /// The members' pins the densities were found for (empty before the first).
    pinned: Vec<bool>,
    /// Per member, `rho*_i`; `None` for a member that is no adhered ghost at rest.
    density: Vec<Option<T>>,
}

impl<T: Real> GhostRest<T> {
    /// For members at the reference positions `reference` (m).
    pub fn new(reference: Vec<Vector3<f64>>) -> Self {
        Self {
            reference,
            pinned: Vec::new(),
            density: Vec::new(),
        }
    }

    /// Per member, `rho*_i` (kg/m^3) of the last [`Self::update`] (`None`: no adhered ghost at
    /// rest).
    pub fn density(&self) -> &[Option<T>] {
        &self.density
    }

    /// The rest densities for the members' pins `pinned`, found anew only when the pins
    /// changed: `sph` the constraints' kernel, `mass` (kg), `rest` (`rho0_i`, kg/m^3) and
    /// `partner` per member.
    pub fn update(
        &mut self,
        pinned: impl Iterator<Item = bool> + Clone,
        sph: &Sph,
        mass: &[T],
        rest: &[T],
        partner: &[bool],
    ) -> Result<()> {
        if !self.pinned.is_empty() && pinned.clone().eq(self.pinned.iter().copied()) {
            return Ok(());
        }
        self.pinned.clear();
        self.pinned.extend(pinned);
        let found = find_horizons(&self.reference, sph.radius)?;
        let csr = (&found.offsets[..], &found.indices[..]);
        let mass: Vec<f64> = mass.iter().map(|m| m.to_f64()).collect();
        let (x, pinned) = (&self.reference, &self.pinned);
        let wall = |i: usize| pinned[i] && !partner[i];
        let density = (0..x.len())
            .into_par_iter()
            .map(|i| {
                let rho = sph.density(i, x, csr.0, csr.1, &mass);
                adhered(i, csr, wall, partner).then(|| T::of(rho.min(rest[i].to_f64())))
            })
            .collect();
        self.density = density;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::sph::Kernel;

    /// A 3 x 3 x 2 blob of cell centres (spacing `d`) under a two-layer ceiling one spacing
    /// wider on every side; returns the positions (m) and which are the ceiling's.
    fn blob_under_a_ceiling(d: f64) -> (Vec<Vector3<f64>>, Vec<bool>) {
        let mut points = Vec::new();
        let mut ceiling = Vec::new();
        for a in -1..4 {
            for b in -1..4 {
                for c in -2..2 {
                    let inside = (0..3).contains(&a) && (0..3).contains(&b);
                    if c >= 0 || inside {
                        let p = Vector3::new(a as f64, b as f64, c as f64) + Vector3::repeat(0.5);
                        points.push(p * d);
                        ceiling.push(c >= 0);
                    }
                }
            }
        }
        (points, ceiling)
    }

    /// Every ghost adhered in the rest configuration asks for its plain density there (a
    /// ceiling's rim corners 0.6319 `rho0`, its rims' middles 0.7545, as numpy has them), the
    /// others nothing; when the pins change, the rest densities follow (the ceiling unpinned:
    /// none is asked).
    #[test]
    fn each_ghost_adhered_at_rest_asks_for_its_density_there() {
        let (d, m): (f64, f64) = (0.01, 1e-3);
        let rho0 = m / d.powi(3);
        let sph = Sph::on_lattice(Kernel::Spiky, 2.2 * d, d).unwrap();
        let (x, ceiling) = blob_under_a_ceiling(d);
        let n = x.len();
        let (mass, rest, partner) = (vec![m; n], vec![rho0; n], vec![false; n]);
        let found = find_horizons(&x, sph.radius).unwrap();
        let csr = (&found.offsets[..], &found.indices[..]);
        let mut ghosts = GhostRest::<f64>::new(x.clone());
        ghosts
            .update(ceiling.iter().copied(), &sph, &mass, &rest, &partner)
            .unwrap();
        let wall = |i: usize| ceiling[i];
        let (mut corners, mut rims) = (0, 0);
        for (i, asked) in ghosts.density().iter().enumerate() {
            if !adhered(i, csr, wall, &partner) {
                assert_eq!(*asked, None, "{i}");
                continue;
            }
            let asked = asked.unwrap();
            let rho = sph.density(i, &x, csr.0, csr.1, &mass);
            assert!((asked - rho).abs() < 1e-12 * rho0, "{i}");
            let k = (x[i] / d).map(|c| c.floor() as i64);
            let rim = |c: i64| c == -1 || c == 3;
            if k.z == 0 && rim(k.x) && rim(k.y) {
                assert!((asked / rho0 - 0.6319).abs() < 1e-4, "{}", asked / rho0);
                corners += 1;
            }
            if k.z == 0 && (rim(k.x) && k.y == 1 || rim(k.y) && k.x == 1) {
                assert!((asked / rho0 - 0.7545).abs() < 1e-4, "{}", asked / rho0);
                rims += 1;
            }
        }
        assert_eq!((corners, rims), (4, 4));
        ghosts
            .update(std::iter::repeat_n(false, n), &sph, &mass, &rest, &partner)
            .unwrap();
        assert!(ghosts.density().iter().all(Option::is_none));
    }
}
