//! Tests of the particle family in the solver: free fall, the global solvers against each
//! other, colliders, thread-count invariance, membranes and particles in one solver.

use nalgebra::Vector3;

use crate::collider::{Collider, Shape};
use crate::particles::{Elastic, Granular, ParticleParams, Particles};
use crate::real::Real;
use crate::solve::{BodyMut, GlobalSolver, Solver, SolverParams};

fn lattice(n: [usize; 3], spacing: f64, origin: Vector3<f64>) -> Vec<Vector3<f64>> {
    let mut out = Vec::new();
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                out.push(origin + Vector3::new(i as f64, j as f64, k as f64) * spacing);
            }
        }
    }
    out
}

pub(crate) fn block(n: [usize; 3], spacing: f64, e: f64) -> Particles {
    let params = ParticleParams {
        spacing,
        density: 1000.0,
        horizon: None,
        material: Elastic::Young { e, nu: 0.25 },
    };
    Particles::new(lattice(n, spacing, Vector3::zeros()), params).unwrap()
}

fn params(solver: GlobalSolver, dt: f64) -> SolverParams {
    SolverParams {
        dt,
        global_solver: solver,
        max_iters: 200,
        tol: 1e-7,
        ..SolverParams::default()
    }
}

/// Free fall of an unstressed body with any global solver is implicit Euler exactly:
/// `v_{n+1} = v_n + h g`, `x_{n+1} = x_n + h v_{n+1}`, in f64, to 1e-12 m.
#[test]
fn free_fall_is_implicit_euler_exactly() {
    for solver in [
        GlobalSolver::Direct,
        GlobalSolver::Jacobi,
        GlobalSolver::Chebyshev,
        GlobalSolver::Position,
    ] {
        let mut body = block([4, 4, 4], 0.01, 1e5);
        let start = body.positions().to_vec();
        let p = params(solver, 0.01);
        let mut solver_ = Solver::<f64>::new(p, Some(1)).unwrap();
        let (mut v, mut x) = (0.0, 0.0);
        for _ in 0..10 {
            solver_.step(&mut [BodyMut::from(&mut body)]).unwrap();
            v += p.dt * p.gravity[2];
            x += p.dt * v;
        }
        for (y, y0) in body.positions().iter().zip(&start) {
            assert!(
                (y - y0 - Vector3::new(0.0, 0.0, x)).amax() < 1e-12,
                "{solver:?}: {y:?} from {y0:?}, fall {x}"
            );
        }
        for v_i in body.velocities() {
            assert!((v_i.z - v).abs() < 1e-10, "{solver:?}");
        }
    }
}

/// A block squashed and released from a pin, one step at h = 1/30 s: every global solver
/// converges to the same implicit Euler solution (1e-6 of the spacing), as its residual says,
/// Jacobi and Chebyshev with and without the two-level correction; the one-level sweeps take
/// no fewer iterations than the direct solver's exact linear solves (Chebyshev on the
/// two-level correction may: it accelerates the outer iteration too).
#[test]
fn every_global_solver_reaches_the_same_implicit_euler_step() {
    let run = |solver: GlobalSolver, two_level: bool| {
        let paper = ParticleParams {
            spacing: 0.01,
            density: 1000.0,
            horizon: None,
            material: Elastic::Paper { mu: 2e4, lam: 2e4 },
        };
        let reference = lattice([5, 4, 4], 0.01, Vector3::zeros());
        let mut body = Particles::new(reference, paper).unwrap();
        let squashed = body
            .reference()
            .iter()
            .map(|x| Vector3::new(x.x * 1.05, x.y, x.z * 0.95 + 0.002 * (300.0 * x.x).sin()))
            .collect();
        body.set_positions(squashed).unwrap();
        body.pin(&[0, 1], None).unwrap();
        let mut p = params(solver, 1.0 / 30.0);
        p.max_iters = 20000;
        p.tol = 1e-9;
        p.particle_two_level = two_level;
        let mut s = Solver::<f64>::new(p, Some(1)).unwrap();
        let stats = s.step(&mut [BodyMut::from(&mut body)]).unwrap();
        assert!(
            stats.converged,
            "{solver:?}: {} iterations",
            stats.iterations
        );
        (body.positions().to_vec(), stats.iterations)
    };
    let (reference, direct_iterations) = run(GlobalSolver::Direct, false);
    for (solver, two_level) in [
        (GlobalSolver::Jacobi, false),
        (GlobalSolver::Chebyshev, false),
        (GlobalSolver::Position, false),
        (GlobalSolver::Jacobi, true),
        (GlobalSolver::Chebyshev, true),
    ] {
        let (y, iterations) = run(solver, two_level);
        let worst = y
            .iter()
            .zip(&reference)
            .map(|(a, b)| (a - b).amax())
            .fold(0.0, f64::max);
        assert!(
            worst < 1e-8,
            "{solver:?} (two-level {two_level}) differs by {worst:e} m"
        );
        assert!(
            two_level || iterations >= direct_iterations,
            "{solver:?}: {iterations} < {direct_iterations}"
        );
    }
}

