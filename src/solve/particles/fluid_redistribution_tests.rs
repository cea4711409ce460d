//! Tests of the redistribution's density hold ([`super`]).

use nalgebra::Vector3;

use crate::particles::{DensitySolver, Particles, ViscoelasticFluid};
use crate::solve::points::Points;
use crate::solve::Timings;

use super::FluidStage;

/// Lattice spacing (m) and rest density (kg/m^3) of the test's water.
const SPACING: f64 = 0.01;
const WATER: f64 = 1000.0;

/// The redistribution's passes, and the most its hold takes.
const PASSES: usize = 10;

/// A 6 x 6 x 6 block of water, its lattice squeezed to 0.97 of the spacing and each particle
/// shifted by up to 0.15 spacings per axis (a fixed pattern), so that its densities are uneven
/// and above rest inside.
fn jittered_block(fluid: ViscoelasticFluid) -> Particles {
    let mut x = Vec::new();
    for i in 0..6 {
        for j in 0..6 {
            for k in 0..6 {
                let n = Vector3::new(i as f64, j as f64, k as f64);
                let seed = (36 * i + 6 * j + k) as f64;
                let jitter = Vector3::new(
                    (12.9898 * seed).sin(),
                    (78.233 * seed).sin(),
                    (37.719 * seed).sin(),
                );
                x.push((n * 0.97 + jitter * 0.15) * SPACING);
            }
        }
    }
    Particles::fluid(x, SPACING, WATER, fluid).unwrap()
}

/// Each member's plain SPH density (kg/m^3) at `y` over the stage's last neighbour lists.
fn densities(stage: &FluidStage<f64>, y: &[Vector3<f64>]) -> Vec<f64> {
    let csr = (&stage.offsets[..], &stage.indices[..]);
    (0..y.len())
        .map(|i| stage.sph.density(i, y, csr.0, csr.1, &stage.mass))
        .collect()
}

/// The largest relative excess `rho_i / ceiling_i - 1` of the members' densities at `y`.
fn excess(stage: &FluidStage<f64>, y: &[Vector3<f64>], ceiling: &[f64]) -> f64 {
    (densities(stage, y).iter().zip(ceiling))
        .map(|(&rho, &top)| rho / top - 1.0)
        .fold(f64::NEG_INFINITY, f64::max)
}

/// The redistribution (strength 1, [`PASSES`] passes) and its hold (up to as many passes) of
/// [`jittered_block`] with the density solver `solver`, after a projection alone: the
/// largest relative excess over the ceilings `max(rho0, rho before the redistribution)`
/// without the hold (the same redistribution passes from the same positions) and with it,
/// and the density tolerance. Asserts that the stage's ceilings are those and that the
/// redistribution moved the members.
fn hold_excess(solver: DensitySolver) -> (f64, f64, f64) {
    let fluid = ViscoelasticFluid {
        density_solver: solver,
        redistribution: 1.0,
        redistribution_iterations: PASSES,
        ..ViscoelasticFluid::default()
    };
    let mut body = jittered_block(fluid);
    let n = body.num_particles();
    let mass = vec![body.particle_mass(); n];
    let bodies = [&mut body];
    let mut points = Points::<f64>::new(&bodies, mass, vec![0.5 * SPACING; n]);
    points.load(&bodies);
    points.y.clone_from(&points.y_start);
    let mut stage = FluidStage::<f64>::of(&bodies).unwrap().unwrap();
    // The projection alone: the densities it leaves are the ceilings' `rho_i`.
    stage.redistribution = 0.0;
    stage
        .project(&mut points, 0.01, &[], &mut Timings::default())
        .unwrap();
    let projected = stage.y.clone();
    let ceiling: Vec<f64> = (stage.density.iter().zip(&stage.rest_density))
        .map(|(&rho, &rho0)| rho.max(rho0))
        .collect();
    let mut unheld = projected.clone();
    let fixed = vec![false; n];
    (stage.redistributor)
        .run(
            &stage.sph,
            &mut unheld,
            &stage.offsets,
            &stage.indices,
            &stage.mass,
            &stage.rest_density,
            &fixed,
            1.0,
            PASSES,
        )
        .unwrap();
    let without = excess(&stage, &unheld, &ceiling);
    // The redistribution and its hold, as the stage runs them.
    stage.redistribution = 1.0;
    stage.redistribute(&points, &[]).unwrap();
    assert_eq!(stage.ceiling, ceiling, "{solver:?}");
    let moved = (stage.y.iter().zip(&projected)).any(|(a, b)| a != b);
    assert!(moved, "{solver:?}: the redistribution moved nothing");
    (without, excess(&stage, &stage.y, &ceiling), stage.tolerance)
}

/// With either density solver, after the redistribution and its hold no member's density
/// exceeds its ceiling by more than the density tolerance (relative), where the
/// redistribution alone leaves one above it by more than 1 % (so the hold had work to do).
/// The conjugate gradients' hold is budgeted in linearisations, as Jacobi's: counted in its
/// solves' iterations it took one and left 0.76 %.
#[test]
fn the_hold_keeps_every_density_within_its_ceiling() {
    for solver in [DensitySolver::Jacobi, DensitySolver::ConjugateGradients] {
        let (without, with, tolerance) = hold_excess(solver);
        assert!(without > 0.01, "{solver:?}: {without}");
        assert!(
            with <= tolerance,
            "{solver:?}: {with} over its ceiling after the hold (without {without})"
        );
    }
}
