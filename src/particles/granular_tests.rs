//! Tests of the granular material's laws (eq. 25-28) and density.

use nalgebra::Vector3;

use super::*;
use crate::geometry::find_horizons;
use crate::particles::{Elastic, ParticleParams, Particles};

fn sand(saturation: f64) -> Granular {
    Granular::new(30.0, saturation)
}

/// Eq. 25: no friction stiffness below the reference density, `K_f` at it, growing by
/// `exp(H_f (r - 1))` above it.
#[test]
fn friction_stiffness_follows_eq_25() {
    let g = sand(0.0);
    assert_eq!(g.friction(0.999), 0.0);
    assert_eq!(g.friction(1.0), g.friction_stiffness);
    let r = 1.05;
    let expected = g.friction_stiffness * (g.friction_hardening * 0.05).exp();
    assert!((g.friction(r) - expected).abs() < 1e-9 * expected);
}

/// Eq. 26-27 corrected: `K_c` at and above the reference density, falling off continuously
/// below it as `exp(-H_0 theta^-1/2 (1 - r))` down to `rho_1 = (1 - b theta) rho_0`, zero
/// below; more water reaches further and falls off more slowly; dry sand has none below
/// `rho_0`.
#[test]
fn cohesion_stiffness_follows_eq_26_and_27() {
    let wet = sand(0.4);
    assert_eq!(wet.cohesion(1.2), wet.cohesion_stiffness);
    let just_below = wet.cohesion(1.0 - 1e-12);
    assert!((just_below - wet.cohesion_stiffness).abs() < 1e-6 * wet.cohesion_stiffness);
    let r = 0.9;
    let falloff = wet.cohesion_falloff / 0.4f64.sqrt();
    let expected = wet.cohesion_stiffness * (-falloff * 0.1).exp();
    assert!((wet.cohesion(r) - expected).abs() < 1e-9 * expected);
    assert!((wet.debonding_ratio() - 0.6).abs() < 1e-15);
    assert!(wet.cohesion(0.6 + 1e-9) > 0.0);
    assert_eq!(wet.cohesion(0.6 - 1e-9), 0.0);
    let damp = sand(0.1);
    assert!(wet.cohesion(0.95) > damp.cohesion(0.95));
    assert_eq!(damp.cohesion(0.85), 0.0);
    let dry = sand(0.0);
    assert_eq!(dry.cohesion(0.9999), 0.0);
    assert_eq!(dry.cohesion(1.0), dry.cohesion_stiffness);
    assert_eq!(
        dry.stiffness(1.0),
        dry.friction_stiffness + dry.cohesion_stiffness
    );
}

/// Bad parameters are refused naming the parameter and the value.
#[test]
fn bad_parameters_name_themselves() {
    let message = |g: Granular| g.validate().unwrap_err().to_string();
    assert!(message(Granular::new(0.0, 0.0)).contains("friction_angle"));
    assert!(message(Granular::new(30.0, 1.5))
        .contains("saturation must be a water saturation in [0, 1], got 1.5"));
    let mut g = sand(0.0);
    g.static_friction = Some(1.2);
    assert!(message(g).contains("static_friction"));
    let mut g = sand(0.0);
    g.friction_stiffness = f64::NAN;
    assert!(message(g).contains("friction_stiffness"));
    let mut g = sand(0.0);
    g.debonding = -0.1;
    assert!(message(g).contains("debonding"));
    assert!(sand(1.0).validate().is_ok());
}

/// Eq. 28: a particle the solve pushed all the way back is held; one in free fall (solved
/// at its target) is not; one pushed back by less than `eta` of the way is not; a particle
/// whose target is its start (nothing to stop) is not.
#[test]
fn static_friction_holds_what_friction_pushed_back() {
    let start = Vector3::new(0.0, 0.0, 1.0);
    let star = Vector3::new(0.0, 0.0, 0.999);
    assert!(holds(0.8, &start, &start, &star));
    assert!(holds(0.8, &Vector3::new(0.0, 0.0, 0.9999), &start, &star));
    assert!(!holds(0.8, &star, &start, &star));
    assert!(!holds(0.8, &Vector3::new(0.0, 0.0, 0.9995), &start, &star));
    assert!(!holds(0.8, &start, &start, &start));
}

/// The density of a block sampled on a cubic lattice: exactly the reference density inside
/// (1e-12), less on the faces and least at the corners; compressed by 2 % in every
/// direction, 6 % more inside (within 1 % of it: the discrete sum is not the integral).
#[test]
fn density_is_the_reference_inside_a_lattice_block_and_less_at_its_surface() {
    let (d, n) = (0.01, 8);
    let mut x = Vec::new();
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                x.push(Vector3::new(i as f64, j as f64, k as f64) * d);
            }
        }
    }
    let params = ParticleParams {
        spacing: d,
        density: 1600.0,
        horizon: None,
        material: Elastic::Paper { mu: 0.0, lam: 1e6 },
    };
    let mut body = Particles::new(x.clone(), params).unwrap();
    body.set_granular(sand(0.0)).unwrap();
    let (delta, volume) = (body.horizon(), body.volume());
    let bonds = body.current_rest_bonds();
    let ratios = density_ratios(&bonds, &x, delta, volume).unwrap();
    let index = |i: usize, j: usize, k: usize| (i * n + j) * n + k;
    assert!(
        (ratios[index(4, 4, 4)] - 1.0).abs() < 1e-12,
        "{}",
        ratios[index(4, 4, 4)]
    );
    assert!(ratios[index(0, 4, 4)] < 0.9);
    assert!(ratios[index(0, 0, 0)] < ratios[index(0, 4, 4)]);
    let squeezed: Vec<_> = x.iter().map(|p| p * 0.98).collect();
    let near = find_horizons(&squeezed, delta).unwrap();
    let mut tight = bonds.clone();
    tight.offsets = near.offsets;
    tight.indices = near.indices;
    let ratios = density_ratios(&tight, &squeezed, delta, volume).unwrap();
    let expected = 0.98f64.powi(-3);
    assert!(
        (ratios[index(4, 4, 4)] - expected).abs() < 1e-2 * expected,
        "{}",
        ratios[index(4, 4, 4)]
    );
}