/// A block dropped on a plane comes to rest on it: after 1.5 s its lowest particles keep their
/// margin (half a spacing) above the plane (1e-6 m) and the body is nearly still, with the
/// diagonal global solvers.
#[test]
fn a_block_dropped_on_a_plane_rests_on_it() {
    for solver in [
        GlobalSolver::Jacobi,
        GlobalSolver::Chebyshev,
        GlobalSolver::Position,
    ] {
        let (lowest, fastest) = drop_on_plane(solver);
        assert!(
            (lowest - 0.005).abs() < 1e-6,
            "{solver:?}: lowest particle at {lowest} m"
        );
        assert!(fastest < 1e-3, "{solver:?}: still moving at {fastest} m/s");
    }
}

/// The same drop with the direct solver, which holds the particles touching the plane in its
/// factor (they take Jacobi moves that the plane projects): it rests as the diagonal solvers'
/// drop does, converging in every step, and refactors only when the set of contacts changes.
#[test]
fn a_block_dropped_on_a_plane_rests_on_it_with_the_direct_solver() {
    let (lowest, fastest) = drop_on_plane(GlobalSolver::Direct);
    assert!(
        (lowest - 0.005).abs() < 1e-6,
        "lowest particle at {lowest} m"
    );
    assert!(fastest < 1e-3, "still moving at {fastest} m/s");
}

/// A 4^3 block dropped from 2 cm onto a plane for 1.5 s: its lowest height (m) and fastest
/// speed (m/s) at the end.
fn drop_on_plane(solver: GlobalSolver) -> (f64, f64) {
    let mut body = block([4, 4, 4], 0.01, 1e5);
    let lifted = body
        .positions()
        .iter()
        .map(|x| x + Vector3::new(0.0, 0.0, 0.02))
        .collect();
    body.set_positions(lifted).unwrap();
    let mut p = params(solver, 0.01);
    p.tol = 1e-6;
    let mut s = Solver::<f64>::new(p, Some(1)).unwrap();
    let plane = Shape::plane([0.0; 3], [0.0, 0.0, 1.0]).unwrap();
    s.add_collider(Collider::new(plane, 0.0, [0.0; 3]).unwrap())
        .unwrap();
    for _ in 0..150 {
        s.step(&mut [BodyMut::from(&mut body)]).unwrap();
    }
    let lowest = body
        .positions()
        .iter()
        .map(|p| p.z)
        .fold(f64::MAX, f64::min);
    let fastest = body
        .velocities()
        .iter()
        .map(|v| v.norm())
        .fold(0.0, f64::max);
    (lowest, fastest)
}

