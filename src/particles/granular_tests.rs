//! Tests of the granular material's laws (eq. 25-28) and density.

use nalgebra::Vector3;

use super::*;
use crate::particles::sph::{Kernel, Sph};
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
    let mut g = sand(0.0);
    g.rolling_resistance = Some(-0.1);
    assert!(message(g).contains(
        "rolling_resistance must be a finite coefficient >= 0 (or None for none), got -0.1"
    ));
    g.rolling_resistance = Some(f64::INFINITY);
    assert!(message(g).contains("rolling_resistance"));
    g.rolling_resistance = Some(0.0);
    assert!(message(g).contains("rolling_resistance 0 needs contact_friction > 0"));
    g.contact_friction = 0.5;
    assert!(g.validate().is_ok());
    let mut g = sand(0.0);
    g.wicking = 0.02;
    assert!(message(g).contains("wicking must be a capillary diffusivity in [0, 0.01] m^2/s"));
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

/// The density ratio of a block sampled on a cubic lattice: exactly 1 at rest for every
/// particle, faces and corners too (1e-12: the kernel's deficiency at a free surface cancels);
/// compressed by 2 % in every direction (the same bonds), inside within 1 % of the SPH sum's
/// own ratio `sum W(0.98 r) / sum W(r)` over the lattice and above 1 everywhere; stretched by
/// 2 %, below 1 everywhere.
#[test]
fn density_ratio_is_one_at_rest_and_follows_compression_at_the_surface_too() {
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
    assert!(ratios.iter().all(|r| (r - 1.0).abs() < 1e-12), "{ratios:?}");
    let index = |i: usize, j: usize, k: usize| (i * n + j) * n + k;
    let sph = Sph::new(Kernel::Poly6, delta).unwrap();
    let lattice = |scale: f64| {
        let mut sum = 0.0;
        for a in -3i32..=3 {
            for b in -3i32..=3 {
                for c in -3i32..=3 {
                    let r = Vector3::new(a as f64, b as f64, c as f64).norm() * d;
                    sum += sph.value(scale * r);
                }
            }
        }
        sum
    };
    let expected = lattice(0.98) / lattice(1.0);
    let squeezed: Vec<_> = x.iter().map(|p| p * 0.98).collect();
    let ratios = density_ratios(&bonds, &squeezed, delta, volume).unwrap();
    let inside = ratios[index(4, 4, 4)];
    assert!(
        (inside - expected).abs() < 1e-2 * expected,
        "{inside} {expected}"
    );
    assert!(ratios.iter().all(|&r| r > 1.0), "{ratios:?}");
    let stretched: Vec<_> = x.iter().map(|p| p * 1.02).collect();
    let ratios = density_ratios(&bonds, &stretched, delta, volume).unwrap();
    assert!(ratios.iter().all(|&r| r < 1.0), "{ratios:?}");
}

/// The capillary strength is 0 for dry sand and the largest `k_c(r) (1 - r) / 9` over
/// `[rho_1 / rho_0, 1]` for wet sand (against a sampling of 1e5 points, 1e-6), grows with the
/// saturation (0.2 to 0.4), and sets the yield law's cohesion `sigma_t tan(phi)`.
#[test]
fn capillary_strength_is_the_largest_tension_the_cohesion_stiffness_holds() {
    assert_eq!(sand(0.0).capillary_strength(), 0.0);
    assert_eq!(sand(0.0).yield_law().cohesion, 0.0);
    for theta in [0.05, 0.2, 0.4, 1.0] {
        let g = sand(theta);
        let low = g.debonding_ratio();
        let sampled = (0..=100_000)
            .map(|k| low + (1.0 - low) * k as f64 / 100_000.0)
            .map(|r| g.cohesion(r) * (1.0 - r) / 9.0)
            .fold(0.0, f64::max);
        let strength = g.capillary_strength();
        assert!(
            (strength - sampled).abs() < 1e-6 * sampled,
            "{strength} {sampled}"
        );
        let expected = strength * g.friction_angle.to_radians().tan();
        assert!((g.yield_law().cohesion - expected).abs() < 1e-12 * expected);
    }
    assert!(sand(0.4).capillary_strength() > sand(0.2).capillary_strength());
}
