//! The particle kernel: a particle's deformation gradient, its bonds' local step (forces and
//! energy), and the gathered force on each particle (He et al. 2017, eq. 8-12).

use nalgebra::{Matrix3, SimdBool, SimdValue, Vector3};
use rayon::prelude::*;

use crate::isa;
use crate::parallel::for_each_vertex;
use crate::real::{Lanes, Real};

use super::bond::{bond_energy_lanes, bond_force, bond_force_lanes, BondLanes, BondRest};
use super::cone::Factors;
use super::deformation::deformation_and_strain;
use super::rest::ParticleRest;

/// Particle `i`'s kernel at the positions `y` (m): writes the force `g` (N) of each of its
/// bonds on `i` into `bond_out` and returns its energy, `V_i Psi_i` (J; eq. 8, with the
/// dilatation term of [`super::bond`]).
///
/// Two passes over the bonds: the first reads each neighbour's position once, keeps the bond
/// vector `Y = y_j - y_i` in `bond_out` (no other storage) and sums `F_i` and the mean strain;
/// the second turns each `Y` into the bond's force in place, a SIMD pack of bonds at a time
/// ([`bond_forces_packed`]). A particle with a cone in the rest data (a plastic body's) takes
/// its Drucker-Prager return between them, over the kept `Y` ([`super::cone`]; its energy,
/// and its dilatation term's mean strain, are then those of the returned bonds).
#[inline(always)]
pub fn particle_kernel<T: Real>(
    i: usize,
    rest: &ParticleRest<T>,
    y: &[Vector3<T>],
    bond_out: &mut [Vector3<T>],
) -> T {
    let row = rest.row(i);
    let neighbors = &rest.indices[row.clone()];
    let bonds = &rest.bonds[row];
    let (f, strain) =
        deformation_and_strain(i, neighbors, bonds, &rest.shape_inverse[i], y, |k, d| {
            bond_out[k] = d
        });
    // A plastic particle's return within the local step ([`super::cone`]).
    let factors = rest
        .cones
        .get(i)
        .copied()
        .flatten()
        .and_then(|cone| cone.local_return(bonds, bond_out, || f.determinant()));
    // The dilatation term's mean strain from the returned bonds' lengths and shares.
    let strain = factors.as_ref().map_or(strain, Factors::kept_mean);
    let pressure = rest.dilatation[i] * strain;
    let mut energy = T::of(0.5) * pressure * strain;
    let packed = match &factors {
        Some(factors) => {
            for (bond, out) in bonds.iter().zip(bond_out) {
                let (g, e) = bond_force(&factors.returned(bond, out), &f, out, pressure);
                *out = g;
                energy += e;
            }
            return energy;
        }
        None => bond_forces_packed(bonds, &f, bond_out, pressure, &mut energy),
    };
    for (bond, out) in bonds[packed..].iter().zip(&mut bond_out[packed..]) {
        let (g, e) = bond_force(bond, &f, out, pressure);
        *out = g;
        energy += e;
    }
    energy
}

/// The local step of the bonds `bonds` of one particle, [`Lanes`] bonds at a time (one per
/// lane of `T::Pack`), with its deformation gradient `f` and dilatation pressure `pressure`
/// (J): each whole pack's `Y` in `bond_out` is replaced by its force (N) and its spring
/// energies (J) are added to `energy` in the bonds' order. Returns how many bonds it did
/// (the rest, fewer than a pack, are left to the caller). A pack where some bond has no
/// direction is done one bond at a time ([`bond_force`]). The lanes compute what the scalar
/// [`bond_force`] does, operation for operation ([`bond_force_lanes`]): the results are the
/// same bits as one bond at a time, faster (the square roots and divisions of eight `f32`
/// bonds in one instruction).
#[inline(always)]
fn bond_forces_packed<T: Real>(
    bonds: &[BondRest<T>],
    f: &Matrix3<T>,
    bond_out: &mut [Vector3<T>],
    pressure: T,
    energy: &mut T,
) -> usize {
    let lanes = <T::Pack as SimdValue>::LANES;
    let whole = bonds.len() - bonds.len() % lanes;
    let f_pack = f.map(<T::Pack as SimdValue>::splat);
    let pressure_pack = <T::Pack as SimdValue>::splat(pressure);
    for (bonds, out) in bonds[..whole]
        .chunks_exact(lanes)
        .zip(bond_out[..whole].chunks_exact_mut(lanes))
    {
        let y = |c: usize| T::Pack::gather(|l| out[l][c]);
        let y = Vector3::new(y(0), y(1), y(2));
        let (g, e, directed) =
            bond_force_lanes(&BondLanes::gather(bonds), &f_pack, &y, pressure_pack);
        if directed.all() {
            for (l, out) in out.iter_mut().enumerate() {
                *out = Vector3::new(g.x.extract(l), g.y.extract(l), g.z.extract(l));
                *energy += e.extract(l);
            }
        } else {
            for (bond, out) in bonds.iter().zip(out) {
                let (g, e) = bond_force(bond, f, out, pressure);
                *out = g;
                *energy += e;
            }
        }
    }
    whole
}

