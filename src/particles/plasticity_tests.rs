//! Tests of Drucker-Prager plasticity and changing neighbourhoods (He et al. 2017, section 5).

use nalgebra::{Matrix3, Vector3};

use super::{
    rebuild_neighbours, DruckerPrager, Elastic, ParticleParams, ParticleRest, Particles, PlasticLaw,
};
use crate::solve::{BodyMut, GlobalSolver, Solver, SolverParams};

fn lattice(n: [usize; 3], spacing: f64) -> Vec<Vector3<f64>> {
    let mut out = Vec::new();
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                out.push(Vector3::new(i as f64, j as f64, k as f64) * spacing);
            }
        }
    }
    out
}

fn law(friction_angle: f64, cohesion: f64, rebuild: bool) -> DruckerPrager {
    DruckerPrager {
        friction_angle,
        cohesion,
        hardening: 0.0,
        rebuild_neighbours: rebuild,
    }
}

fn body(n: [usize; 3], plastic: Option<DruckerPrager>) -> Particles {
    body_at(n, plastic, Vector3::zeros())
}

/// [`body`] translated by `offset` (m).
fn body_at(n: [usize; 3], plastic: Option<DruckerPrager>, offset: Vector3<f64>) -> Particles {
    let params = ParticleParams {
        spacing: 0.01,
        density: 1000.0,
        horizon: None,
        material: Elastic::Young { e: 1e5, nu: 0.3 },
    };
    let x = lattice(n, 0.01).into_iter().map(|x| x + offset).collect();
    let mut b = Particles::new(x, params).unwrap();
    b.set_plasticity(plastic).unwrap();
    b
}

/// After the return every particle that yielded lies on the yield surface,
/// `|sqrt(J2) - (A + B I1)| <= 1e-3 sqrt(J2)` before the return (both branches of eq. 18: a
/// shear with `A + B I1 > 0`, and a strong dilation of a frictional body past the cone's
/// apex), and none lies outside it.
#[test]
fn the_return_puts_the_state_on_the_yield_surface() {
    let shear = Matrix3::new(1.0, 0.06, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.97);
    let dilation = Matrix3::identity() * 1.08 + shear - Matrix3::identity();
    for (name, dp, f) in [
        ("shear", law(20.0, 300.0, false), shear),
        ("dilation", law(30.0, 50.0, false), dilation),
    ] {
        let b = body([6, 6, 6], Some(dp));
        let y: Vec<Vector3<f64>> = b
            .reference()
            .iter()
            .enumerate()
            .map(|(i, x)| f * x + Vector3::new(0.0, 0.0, 1e-4 * (i as f64 * 0.7).sin()))
            .collect();
        let plastic = PlasticLaw::of(&b).unwrap();
        let mut bonds = b.current_rest_bonds();
        let before = plastic.yield_states(&bonds, &y);
        let yielded = plastic.apply(
            &mut bonds,
            &y,
            &mut vec![false; y.len()],
            None,
            &mut Vec::new(),
        );
        assert!(yielded > 100, "{name}: {yielded} of 216 yielded");
        let after = plastic.yield_states(&bonds, &y);
        let mut apex = 0;
        for (i, (s0, s1)) in before.iter().zip(&after).enumerate() {
            let (s0, s1) = (s0.unwrap(), s1.unwrap());
            if s0.sqrt_j2 <= s0.strength {
                assert_eq!(
                    s0, s1,
                    "{name}: particle {i} did not yield and must not change"
                );
                continue;
            }
            let tol = 1e-3 * s0.sqrt_j2;
            assert!(
                (s1.sqrt_j2 - s1.strength.max(0.0)).abs() <= tol,
                "{name}: particle {i} at sqrt(J2) {} for A + B I1 {} (before {} {})",
                s1.sqrt_j2,
                s1.strength,
                s0.sqrt_j2,
                s0.strength
            );
            apex += usize::from(s0.strength <= 0.0);
        }
        if name == "dilation" {
            assert!(apex > 0, "the apex branch was not reached");
        }
    }
}

/// Bad parameters are refused, naming the value.
#[test]
fn bad_plastic_parameters_are_refused_by_name() {
    let cases = [
        (law(-1.0, 1.0, true), "friction_angle"),
        (law(90.0, 1.0, true), "friction_angle"),
        (law(f64::NAN, 1.0, true), "friction_angle"),
        (law(10.0, -5.0, true), "cohesion"),
        (law(0.0, 0.0, true), "cohesion = 0"),
        (
            DruckerPrager {
                hardening: -1.0,
                ..law(10.0, 1.0, true)
            },
            "hardening",
        ),
    ];
    for (dp, name) in cases {
        let message = dp.validate().unwrap_err().to_string();
        assert!(message.contains(name), "{message}");
    }
}

