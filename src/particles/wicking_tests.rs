//! Tests of the capillary wicking between grains ([`super`]): the analytic 1D diffusion,
//! conservation, the bounds, the substeps and the thread count.

use nalgebra::Vector3;

use super::*;
use crate::geometry::find_horizons;

const SPACING: f64 = 0.01;
const HORIZON: f64 = 2.2 * SPACING;

/// A bar of `length` x `side` x `side` grains on the lattice, its bonds within the horizon.
fn bar(length: usize, side: usize) -> (Vec<Vector3<f64>>, RestBonds) {
    let mut y = Vec::new();
    for a in 0..length {
        for b in 0..side {
            for c in 0..side {
                y.push(Vector3::new(a as f64, b as f64, c as f64) * SPACING);
            }
        }
    }
    let horizons = find_horizons(&y, HORIZON).unwrap();
    let bonds = RestBonds::from_reference(&y, &horizons);
    (y, bonds)
}

/// `erfc(x)` within 1.5e-7 (Abramowitz and Stegun 7.1.26).
fn erfc(x: f64) -> f64 {
    if x < 0.0 {
        return 2.0 - erfc(-x);
    }
    let t = 1.0 / (1.0 + 0.327_591_1 * x);
    let poly = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    poly * (-x * x).exp()
}

/// The saturations of each layer across the bar (its mean), `side^2` grains a layer.
fn layers(theta: &[f64], side: usize) -> Vec<f64> {
    theta
        .chunks(side * side)
        .map(|l| l.iter().sum::<f64>() / l.len() as f64)
        .collect()
}

/// Where the layers' saturation first falls to `level` past the wet half (m from the
/// interface at 29.5 spacings), linearly between layers.
fn front(profile: &[f64], level: f64) -> f64 {
    let k = (30..profile.len()).find(|&k| profile[k] < level).unwrap();
    let (a, b) = (profile[k - 1], profile[k]);
    ((k - 1) as f64 + (a - level) / (a - b) - 29.5) * SPACING
}

/// A bar of sand 60 grains long, saturated over its first half and dry beyond, at `D` = 1e-3
/// m^2/s, 10 ms steps: the held water spreads as the 1D diffusion from a step,
/// `theta = erfc((x - x_0) / (2 sqrt(D t))) / 2`. The front (where the layers' mean falls to
/// 0.1, analytically `2 sqrt(D t) erfc^-1(0.2)` past the interface) after 0.25 s and 1 s is
/// within 10 % of the analytic depth in a 7 x 7 bar and grows as `sqrt(t)` (its ratio over
/// the four times longer run within 5 % of 2); every layer's mean within 0.03 of the
/// analytic profile at 1 s. The total held water is conserved to 1e-13 of itself and no
/// saturation leaves [0, 1].
#[test]
fn a_wetted_half_bar_wicks_as_the_analytic_1d_diffusion() {
    let (d, h, side) = (1e-3, 0.01, 7);
    let (y, bonds) = bar(60, side);
    let mut theta: Vec<f64> = (0..y.len())
        .map(|i| if i / (side * side) < 30 { 1.0 } else { 0.0 })
        .collect();
    let total: f64 = theta.iter().sum();
    let mut wicking = Wicking::new(d, HORIZON, SPACING).unwrap();
    let mut fronts = Vec::new();
    for step in 1..=100 {
        assert_eq!(wicking.wick(&bonds, &y, &mut theta, h), 1);
        if step == 25 || step == 100 {
            let t = step as f64 * h;
            let profile = layers(&theta, side);
            let depth = front(&profile, 0.1);
            let analytic = 2.0 * (d * t).sqrt() * 0.906_193_8;
            eprintln!(
                "t {t}: front {depth} analytic {analytic} ratio {}",
                depth / analytic
            );
            assert!((depth / analytic - 1.0).abs() < 0.1, "{depth} {analytic}");
            fronts.push(depth);
            if step == 100 {
                let worst = profile
                    .iter()
                    .enumerate()
                    .map(|(k, &p)| {
                        let x = (k as f64 - 29.5) * SPACING;
                        (p - erfc(x / (2.0 * (d * t).sqrt())) / 2.0).abs()
                    })
                    .fold(0.0, f64::max);
                eprintln!("worst layer error {worst}");
                assert!(worst < 0.03, "{worst}");
            }
        }
    }
    eprintln!("sqrt(t) ratio {}", fronts[1] / fronts[0]);
    assert!(
        (fronts[1] / fronts[0] / 2.0 - 1.0).abs() < 0.05,
        "{fronts:?}"
    );
    let now: f64 = theta.iter().sum();
    eprintln!("conservation {}", (now - total).abs() / total);
    assert!((now - total).abs() <= 1e-13 * total, "{now} {total}");
    assert!(theta.iter().all(|t| (0.0..=1.0).contains(t)));
}

