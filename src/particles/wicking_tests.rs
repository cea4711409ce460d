//! Tests of the capillary wicking between grains ([`super`]): the analytic 1D diffusion,
//! the rate at free surfaces, conservation, the bounds, the substeps, their cap and the
//! thread count.

use nalgebra::Vector3;

use super::*;
use crate::geometry::find_horizons;

const SPACING: f64 = 0.01;
const HORIZON: f64 = 2.2 * SPACING;

/// A bar of `length` x `side` x `side` grains on the lattice, its bonds within the horizon.
fn bar(length: usize, side: usize) -> (Vec<Vector3<f64>>, RestBonds) {
    bar_at(length, side, SPACING)
}

/// [`bar`] on the lattice of `spacing` (m), the horizon 2.2 spacings.
fn bar_at(length: usize, side: usize, spacing: f64) -> (Vec<Vector3<f64>>, RestBonds) {
    let mut y = Vec::new();
    for a in 0..length {
        for b in 0..side {
            for c in 0..side {
                y.push(Vector3::new(a as f64, b as f64, c as f64) * spacing);
            }
        }
    }
    let horizons = find_horizons(&y, 2.2 * spacing).unwrap();
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
        assert_eq!(wicking.wick(&bonds, &y, &mut theta, h).unwrap(), 1);
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

/// The Laplacian of a field that varies along the bar as `x^2` is 2 times its coefficient
/// everywhere, so one short step raises every saturation at `2 b D` (`theta = 0.2 + b x^2`,
/// `D` = 1e-5 m^2/s, 1 ms) in a 9 x 9 x 9 block: exactly (to 1e-9, the lattice normalisation)
/// at its centre, within 12 % at the middle of a face and within 25 % on the middle of an
/// edge (along them). The surface correction restores the kernel's second moment there but
/// not its shape: measured 1.076 and 1.175; without it 0.766 and 0.585, which fail.
#[test]
fn a_quadratic_field_rises_at_its_laplacian_inside_and_near_at_free_surfaces() {
    let (y, bonds) = bar(9, 9);
    let (d, h, b) = (1e-5, 1e-3, 0.5 / (0.08 * 0.08));
    let start: Vec<f64> = y.iter().map(|p| 0.2 + b * p.x * p.x).collect();
    let mut theta = start.clone();
    let mut wicking = Wicking::new(d, HORIZON, SPACING).unwrap();
    assert_eq!(wicking.wick(&bonds, &y, &mut theta, h).unwrap(), 1);
    let rate = |a: usize, b_: usize, c: usize| {
        let i = (a * 9 + b_) * 9 + c;
        (theta[i] - start[i]) / h / (2.0 * b * d)
    };
    let (inside, face, edge) = (rate(4, 4, 4), rate(4, 4, 0), rate(4, 0, 0));
    eprintln!("rate over 2 b D: inside {inside}, face {face}, edge {edge}");
    assert!((inside - 1.0).abs() < 1e-9, "{inside}");
    assert!((face - 1.0).abs() < 0.12, "{face}");
    assert!((edge - 1.0).abs() < 0.25, "{edge}");
}

/// At the largest diffusivity and 10 ms steps on a 1 cm lattice the wicking takes substeps
/// (`ceil(2 h D max sum G)`), stays within [0, 1] and conserves the water; a grain with no
/// neighbour keeps its saturation.
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
    let substeps = wicking.wick(&bonds, &y, &mut theta, 0.01).unwrap();
    eprintln!("substeps {substeps}");
    assert!(substeps >= 5, "{substeps}");
    let now: f64 = theta.iter().sum();
    assert!((now - total).abs() <= 1e-12 * total, "{now} {total}");
    assert!(theta.iter().all(|t| (0.0..=1.0).contains(t)));
    assert_eq!(theta[lone], 0.3);
}

/// The substeps grow as `D h / spacing^2`: the largest diffusivity over 10 ms steps on a 1 mm
/// lattice would need about a thousand (a hundred times the 1 cm lattice's), more than
/// [`MAX_WICKING_SUBSTEPS`]: refused naming `wicking`, the diffusivity, the step, the spacing
/// and the substeps, and no water moves. A step ten times shorter at a tenth of the
/// diffusivity there is taken.
#[test]
fn a_step_that_needs_too_many_substeps_is_refused_and_moves_no_water() {
    let spacing = 1e-3;
    let (y, bonds) = bar_at(12, 3, spacing);
    let start: Vec<f64> = (0..y.len()).map(|i| (i % 2) as f64).collect();
    let mut theta = start.clone();
    let mut wicking = Wicking::new(MAX_WICKING, 2.2 * spacing, spacing).unwrap();
    let message = wicking
        .wick(&bonds, &y, &mut theta, 0.01)
        .unwrap_err()
        .to_string();
    eprintln!("{message}");
    for part in ["wicking=0.01", "0.01 s", "0.001 m", "substeps", "100"] {
        assert!(message.contains(part), "{part}: {message}");
    }
    assert_eq!(theta, start);
    let mut wicking = Wicking::new(MAX_WICKING / 10.0, 2.2 * spacing, spacing).unwrap();
    let substeps = wicking.wick(&bonds, &y, &mut theta, 1e-3).unwrap();
    assert!((2..=MAX_WICKING_SUBSTEPS).contains(&substeps), "{substeps}");
    assert_ne!(theta, start);
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
                    wicking.wick(&bonds, &y, &mut theta, 0.01).unwrap();
                }
                theta
            })
    };
    assert_eq!(run(1), run(2));
}