/// One and two threads give the same bits, for every global solver, in f32 and f64.
#[test]
fn one_and_two_threads_agree_bit_for_bit() {
    fn check<T: Real>(solver: GlobalSolver) {
        let run = |threads| {
            let mut body = block([9, 8, 8], 0.01, 5e4);
            body.pin(&[0, 1, 2], None).unwrap();
            let mut p = params(solver, 0.01);
            p.max_iters = 30;
            let mut s = Solver::<T>::new(p, Some(threads)).unwrap();
            let plane = Shape::plane([0.0, 0.0, -0.01], [0.1, 0.0, 1.0]).unwrap();
            s.add_collider(Collider::new(plane, 0.3, [0.0; 3]).unwrap())
                .unwrap();
            for _ in 0..5 {
                s.step(&mut [BodyMut::from(&mut body)]).unwrap();
            }
            body.positions().to_vec()
        };
        let (a, b) = (run(1), run(2));
        assert!(a == b, "{} {solver:?}", T::NAME);
    }
    for solver in [
        GlobalSolver::Direct,
        GlobalSolver::Jacobi,
        GlobalSolver::Chebyshev,
        GlobalSolver::Position,
    ] {
        check::<f32>(solver);
        check::<f64>(solver);
    }
}

/// Two free blocks, one dropped onto the other, resting on a tilted frictional plane: the
/// coarse step gathers collider contacts (with their tangential equalities) and pairs between
/// the bodies, its collider gaps in parallel; one and two threads give the same bits.
#[test]
fn free_bodies_on_a_frictional_plane_step_the_same_on_one_and_two_threads() {
    fn check<T: Real>() {
        let run = |threads| {
            let mut lower = block([4, 4, 4], 0.01, 1e5);
            let mut upper = block([4, 4, 4], 0.01, 1e5);
            let lifted = upper
                .positions()
                .iter()
                .map(|p| p + Vector3::new(0.005, 0.005, 0.045));
            upper.set_positions(lifted.collect()).unwrap();
            let mut p = params(GlobalSolver::Chebyshev, 0.01);
            p.max_iters = 40;
            let mut s = Solver::<T>::new(p, Some(threads)).unwrap();
            let plane = Shape::plane([0.0, 0.0, -0.006], [0.3, 0.0, 1.0]).unwrap();
            s.add_collider(Collider::new(plane, 0.8, [0.0; 3]).unwrap())
                .unwrap();
            for _ in 0..12 {
                s.step(&mut [BodyMut::from(&mut lower), BodyMut::from(&mut upper)])
                    .unwrap();
            }
            [lower.positions().to_vec(), upper.positions().to_vec()]
        };
        assert!(run(1) == run(2), "{}", T::NAME);
    }
    check::<f32>();
    check::<f64>();
}

/// A bar twelve spacings across and 36 long, stretched 0.1 % between its pinned end layers
/// and brought to rest (steps of h = 10 s without gravity, where inertia is 1e-8 of the
/// stiffness, 300 Chebyshev iterations each): Young's modulus (the end reaction over the cross-section, against the axial
/// strain of the middle third) and Poisson ratio (the middle section's lateral strain) match
/// `Elastic::Young` within 15 %, for nu = 0.25 and 0.4: the free surfaces' missing bonds are
/// made up for.
#[test]
fn a_bar_has_the_asked_young_modulus_and_poisson_ratio() {
    for nu in [0.25, 0.4] {
        let (n, len, s, e) = (12usize, 36usize, 0.01, 1e5);
        let params = ParticleParams {
            spacing: s,
            density: 1000.0,
            horizon: None,
            material: Elastic::Young { e, nu },
        };
        let mut body = Particles::new(lattice([n, n, len], s, Vector3::zeros()), params).unwrap();
        let strain = 1e-3;
        let stretched: Vec<_> = body
            .reference()
            .iter()
            .map(|x| Vector3::new(x.x, x.y, x.z * (1.0 + strain)))
            .collect();
        body.set_positions(stretched).unwrap();
        let layer = |k: usize| (0..n * n).map(move |i| (k * n * n + i) as i64);
        let ends: Vec<i64> = layer(0).chain(layer(len - 1)).collect();
        body.pin(&ends, None).unwrap();
        let p = SolverParams {
            dt: 10.0,
            gravity: [0.0; 3],
            global_solver: GlobalSolver::Chebyshev,
            max_iters: 300,
            tol: 0.0,
            ..SolverParams::default()
        };
        let mut solver = Solver::<f64>::new(p, None).unwrap();
        for _ in 0..4 {
            solver.step(&mut [BodyMut::from(&mut body)]).unwrap();
        }
        let y = body.positions();
        let forces = body.internal_forces().unwrap();
        let reaction: f64 = layer(len - 1).map(|i| forces[i as usize].z).sum();
        let stress = -reaction / ((n as f64 * s) * (n as f64 * s));
        let mean_z = |k: usize| layer(k).map(|i| y[i as usize].z).sum::<f64>() / (n * n) as f64;
        let (k1, k2) = (len / 3, 2 * len / 3);
        let axial = (mean_z(k2) - mean_z(k1)) / ((k2 - k1) as f64 * s) - 1.0;
        let mid = len / 2;
        let side = |i: usize| (0..n).map(|j| y[mid * n * n + j * n + i].x).sum::<f64>() / n as f64;
        let lateral = (side(n - 1) - side(0)) / ((n - 1) as f64 * s) - 1.0;
        let (young, poisson) = (stress / axial, -lateral / axial);
        eprintln!("nu {nu}: measured E {young:e} Pa, nu {poisson}");
        assert!(
            (young / e - 1.0).abs() < 0.15,
            "nu {nu}: E {young:e} Pa for {e:e}"
        );
        assert!(
            (poisson - nu).abs() < 0.15 * nu,
            "nu {nu}: measured {poisson}"
        );
    }
}