/// A plastic body's shape matrices before any step are the elastic body's, bit for bit (its
/// springs are not: a plastic body keeps the isotropic surface factors,
/// `ParticleRest::add_bonds`), and an elastic body stepped beside a plastic one (whose end of step rebuilds the family's rest
/// data) moves exactly as it does alone (with a fixed count of plain Jacobi iterations
/// without line search, so that the bodies do not share a convergence test or step length;
/// the plastic body 1 m away, so that the bodies' repulsion never acts).
#[test]
fn an_elastic_body_is_unchanged_by_plasticity_beside_it() {
    let (elastic, plastic) = (
        body([4, 4, 5], None),
        body([4, 4, 5], Some(law(0.0, 100.0, true))),
    );
    let (a, b) = (
        ParticleRest::<f64>::of_bodies(&[&elastic]).unwrap(),
        ParticleRest::<f64>::of_bodies(&[&plastic]).unwrap(),
    );
    assert_eq!(a.shape_inverse, b.shape_inverse);
    let run = |with_plastic: bool| {
        let mut e = body([4, 4, 5], None);
        e.set_velocities(vec![Vector3::new(0.3, -0.2, 0.5); e.num_particles()])
            .unwrap();
        e.pin(&[0], None).unwrap();
        let mut p = body_at(
            [4, 4, 5],
            Some(law(0.0, 100.0, true)),
            Vector3::new(1.0, 0.0, 0.0),
        );
        p.pin(&[0], None).unwrap();
        p.set_velocities(vec![Vector3::new(0.0, 0.0, 1.0); p.num_particles()])
            .unwrap();
        let params = SolverParams {
            global_solver: GlobalSolver::Jacobi,
            step_length: false,
            tol: 0.0,
            max_iters: 30,
            ..SolverParams::default()
        };
        let mut s = Solver::<f64>::new(params, Some(1)).unwrap();
        for _ in 0..5 {
            if with_plastic {
                s.step(&mut [BodyMut::from(&mut e), BodyMut::from(&mut p)])
                    .unwrap();
            } else {
                s.step(&mut [BodyMut::from(&mut e)]).unwrap();
            }
        }
        assert!(e.rest_bonds().is_none(), "an elastic body keeps its bonds");
        assert_eq!(p.rest_bonds().is_some(), with_plastic);
        e.positions().to_vec()
    };
    assert!(run(false) == run(true));
}

/// A plastic body with changing neighbourhoods, stepped with one and with two threads, in f32
/// and f64: the same bits, for Chebyshev and the direct solver.
#[test]
fn plastic_steps_are_the_same_for_any_thread_count() {
    fn check<T: crate::real::Real>(solver: GlobalSolver) {
        let run = |threads| {
            let mut b = body([5, 5, 8], Some(law(10.0, 50.0, true)));
            b.pin(&[0, 1, 2, 3, 4], None).unwrap();
            b.set_velocities(vec![Vector3::new(0.2, 0.0, 0.5); b.num_particles()])
                .unwrap();
            let p = SolverParams {
                dt: 0.01,
                global_solver: solver,
                max_iters: 20,
                ..SolverParams::default()
            };
            let mut s = Solver::<T>::new(p, Some(threads)).unwrap();
            for _ in 0..6 {
                s.step(&mut [BodyMut::from(&mut b)]).unwrap();
            }
            assert!(b
                .positions()
                .iter()
                .all(|p| p.iter().all(|c| c.is_finite())));
            let bonds = b.rest_bonds().expect("stepped").clone();
            assert!(
                bonds.plastic_strain.iter().any(|&e| e > 0.0),
                "nothing yielded"
            );
            (b.positions().to_vec(), bonds)
        };
        assert!(run(1) == run(2), "{} {solver:?}", T::NAME);
    }
    for solver in [GlobalSolver::Chebyshev, GlobalSolver::Direct] {
        check::<f32>(solver);
        check::<f64>(solver);
    }
}

/// A new neighbour's reference vector comes from the clamped inverse map (eq. 20): under a
/// uniform stretch `F = diag(1.3, 1, 1)` already taken up plastically (the bonds' `X` are the
/// stretched ones), the neighbours that come within the horizon get `X = y_j - y_i` (the
/// rest state is the stretched one); and the pairs that left the horizon lose their bonds.
#[test]
fn new_neighbours_get_reference_vectors_from_the_inverse_map() {
    let b = body([6, 6, 6], Some(law(0.0, 100.0, true)));
    let f = Matrix3::from_diagonal(&Vector3::new(1.3, 1.0, 0.8));
    let y: Vec<Vector3<f64>> = b.reference().iter().map(|x| f * x).collect();
    let mut bonds = b.current_rest_bonds();
    for i in 0..bonds.len() {
        for k in bonds.row(i) {
            bonds.xi[k] = y[bonds.indices[k] as usize] - y[i];
        }
    }
    let rebuilt = rebuild_neighbours(&bonds, &y, b.horizon(), b.volume())
        .unwrap()
        .expect("the neighbours changed");
    let mut new = 0;
    for i in 0..rebuilt.len() {
        for k in rebuilt.row(i) {
            let j = rebuilt.indices[k] as usize;
            let d = y[j] - y[i];
            assert!(d.norm() < b.horizon());
            assert!(
                (rebuilt.xi[k] - d).norm() < 1e-12,
                "particle {i} bond to {j}"
            );
            new += usize::from(bonds.of(i).binary_search(&(j as u32)).is_err());
        }
    }
    assert!(new > 0, "no new neighbour");
}

