//! The particle kernel: a particle's deformation gradient, its bonds' local step (forces and
//! energy), and the gathered force on each particle (He et al. 2017, eq. 8-12).

use nalgebra::Vector3;

use crate::parallel::for_each_vertex;
use crate::real::Real;

use super::bond::bond_force;
use super::cone::Factors;
use super::deformation::deformation_and_strain;
use super::rest::ParticleRest;

/// Particle `i`'s kernel at the positions `y` (m): writes the force `g` (N) of each of its
/// bonds on `i` into `bond_out` and returns its energy, `V_i Psi_i` (J; eq. 8, with the
/// dilatation term of [`super::bond`]).
///
/// Two passes over the bonds: the first reads each neighbour's position once, keeps the bond
/// vector `Y = y_j - y_i` in `bond_out` (no other storage) and sums `F_i` and the mean strain;
/// the second turns each `Y` into the bond's force in place. A particle with a cone in the
/// rest data (a plastic body's) takes its Drucker-Prager return between them, over the kept
/// `Y` ([`super::cone`]; its energy, and its dilatation term's mean strain, are then those of
/// the returned bonds).
#[inline]
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
        .and_then(|cone| cone.local_return(bonds, bond_out));
    // The dilatation term's mean strain from the returned bonds' lengths and shares.
    let strain = factors.as_ref().map_or(strain, Factors::kept_mean);
    let pressure = rest.dilatation[i] * strain;
    let mut energy = T::of(0.5) * pressure * strain;
    for (bond, out) in bonds.iter().zip(bond_out) {
        let (g, e) = match &factors {
            Some(factors) => bond_force(&factors.returned(bond, out), &f, out, pressure),
            None => bond_force(bond, &f, out, pressure),
        };
        *out = g;
        energy += e;
    }
    energy
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
        particle_kernel(i, rest, y, out)
    });
}

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