/// A step that fails (forced by a `max_speed` of 1 nm/s) hands the next one the state it
/// started from, the grains' friction multipliers, even when the next step builds the
/// particles' working set anew for the same bodies (left stale, as a plastic rebuild that
/// fails at a step's end leaves it): the retried step is bit for bit an undisturbed twin's,
/// in f32 and f64. Before, any rebuild dropped the failed step's start, and with it the
/// multipliers.
#[test]
fn a_failed_steps_start_survives_a_working_set_built_anew_for_the_same_bodies() {
    fn check<T: Real>() {
        let sand = || {
            let mut body = block([3, 3, 3], 0.01, 1e5);
            let material = Granular {
                contact_friction: 0.5,
                ..Granular::new(30.0, 0.0)
            };
            body.set_granular(material).unwrap();
            body
        };
        let params = SolverParams {
            dt: 2e-3,
            max_iters: 10,
            tol: 0.0,
            ..SolverParams::default()
        };
        let solver = || {
            let mut s = Solver::<T>::new(params, Some(1)).unwrap();
            let plane = Shape::plane([0.0, 0.0, -0.005], [0.0, 0.0, 1.0]).unwrap();
            s.add_collider(Collider::new(plane, 0.3, [0.0; 3]).unwrap())
                .unwrap();
            s
        };
        let (mut body, mut twin_body) = (sand(), sand());
        let (mut s, mut twin) = (solver(), solver());
        for _ in 0..4 {
            s.step(&mut [BodyMut::from(&mut body)]).unwrap();
            twin.step(&mut [BodyMut::from(&mut twin_body)]).unwrap();
        }
        let start = s.saved_state(&[]);
        assert!(!start.grain_contacts.is_empty(), "{}", T::NAME);
        s.set_params(SolverParams {
            max_speed: 1e-9,
            ..params
        })
        .unwrap();
        assert!(s.step(&mut [BodyMut::from(&mut body)]).is_err());
        assert_eq!(s.saved_state(&[]), start, "{}", T::NAME);
        s.set_params(params).unwrap();
        s.particle_system().unwrap().make_stale();
        s.step(&mut [BodyMut::from(&mut body)]).unwrap();
        twin.step(&mut [BodyMut::from(&mut twin_body)]).unwrap();
        assert!(body.positions() == twin_body.positions(), "{}", T::NAME);
        assert!(body.velocities() == twin_body.velocities(), "{}", T::NAME);
        assert_eq!(s.saved_state(&[]), twin.saved_state(&[]), "{}", T::NAME);
    }
    check::<f32>();
    check::<f64>();
}
