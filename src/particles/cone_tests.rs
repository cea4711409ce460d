//! Tests of the return within the local step ([`super`]): it is the return the step's end
//! stores, and it changes nothing inside the cone.

use nalgebra::Vector3;

use crate::particles::deformation::deformation_gradient;
use crate::particles::tests::lattice;
use crate::particles::{
    evaluate_particles, DruckerPrager, Elastic, Granular, ParticleParams, ParticleRest, Particles,
    PlasticLaw, RestBonds, RestConstants,
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

/// The rest data of `body` with the bonds `bonds`, granular `lam` per particle (Pa) if any,
/// and with `cones` the cones of its law (the bonds' plastic strains and volume ratios).
fn rest_of(
    body: &Particles,
    bonds: &RestBonds,
    lam: Option<&[f64]>,
    cones: bool,
) -> ParticleRest<f64> {
    let mut rest = ParticleRest::<f64>::of_bodies(&[body]).unwrap();
    rest.refill(&[(bonds, RestConstants::of(body), lam)])
        .unwrap();
    if cones {
        let law = PlasticLaw::of(body).unwrap();
        rest.set_cones(0, &law, bonds, None);
    }
    rest
}

/// Asserts that the kernel's bond forces `kernel` are the stored return's `after` to 1e-9 of
/// the largest elastic force (in `before`), and that the elastic ones are not (more than 1 %
/// of it apart).
fn assert_the_stored_forces(
    kernel: &[Vector3<f64>],
    after: &[Vector3<f64>],
    before: &[Vector3<f64>],
) {
    let largest = before.iter().map(|g| g.norm()).fold(0.0, f64::max);
    let apart = |a: &[Vector3<f64>]| {
        a.iter()
            .zip(after)
            .map(|(g, h)| (g - h).norm())
            .fold(0.0, f64::max)
    };
    assert!(
        apart(kernel) < 1e-9 * largest,
        "{} {largest}",
        apart(kernel)
    );
    assert!(
        apart(before) > 1e-2 * largest,
        "{} {largest}",
        apart(before)
    );
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
    assert!(constants.plastic);
    let law = PlasticLaw::of(&body).unwrap();
    let bonds = body.current_rest_bonds();
    let lam = vec![1.2e5; body.num_particles()];
    let within = rest_of(&body, &bonds, Some(&lam), true);
    let elastic = rest_of(&body, &bonds, Some(&lam), false);
    for scale in [0.99, 1.01] {
        let y = deformed(&body, scale, 0.1);
        let (kernel, kernel_energy) = forces(&within, &y);
        let mut stored = bonds.clone();
        let mut flags = vec![false; body.num_particles()];
        let yielded = law.apply(&mut stored, &y, &mut flags, None, &mut Vec::new());
        assert!(yielded > body.num_particles() / 2, "{yielded}");
        let (after, after_energy) = forces(&rest_of(&body, &stored, Some(&lam), false), &y);
        let (before, _) = forces(&elastic, &y);
        assert_the_stored_forces(&kernel, &after, &before);
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

/// A 6^3 block of clay on a lattice of 1 cm (`mu > 0` and a dilatation term: E = 500 kPa,
/// nu = 0.3) with the friction angle `phi` (degrees) and the cohesion 2 kPa.
fn clay(phi: f64) -> Particles {
    let x = lattice([6, 6, 6], 0.01);
    let params = ParticleParams {
        spacing: 0.01,
        density: 1800.0,
        horizon: None,
        material: Elastic::Young { e: 5e5, nu: 0.3 },
    };
    let mut body = Particles::new(x, params).unwrap();
    let law = DruckerPrager {
        friction_angle: phi,
        cohesion: 2e3,
        hardening: 0.0,
        rebuild_neighbours: false,
    };
    body.set_plasticity(Some(law)).unwrap();
    body
}

/// Clay (`mu > 0`, `kappa > 0`, phi = 30 degrees) stretched uniformly by 1 %: beyond the
/// cone's apex (`9 K e_iso` = 37.5 kPa against `A / B` = 10.4 kPa) every particle returns
/// to it, and the stored return scales every bond by the same factor, so the stored
/// neighbourhood is an affine image of the step's and its `F' X'` is `Y`. The kernel with
/// the cones then gives every bond the force of the stored bonds (to 1e-9 of the largest
/// elastic force): the deviatoric springs, the isotropic ones and the dilatation pressure
/// `9 kappa V s` with its shares `w V_j / (A_i |X'|)` of the returned lengths
/// ([`super::Factors::returned`]). Without the cones the forces differ by more than 1 %.
#[test]
fn clays_return_in_the_kernel_gives_the_stored_returns_forces_at_the_apex() {
    let body = clay(30.0);
    let constants = RestConstants::of(&body);
    assert!(constants.moduli.mu > 0.0 && constants.moduli.kappa > 0.0);
    let law = PlasticLaw::of(&body).unwrap();
    let bonds = body.current_rest_bonds();
    let n = body.num_particles();
    let y = deformed(&body, 1.01, 0.0);
    let (kernel, _) = forces(&rest_of(&body, &bonds, None, true), &y);
    let mut stored = bonds.clone();
    assert_eq!(
        law.apply(&mut stored, &y, &mut vec![false; n], None, &mut Vec::new()),
        n
    );
    let (after, _) = forces(&rest_of(&body, &stored, None, false), &y);
    let (before, _) = forces(&rest_of(&body, &bonds, None, false), &y);
    assert_the_stored_forces(&kernel, &after, &before);
}

/// Clay (`mu > 0` and a dilatation term: E = 500 kPa, nu = 0.3, phi = 0, c = 2 kPa) returns
/// within the local step too. Sheared by 5 % and compressed by 1 % (an affine deformation,
/// beyond the yield strain `2 c / E` = 0.8 % everywhere), the kernel with the cones gives the
/// bond forces of the bonds the step's end stores (evaluated without cones) to within 0.5 % of
/// how far the elastic forces are from them (0.27 % measured): the kernel keeps `F_i` and the deviatoric
/// directions of the step's bonds, which the stored bonds reproduce to first order only
/// (each bond's length is its own). Every particle yields.
#[test]
fn clay_returns_within_the_local_step_to_first_order() {
    let body = clay(0.0);
    let constants = RestConstants::of(&body);
    assert!(constants.plastic && constants.moduli.mu > 0.0);
    assert!(constants.moduli.kappa != 0.0);
    let law = PlasticLaw::of(&body).unwrap();
    let bonds = body.current_rest_bonds();
    let n = body.num_particles();
    let y = deformed(&body, 0.99, 0.05);
    let (kernel, _) = forces(&rest_of(&body, &bonds, None, true), &y);
    let mut stored = bonds.clone();
    let yielded = law.apply(&mut stored, &y, &mut vec![false; n], None, &mut Vec::new());
    assert_eq!(yielded, n);
    let (after, _) = forces(&rest_of(&body, &stored, None, false), &y);
    let (before, _) = forces(&rest_of(&body, &bonds, None, false), &y);
    let apart = |a: &[Vector3<f64>]| {
        a.iter()
            .zip(&after)
            .map(|(g, h)| (g - h).norm_squared())
            .sum::<f64>()
            .sqrt()
    };
    assert!(
        apart(&kernel) < 5e-3 * apart(&before),
        "{} {}",
        apart(&kernel),
        apart(&before)
    );
}

/// A clay particle's neighbourhood collapsed onto it (the interior particle and every
/// particle within its horizon at one point, E = 500 kPa, nu = 0.3, phi = 0, c = 2 kPa):
/// the collapsed particle (`e_iso = -1`, no deviation) stays inside its cone; its neighbours
/// (bonds of zero length beside bonds stretched by up to 2 horizons) and the particles
/// around the point yield; a bond of zero length, which no reference length gives another
/// strain than -1, keeps its length and share ([`super::Factors::returned`]). The kernel with
/// the cones gives finite forces and energies everywhere, and every particle that yields
/// without a bond of zero length is left on its cone (`sqrt(J2)` within 1e-3 of `A + B I1`
/// at the kernel's returned lengths, as the return at a step's end: `plasticity_tests`).
/// At the floor itself (`1 + e'` below 1e-6, `e_iso = -1`) a returned bond keeps its length
/// when it has no length to give and takes `|Y| / 1e-6` otherwise, both finite.
#[test]
fn a_collapsed_neighbourhood_returns_to_finite_forces_and_onto_its_cone() {
    let body = clay(0.0);
    let n = body.num_particles();
    let rest = rest_of(&body, &body.current_rest_bonds(), None, true);
    let x = body.positions();
    let centre = (0..n)
        .min_by(|&a, &b| {
            let c = Vector3::repeat(0.025);
            (x[a] - c).norm().total_cmp(&(x[b] - c).norm())
        })
        .unwrap();
    let y: Vec<Vector3<f64>> = x
        .iter()
        .map(|p| match (p - x[centre]).norm() <= body.horizon() {
            true => x[centre],
            false => *p,
        })
        .collect();
    let collapsed = y.iter().filter(|p| **p == x[centre]).count();
    assert!(collapsed > 20, "{collapsed}");
    let (forces, energy) = forces(&rest, &y);
    assert!(forces.iter().all(|g| g.iter().all(|c| c.is_finite())));
    assert!(energy.iter().all(|e| e.is_finite()));
    let range = |i: usize| rest.offsets[i] as usize..rest.offsets[i + 1] as usize;
    let bond_vectors = |i: usize| -> Vec<Vector3<f64>> {
        range(i)
            .map(|b| y[rest.indices[b] as usize] - y[i])
            .collect()
    };
    let (mut on_cone, mut with_zero) = (0, 0);
    for i in 0..n {
        let cone = rest.cones[i].unwrap();
        let (bonds_i, ys) = (&rest.bonds[range(i)], bond_vectors(i));
        let neighbours = &rest.indices[range(i)];
        let f = deformation_gradient(i, neighbours, bonds_i, &rest.shape_inverse[i], &y);
        let Some(factors) = cone.local_return(bonds_i, &ys, || f.determinant()) else {
            continue;
        };
        assert_ne!(
            i, centre,
            "the collapsed particle has no deviation to return"
        );
        let returned: Vec<_> = bonds_i
            .iter()
            .zip(&ys)
            .map(|(b, y)| factors.returned(b, y))
            .collect();
        assert!(returned
            .iter()
            .all(|b| b.length.is_finite() && b.length > 0.0 && b.share.is_finite()));
        if ys.iter().any(|y| y.norm() == 0.0) {
            with_zero += 1;
            continue;
        }
        let strain = |b: &super::BondRest<f64>, y: &Vector3<f64>| y.norm() / b.length - 1.0;
        let weight: f64 = returned.iter().map(|b| b.weight).sum();
        let iso = returned
            .iter()
            .zip(&ys)
            .map(|(b, y)| b.weight * strain(b, y))
            .sum::<f64>()
            / weight;
        let square: f64 = returned
            .iter()
            .zip(&ys)
            .map(|(b, y)| b.weight * (strain(b, y) - iso).powi(2))
            .sum();
        let (sqrt_j2, strength) = cone.state(iso, (square / weight).sqrt());
        assert!(
            (sqrt_j2 - strength).abs() < 1e-3 * strength,
            "{i}: {sqrt_j2} {strength}"
        );
        on_cone += 1;
    }
    assert!(on_cone > 20 && with_zero > 20, "{on_cone} {with_zero}");
    // At the floor: a neighbourhood collapsed to `e_iso = -1` with a deviation left.
    let factors = super::Factors {
        alpha: 0.0,
        beta: 0.5,
        iso: -1.0,
        kept: -1.0,
    };
    let bond = rest.bonds[0];
    assert_eq!(
        factors.returned(&bond, &Vector3::zeros()).length,
        bond.length
    );
    let tiny = bond.xi * 1e-7;
    let floored = factors.returned(&bond, &tiny);
    assert!((floored.length - tiny.norm() / 1e-6).abs() < 1e-12 * bond.length);
    assert!(floored.share.is_finite() && floored.share > bond.share);
}

/// A return that keeps the rest volume takes `cbrt(J_i) - 1` where it is within
/// [`super::KEPT_CORRECTION`] of eq. 18's mean (to 1e-15), and moves that mean by the bound
/// only where `det F_i` says the volume is far off (a flattened neighbourhood: `J_i` = 8 or
/// 1/8 at `e_iso` = 0.001, so the kept mean is 0.011 or -0.009), in both precisions.
#[test]
fn the_rest_volume_moves_the_kept_mean_by_a_bounded_step() {
    let cone = |ratio: f64| super::Cone {
        a: 100.0,
        b: 0.0,
        bulk9: 1e6,
        shear15: 1e6,
        volume: Some(ratio),
        relaxation_time: 0.0,
        step: 0.0,
    };
    let (iso, dev) = (0.001, 0.01);
    let near = cone(1.0).factors_at(iso, dev, 1.005f64).unwrap();
    assert!(
        (near.kept - (1.005f64.cbrt() - 1.0)).abs() < 1e-15,
        "{near:?}"
    );
    for (det, kept) in [(8.0, iso + 0.01), (0.125, iso - 0.01)] {
        let far = cone(1.0).factors_at(iso, dev, det).unwrap();
        assert!((far.kept - kept).abs() < 1e-15, "{det}: {far:?}");
        let single = super::Cone::<f32> {
            a: 100.0,
            b: 0.0,
            bulk9: 1e6,
            shear15: 1e6,
            volume: Some(1.0),
            relaxation_time: 0.0,
            step: 0.0,
        };
        let far32 = single
            .factors_at(iso as f32, dev as f32, det as f32)
            .unwrap();
        assert!((far32.kept as f64 - kept).abs() < 1e-6, "{det}: {far32:?}");
    }
}

/// The rate-dependent return ([`super::Cone::relaxed`]): in a steady deviatoric flow, each
/// step adding `d h` to the RMS deviation `||e_dev||` (`d` = 2/s, `h` = 5 ms), the state
/// settles at the overstress `sqrt(J2) - A = sqrt(15) G tau d` (`tau` = 0.1 s: 0.2 of the
/// yield strain's stress, to 1e-9 of it after 1000 steps; the return takes `h / (tau + h)` of
/// the way to the cone), in both precisions (f32 to 1e-4); `tau = 0` is eq. 18's return to
/// the last bit, at any step.
#[test]
fn a_rate_dependent_return_keeps_the_bingham_overstress_of_a_steady_flow() {
    fn steady<T: crate::real::Real>(tau: f64) -> f64 {
        let cone = super::Cone::<T> {
            a: T::of(1000.0),
            b: T::zero(),
            bulk9: T::of(1e5),
            shear15: T::of(15f64.sqrt() * 500.0),
            volume: None,
            relaxation_time: T::of(tau),
            step: T::of(0.005),
        };
        let (rate, h) = (T::of(2.0), T::of(0.005));
        let mut dev = T::zero();
        for _ in 0..1000 {
            let trial = dev + rate * h;
            dev = cone
                .factors(T::zero(), trial)
                .map_or(trial, |f| (T::one() - f.beta) * trial);
        }
        (cone.shear15 * dev - cone.a).to_f64()
    }
    let expected = 15f64.sqrt() * 500.0 * 0.1 * 2.0;
    let q = steady::<f64>(0.1);
    assert!((q / expected - 1.0).abs() < 1e-9, "{q} against {expected}");
    let q32 = steady::<f32>(0.1);
    assert!(
        (q32 / expected - 1.0).abs() < 1e-4,
        "{q32} against {expected}"
    );
    assert!(steady::<f64>(0.0).abs() < 1e-9);
    let plain = super::Cone {
        a: 100.0,
        b: 0.0,
        bulk9: 1e6,
        shear15: 1e6,
        volume: None,
        relaxation_time: 0.0,
        step: 0.0,
    };
    let timed = super::Cone {
        step: 0.005,
        ..plain
    };
    assert_eq!(plain.factors(0.001, 0.01), timed.factors(0.001, 0.01));
}

/// The relaxed return is Duvaut and Lions' update in both of eq. 18's regions: from a trial
/// beyond the apex (`B` = 0.3, `f` = -200 Pa, `sqrt(J2)` = 200 Pa) and one beyond the side
/// (`f` = 70 Pa), `sqrt(J2)`, `f` and the cone function `sqrt(J2) - f` of the returned state are
/// `(1 - r)` times the trial's plus `r` times eq. 18's return (to 1e-12 of the trial's
/// stress; `tau` = 0.1 s, `h` = 5 ms, `r = h / (tau + h)`). The kept mean's correction toward
/// the rest volume is not relaxed: it reaches `cbrt(J_i) - 1` as the rate-independent one does.
#[test]
fn the_relaxed_return_interpolates_toward_eq_18_at_the_apex_and_keeps_the_volume_whole() {
    let plain = super::Cone {
        a: 100.0,
        b: 0.3,
        bulk9: 1e6,
        shear15: 1e6,
        volume: None,
        relaxation_time: 0.0,
        step: 0.005,
    };
    let timed = super::Cone {
        relaxation_time: 0.1,
        ..plain
    };
    let r = 0.005 / 0.105;
    let state = |f: &super::Factors<f64>, dev: f64| plain.state(f.kept, (1.0 - f.beta) * dev);
    for (iso, dev) in [(0.001, 0.0002), (0.0001, 0.0002)] {
        let trial = plain.state(iso, dev);
        let full = state(&plain.factors(iso, dev).unwrap(), dev);
        let relaxed = state(&timed.factors(iso, dev).unwrap(), dev);
        let mix = |t: f64, f: f64| (1.0 - r) * t + r * f;
        let tol = 1e-12 * trial.0;
        assert!(
            (relaxed.0 - mix(trial.0, full.0)).abs() < tol,
            "{relaxed:?} {full:?}"
        );
        assert!(
            (relaxed.1 - mix(trial.1, full.1)).abs() < tol,
            "{relaxed:?} {full:?}"
        );
        let over = |s: (f64, f64)| s.0 - s.1;
        assert!(
            (over(relaxed) - (1.0 - r) * over(trial) - r * over(full)).abs() < tol,
            "{iso}: {relaxed:?} {trial:?}"
        );
    }
    let anchored = |relaxation_time: f64| super::Cone {
        b: 0.0,
        volume: Some(1.0),
        relaxation_time,
        ..plain
    };
    let det = 1.005f64;
    for tau in [0.0, 0.1] {
        let f = anchored(tau).factors_at(0.001, 0.01, det).unwrap();
        assert!((f.kept - (det.cbrt() - 1.0)).abs() < 1e-15, "{tau}: {f:?}");
    }
}