/// The surface correction: 1 inside the lattice, about 1.48 on a flat face, 2.22 on an edge
/// and 3.42 at a corner (the lattice's second moment over the share a grain there keeps).
#[test]
fn the_surface_correction_restores_the_lattice_moment() {
    let (y, bonds) = bar(9, 9);
    let mut wicking = Wicking::new(1e-5, HORIZON, SPACING).unwrap();
    let mut theta = vec![0.5; y.len()];
    wicking.wick(&bonds, &y, &mut theta, 1e-3);
    let at = |a: usize, b: usize, c: usize| wicking.correction[(a * 9 + b) * 9 + c];
    for (value, expected) in [
        (at(4, 4, 4), 1.0),
        (at(4, 4, 0), 1.4766),
        (at(4, 0, 0), 2.2205),
        (at(0, 0, 0), 3.4177),
    ] {
        assert!((value - expected).abs() < 1e-4, "{value} {expected}");
    }
    assert!(
        theta.iter().all(|&t| t == 0.5),
        "a uniform saturation stays"
    );
}

/// At the largest diffusivity and 10 ms steps on a 1 cm lattice the wicking takes substeps
/// (`ceil(2 h D max sum G)`: measured 10), stays within [0, 1] and conserves the water; a
/// grain with no neighbour keeps its saturation.
#[test]
fn a_large_diffusivity_takes_substeps_and_stays_bounded() {
    let (mut y, bonds) = bar(20, 3);
    let lone = y.len() - 1;
    y[lone] += Vector3::new(10.0, 0.0, 0.0) * SPACING;
    let mut theta: Vec<f64> = (0..y.len())
        .map(|i| if i % 7 == 0 { 1.0 } else { 0.0 })
        .collect();
    theta[lone] = 0.3;
    let total: f64 = theta.iter().sum();
    let mut wicking = Wicking::new(MAX_WICKING, HORIZON, SPACING).unwrap();
    let substeps = wicking.wick(&bonds, &y, &mut theta, 0.01);
    eprintln!("substeps {substeps}");
    assert!(substeps >= 5, "{substeps}");
    let now: f64 = theta.iter().sum();
    assert!((now - total).abs() <= 1e-12 * total, "{now} {total}");
    assert!(theta.iter().all(|t| (0.0..=1.0).contains(t)));
    assert_eq!(theta[lone], 0.3);
}

#[test]
fn one_and_two_threads_wick_bit_for_bit() {
    let (y, bonds) = bar(30, 4);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let mut theta: Vec<f64> = (0..y.len())
                    .map(|i| ((i * 37) % 11) as f64 / 10.0)
                    .collect();
                let mut wicking = Wicking::new(1e-3, HORIZON, SPACING).unwrap();
                for _ in 0..5 {
                    wicking.wick(&bonds, &y, &mut theta, 0.01);
                }
                theta
            })
    };
    assert_eq!(run(1), run(2));
}