/// Coincident particles (which the search counts as neighbours) get no bond between them,
/// the bonds stay symmetric and valid, and every other pair keeps its vector and birth length.
#[test]
fn coincident_particles_get_no_bond_and_the_others_keep_theirs() {
    let b = body([4, 4, 4], Some(law(0.0, 100.0, true)));
    let mut y = b.reference().to_vec();
    y[0] = y[1];
    let bonds = b.current_rest_bonds();
    let rebuilt = rebuild_neighbours(&bonds, &y, b.horizon(), b.volume())
        .unwrap()
        .expect("the pairs changed");
    rebuilt.check(y.len()).unwrap();
    assert!(rebuilt.of(0).binary_search(&1).is_err());
    assert!(rebuilt.of(1).binary_search(&0).is_err());
    for i in 0..rebuilt.len() {
        for k in rebuilt.row(i) {
            let j = rebuilt.indices[k];
            if let Ok(m) = bonds.of(i).binary_search(&j) {
                let old = bonds.offsets[i] as usize + m;
                assert_eq!(
                    (rebuilt.xi[k], rebuilt.born[k]),
                    (bonds.xi[old], bonds.born[old])
                );
            }
        }
    }
}

/// The stored return keeps a bond's reference exactly when the kernel's does
/// ([`super::Factors::kept_length`]), and gives it the kernel's length: where eq. 19 gives no
/// direction (`alpha = 1`, `beta = 0`, `e_iso = -1`: `R X (1 + e_iso) = 0`) it takes the
/// deformed bond's, and a bond squeezed below `1e-6` of its reference length keeps it in both.
#[test]
fn the_stored_return_keeps_and_returns_the_bonds_the_kernel_does() {
    let spacing = 0.01;
    let x = Vector3::new(spacing, 0.0, 0.0);
    let bond = super::BondRest {
        xi: x,
        length: spacing,
        weight: 1.0,
        k_dev: 1.0,
        k_iso: 1.0,
        share: 1.0,
    };
    let undirected = super::plasticity::Return {
        factors: super::Factors {
            alpha: 1.0,
            beta: 0.0,
            iso: -1.0,
            kept: 0.0,
        },
        rotation: Matrix3::identity(),
        increment: 0.0,
    };
    let yb = Vector3::new(0.3, 0.4, 0.0) * spacing;
    let kernel = undirected.factors.returned(&bond, &yb).length;
    assert!(kernel != spacing, "{kernel}");
    let moved = undirected
        .moved(&x, &yb)
        .expect("a bond with a length is returned");
    assert!((moved.norm() - kernel).abs() < 1e-15, "{moved} {kernel}");
    assert!(
        (moved / moved.norm() - yb / yb.norm()).norm() < 1e-15,
        "{moved}"
    );
    let squeezing = super::plasticity::Return {
        factors: super::Factors {
            alpha: 0.0,
            beta: 0.5,
            iso: -1.0,
            kept: -1.0,
        },
        ..undirected
    };
    for (scale, kept) in [(1e-13, true), (1e-11, false)] {
        let yb = x * scale;
        let kernel = squeezing.factors.returned(&bond, &yb).length;
        assert_eq!(kernel == spacing, kept, "{scale}: {kernel}");
        assert_eq!(squeezing.moved(&x, &yb).is_none(), kept, "{scale}");
    }
}

