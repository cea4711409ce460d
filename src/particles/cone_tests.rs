//! Tests of the return within the local step ([`super`]): it is the return the step's end
//! stores, and it changes nothing inside the cone.

use nalgebra::Vector3;

use crate::particles::tests::lattice;
use crate::particles::{
    evaluate_particles, Elastic, Granular, ParticleParams, ParticleRest, Particles, PlasticLaw,
    RestBonds, RestConstants,
};

/// A 6^3 block of dry sand on a lattice of 1 cm (30 degrees).
fn block() -> Particles {
    let x = lattice([6, 6, 6], 0.01);
    let params = ParticleParams {
        spacing: 0.01,
        density: 1600.0,
        horizon: None,
        material: Elastic::Paper { mu: 0.0, lam: 1e5 },
    };
    let mut body = Particles::new(x, params).unwrap();
    body.set_granular(Granular::new(30.0, 0.0)).unwrap();
    body
}

/// The bond forces and energies of `rest` at `y`.
fn forces(rest: &ParticleRest<f64>, y: &[Vector3<f64>]) -> (Vec<Vector3<f64>>, Vec<f64>) {
    let mut bonds = vec![Vector3::zeros(); rest.indices.len()];
    let mut energy = vec![0.0; rest.len()];
    evaluate_particles(rest, y, &mut bonds, &mut energy);
    (bonds, energy)
}

/// The block's positions scaled by `scale` and sheared by `shear` (x += shear z).
fn deformed(body: &Particles, scale: f64, shear: f64) -> Vec<Vector3<f64>> {
    let c = Vector3::repeat(0.025);
    body.positions()
        .iter()
        .map(|p| {
            let q = (p - c) * scale;
            c + q + Vector3::x() * (shear * q.z)
        })
        .collect()
}

/// Sheared by 10 % and compressed (the return to the cone's side, `alpha = 0`) or stretched
/// (to the apex, `beta = 1`: dry sand's bonds then carry nothing) by 1 %: the kernel with the
/// cones gives every bond the force, and every particle the energy, of the bonds that the
/// return at a step's end ([`PlasticLaw::apply`]) stores at the same positions, evaluated
/// without cones (to 1e-9 of the largest elastic force: lengths are computed the same way,
/// directions differ and do not enter a pair-spring bond); most particles yield. The
/// elastic forces differ from them by more than 1 % of the largest.
/// Inside the cone (a uniform compression) the cones change nothing, bit for bit.
#[test]
fn the_kernels_return_gives_the_forces_of_the_stored_return() {
    let body = block();
    let constants = RestConstants::of(&body);
    assert!(constants.returns_in_kernel());
    let law = PlasticLaw::of(&body).unwrap();
    let bonds = body.current_rest_bonds();
    let lam = vec![1.2e5; body.num_particles()];
    let rest_of = |bonds: &RestBonds, cones: bool| {
        let mut rest = ParticleRest::<f64>::of_bodies(&[&body]).unwrap();
        rest.refill(&[(bonds, constants, Some(&lam))]).unwrap();
        if cones {
            rest.set_cones(0, &law, &vec![0.0; lam.len()], None);
        }
        rest
    };
    let within = rest_of(&bonds, true);
    let elastic = rest_of(&bonds, false);
    for scale in [0.99, 1.01] {
        let y = deformed(&body, scale, 0.1);
        let (kernel, kernel_energy) = forces(&within, &y);
        let mut stored = bonds.clone();
        let mut flags = vec![false; body.num_particles()];
        let yielded = law.apply(&mut stored, &y, &mut flags, None);
        assert!(yielded > body.num_particles() / 2, "{yielded}");
        let (after, after_energy) = forces(&rest_of(&stored, false), &y);
        let (before, _) = forces(&elastic, &y);
        let largest = before.iter().map(|g| g.norm()).fold(0.0, f64::max);
        let apart = |a: &[Vector3<f64>]| {
            a.iter()
                .zip(&after)
                .map(|(g, h)| (g - h).norm())
                .fold(0.0, f64::max)
        };
        assert!(
            apart(&kernel) < 1e-9 * largest,
            "{} {largest}",
            apart(&kernel)
        );
        assert!(
            apart(&before) > 1e-2 * largest,
            "{} {largest}",
            apart(&before)
        );
        for (a, b) in kernel_energy.iter().zip(&after_energy) {
            assert!((a - b).abs() <= 1e-9 * b.abs().max(1e-12), "{a} {b}");
        }
    }
    let y = deformed(&body, 0.99, 0.0);
    let (kernel, energy) = forces(&within, &y);
    let (plain, plain_energy) = forces(&elastic, &y);
    assert_eq!(kernel, plain);
    assert_eq!(energy, plain_energy);
}