/// The kernel of every particle (in parallel, the same for any thread count): bond forces into
/// `bond_force` (one per bond), bond energies per particle into `energy` (J).
pub fn evaluate_particles<T: Real>(
    rest: &ParticleRest<T>,
    y: &[Vector3<T>],
    bond_force: &mut [Vector3<T>],
    energy: &mut [T],
) {
    for_each_vertex(&rest.offsets, bond_force, energy, &|i, out| {
        isa::run(
            #[inline(always)]
            || particle_kernel(i, rest, y, out),
        )
    });
}

/// Particle `i`'s energy `V_i Psi_i` (J) at the positions `y` (m) without its bonds' forces:
/// the bits of [`particle_kernel`]'s, the same operations summed in the same order (the
/// deformation gradient and mean strain, the dilatation energy, then each bond's spring energy,
/// [`Lanes`] bonds at a time), without the forces' divisions and with nothing written per
/// bond: each bond's `Y = y_j - y_i` is formed again where [`particle_kernel`] keeps it.
/// Not for a particle with a cone (its return reads the kept `Y`; [`evaluate_energies`]).
#[inline(always)]
pub fn particle_energy<T: Real>(i: usize, rest: &ParticleRest<T>, y: &[Vector3<T>]) -> T {
    let row = rest.row(i);
    let neighbors = &rest.indices[row.clone()];
    let bonds = &rest.bonds[row];
    let shape_inverse = &rest.shape_inverse[i];
    let (f, strain) = deformation_and_strain(i, neighbors, bonds, shape_inverse, y, |_, _| {});
    let pressure = rest.dilatation[i] * strain;
    let mut energy = T::of(0.5) * pressure * strain;
    let y_i = y[i];
    let lanes = <T::Pack as SimdValue>::LANES;
    let whole = bonds.len() - bonds.len() % lanes;
    let f_pack = f.map(<T::Pack as SimdValue>::splat);
    for (js, group) in neighbors[..whole]
        .chunks_exact(lanes)
        .zip(bonds[..whole].chunks_exact(lanes))
    {
        let mut pack = [[T::zero(); 8]; 3];
        for (l, &j) in js.iter().enumerate() {
            let d = y[j as usize] - y_i;
            for (c, component) in pack.iter_mut().enumerate() {
                component[l] = d[c];
            }
        }
        let component = |c: usize| T::Pack::gather(|l| pack[c][l]);
        let d = Vector3::new(component(0), component(1), component(2));
        let e = bond_energy_lanes(&BondLanes::gather(group), &f_pack, &d);
        for l in 0..lanes {
            energy += e.extract(l);
        }
    }
    for (&j, bond) in neighbors[whole..].iter().zip(&bonds[whole..]) {
        let d = y[j as usize] - y_i;
        energy += bond_energy_lanes(&BondLanes::gather(std::slice::from_ref(bond)), &f, &d);
    }
    energy
}

/// The energy `V_i Psi_i` (J) of every particle at `y` (m) into `energy` ([`particle_energy`],
/// in parallel): the energies [`evaluate_particles`] gives, bit for bit, for a caller that
/// needs no force. Rest data with a cone (a granular body's) is refused: its particles' energy
/// comes from the return only [`evaluate_particles`] takes.
pub fn evaluate_energies<T: Real>(rest: &ParticleRest<T>, y: &[Vector3<T>], energy: &mut [T]) {
    assert!(
        rest.cones.is_empty(),
        "the energy alone is not taken with cones"
    );
    energy
        .par_chunks_mut(ENERGY_CHUNK)
        .enumerate()
        .for_each(|(chunk, out)| {
            isa::run(
                #[inline(always)]
                || {
                    for (k, e) in out.iter_mut().enumerate() {
                        *e = particle_energy(chunk * ENERGY_CHUNK + k, rest, y);
                    }
                },
            )
        });
}

/// Particles per parallel task of [`evaluate_energies`].
const ENERGY_CHUNK: usize = 512;

/// The internal force on particle `i` (N): its bonds' forces on it minus their reverses',
/// `sum_j (g_ij - g_ji)` (eq. 12, `V_i sum_j V_j (T_i<xi> - T_j<-xi>)`).
#[inline(always)]
pub fn particle_force<T: Real>(
    i: usize,
    rest: &ParticleRest<T>,
    bond_force: &[Vector3<T>],
) -> Vector3<T> {
    let mut f = Vector3::zeros();
    for b in rest.row(i) {
        f += bond_force[b] - bond_force[rest.reverse[b] as usize];
    }
    f
}