/// On a cone without friction the return keeps the rest volume (`super::cone`): clay-like
/// (E = 100 kPa, nu = 0.3, phi = 0, c = 300 Pa) stretched without a change of volume
/// (`F = diag(1.15, 1 / sqrt 1.15, 1 / sqrt 1.15)`, `det F = 1`) far beyond yield: every
/// particle yields, its mean bond strain before the return is not 0 (the deviatoric strain's
/// second-order part, and at the surface its anisotropic bond directions' first-order part:
/// up to more than 4e-3 in size) and the bonds it stores leave it the mean strain
/// `cbrt(J_i) - 1` = 0 at the same positions, or `e_iso` moved toward it by
/// [`super::cone::KEPT_CORRECTION`] where it is further (a corner: 0.030) (1e-12: eq. 18
/// would keep `e_iso`). [`PlasticLaw::reanchor`] then gives every bond the birth length
/// `|X|`, and each particle's volume `J_i = R_i det F_i` with those bonds and weights is the
/// same as before the return (1e-12) and 1 (1e-12: the stretch is affine). A frictional cone
/// (20 degrees) keeps eq. 18's mean `(1 - alpha) e_iso`.
#[test]
fn a_return_without_friction_keeps_the_rest_volume() {
    let s = 1.15f64;
    let f = Matrix3::from_diagonal(&Vector3::new(s, 1.0 / s.sqrt(), 1.0 / s.sqrt()));
    for phi in [0.0, 20.0] {
        let b = body([6, 6, 6], Some(law(phi, 300.0, false)));
        let y: Vec<Vector3<f64>> = b.reference().iter().map(|x| f * x).collect();
        let plastic = PlasticLaw::of(&b).unwrap();
        assert_eq!(plastic.anchored, phi == 0.0);
        let mut bonds = b.current_rest_bonds();
        let (delta, volume) = (plastic.delta, plastic.volume);
        let before: Vec<_> = (0..y.len())
            .map(|i| super::plasticity::local_strain(&bonds, i, &y, delta, volume).unwrap())
            .collect();
        let mut volumes = Vec::new();
        let n = plastic.apply(
            &mut bonds,
            &y,
            &mut vec![false; y.len()],
            None,
            &mut volumes,
        );
        assert_eq!(n, y.len(), "{phi}");
        let returned: Vec<_> = (0..y.len())
            .map(|i| super::plasticity::local_strain(&bonds, i, &y, delta, volume).unwrap())
            .collect();
        let volumes_before = volumes.clone();
        if plastic.anchored {
            let before = bonds.born.clone();
            plastic.reanchor(&mut bonds, &y, &mut volumes);
            assert_ne!(bonds.born, before, "{phi}: no bond was born anew");
            let mut reborn = bonds.born.iter().zip(&bonds.xi);
            assert!(reborn.all(|(&b, x)| b == x.norm()));
        }
        let volumes = volumes_before;
        let largest = before.iter().map(|l| l.iso.abs()).fold(0.0, f64::max);
        assert!(largest > 4e-3, "{phi}: {largest}");
        for (i, (old, new)) in before.iter().zip(&returned).enumerate() {
            let eq18 = plastic
                .cone_at(300.0, 0.0)
                .factors(old.iso, old.dev)
                .unwrap();
            let bound = super::cone::KEPT_CORRECTION;
            let kept = if phi == 0.0 {
                eq18.kept - eq18.kept.clamp(-bound, bound)
            } else {
                eq18.kept
            };
            assert!(
                (new.iso - kept).abs() < 1e-12,
                "{phi} {i}: {} {}",
                new.iso,
                kept
            );
            if phi == 0.0 {
                assert!((volumes[i] - 1.0).abs() < 1e-12, "{i}: {}", volumes[i]);
                let reborn = super::plasticity::local_strain(&bonds, i, &y, delta, volume);
                let j = bonds.volume[i] * reborn.unwrap().f.determinant();
                assert!((j - volumes[i]).abs() < 1e-12, "{i}: {j} {}", volumes[i]);
            }
        }
    }
}

/// A particle's volume ratio is set anew only where it is meaningful
/// ([`super::plasticity::reanchored`]): where its new reference bonds are squeezed flat
/// (their `z` components scaled by 1e-9, so `det F_i = 1e9` at the rest positions and
/// `R_i = J_i / det F_i = 1e-9`) or stretched flat the other way (by 1e9: the shape matrix
/// near singular) it keeps its old ratio, and the bonds pass [`RestBonds::check`]; an
/// unflattened neighbour takes `J_i / det F_i` (1 at rest, 1e-12).
#[test]
fn a_flattened_neighbourhood_keeps_its_volume_ratio() {
    let b = body([6, 6, 6], Some(law(0.0, 300.0, false)));
    let plastic = PlasticLaw::of(&b).unwrap();
    let y = b.reference().to_vec();
    for scale in [1e-9, 1e9] {
        let mut bonds = b.current_rest_bonds();
        bonds.volume[0] = 1.25;
        for k in bonds.row(0) {
            bonds.xi[k].z *= scale;
        }
        let mut volumes = vec![1.0; y.len()];
        plastic.reanchor(&mut bonds, &y, &mut volumes);
        assert_eq!(bonds.volume[0], 1.25, "{scale}");
        assert!((bonds.volume[1] - 1.0).abs() < 1e-12, "{}", bonds.volume[1]);
        bonds.check(y.len()).unwrap();
    }
}
