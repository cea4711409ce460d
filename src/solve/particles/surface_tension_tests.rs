//! Tests of the surface tension's forces ([`super`]).

use nalgebra::Vector3;

use crate::geometry::find_horizons;
use crate::particles::sph::{Kernel, Sph};
use crate::particles::FLUID_SUPPORT;

use super::super::fluid_viscosity::Fluid;
use super::{cohesion, gamma_per_tension, pair, SurfaceTension};

/// Lattice spacing (m), rest density (kg/m^3) and surface tension (N/m) of the tests' water.
const SPACING: f64 = 0.01;
const WATER: f64 = 1000.0;
const SIGMA: f64 = 0.07;

/// The lattice points `(i, j, k) * SPACING` with `keep(i, j, k)`, each moved by up to
/// `jitter` spacings per axis (a fixed pattern).
fn lattice(n: i32, jitter: f64, keep: impl Fn(i32, i32, i32) -> bool) -> Vec<Vector3<f64>> {
    let mut x = Vec::new();
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                if !keep(i, j, k) {
                    continue;
                }
                let seed = (n * n * i + n * j + k) as f64;
                let shake = Vector3::new(
                    (12.9898 * seed).sin(),
                    (78.233 * seed).sin(),
                    (37.719 * seed).sin(),
                );
                x.push((Vector3::new(i as f64, j as f64, k as f64) + shake * jitter) * SPACING);
            }
        }
    }
    x
}

/// The forces (N) of the surface tension [`SIGMA`] on the water particles at `y`, with the
/// tension and the stage's data they were computed from handed to `check`.
fn with_forces(y: Vec<Vector3<f64>>, check: impl Fn(&SurfaceTension<f64>, &Fluid<'_, f64>)) {
    let sph = Sph::on_lattice(Kernel::Spiky, FLUID_SUPPORT * SPACING, SPACING).unwrap();
    let found = find_horizons(&y, sph.radius).unwrap();
    let n = y.len();
    let m = WATER * SPACING.powi(3);
    let (mass, rest, nu) = (vec![m; n], vec![WATER; n], vec![1e-6; n]);
    let members: Vec<u32> = (0..n as u32).collect();
    let partner = vec![false; n];
    let stage = Fluid {
        sph: &sph,
        offsets: &found.offsets,
        indices: &found.indices,
        y: &y,
        mass: &mass,
        rest_density: &rest,
        nu: &nu,
        members: &members,
        partner: &partner,
        h: 1e-3,
    };
    let gamma = SIGMA * gamma_per_tension(sph.radius, SPACING, m);
    let mut tension = SurfaceTension::new(vec![gamma; n]);
    tension.forces(&stage);
    check(&tension, &stage);
}

#[test]
fn the_cohesion_spline_is_continuous_and_attracts_at_every_lattice_distance() {
    let h = FLUID_SUPPORT;
    let below = cohesion(h, 0.5 * h - 1e-12);
    let above = cohesion(h, 0.5 * h + 1e-12);
    assert!((below - above).abs() < 1e-9 * above, "{below} {above}");
    for r in [1.0, 2f64.sqrt(), 3f64.sqrt(), 2.0] {
        assert!(cohesion(h, r) > 0.0, "C({r}) = {}", cohesion(h, r));
    }
    assert_eq!(cohesion(h, h), 0.0);
}

/// Momentum: each pair's forces are equal and opposite to the last bit, and the total force
/// on a jittered block is zero to round-off.
#[test]
fn the_pair_forces_are_equal_and_opposite() {
    with_forces(lattice(6, 0.2, |_, _, _| true), |tension, stage| {
        let buffers = (&tension.gamma[..], &tension.density[..]);
        let mut pairs = 0;
        for i in 0..stage.y.len() {
            for &j in &stage.indices[stage.offsets[i] as usize..stage.offsets[i + 1] as usize] {
                let (f, g) = (
                    pair(stage, buffers, i, j as usize),
                    pair(stage, buffers, j as usize, i),
                );
                assert_eq!(f, -g, "pair {i} {j}");
                pairs += 1;
            }
        }
        assert!(pairs > 1000);
        let total: Vector3<f64> = tension.force().iter().sum();
        let scale: f64 = tension.force().iter().map(|f| f.norm()).sum();
        assert!(scale > 0.0);
        assert!(total.norm() < 1e-12 * scale, "{total:?} of {scale}");
    });
}

/// Inside a uniform lattice the cohesion cancels: the force on a particle more than two
/// supports deep is zero to round-off, on a face particle not.
#[test]
fn a_uniform_interior_feels_no_force() {
    with_forces(lattice(11, 0.0, |_, _, _| true), |tension, stage| {
        let centre = stage
            .y
            .iter()
            .position(|y| (y - Vector3::repeat(5.0 * SPACING)).norm() < 1e-9)
            .unwrap();
        let face = stage
            .y
            .iter()
            .position(|y| (y - Vector3::new(5.0, 5.0, 0.0) * SPACING).norm() < 1e-9)
            .unwrap();
        let (inside, outside) = (tension.force()[centre], tension.force()[face]);
        assert!(outside.norm() > 0.0);
        assert!(
            inside.norm() < 1e-12 * outside.norm(),
            "{inside:?} against {outside:?}"
        );
        // The face particle is pulled into the liquid.
        assert!(outside.z > 0.0, "{outside:?}");
    });
}

/// On a ball of liquid, the surface tension pulls every particle of its outer shell inwards
/// (radial component < 0).
#[test]
fn a_ball_is_pulled_in_at_its_surface() {
    let c = 5.0;
    let ball = |i: i32, j: i32, k: i32| {
        let d = Vector3::new(i as f64 - c, j as f64 - c, k as f64 - c);
        d.norm() <= 4.6
    };
    with_forces(lattice(11, 0.0, ball), |tension, stage| {
        let centre = Vector3::repeat(c * SPACING);
        let mut shell = 0;
        for (y, f) in stage.y.iter().zip(tension.force()) {
            let out = (y - centre) / SPACING;
            if out.norm() > 3.9 {
                shell += 1;
                assert!(f.dot(&out) < 0.0, "at {out:?}: {f:?}");
            }
        }
        assert!(shell > 100, "{shell}");
    });
}
