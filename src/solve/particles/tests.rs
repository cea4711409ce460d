//! Tests of the particle family in the solver: free fall, the global solvers against each
//! other, colliders, thread-count invariance, membranes and particles in one solver.

use nalgebra::Vector3;

use crate::collider::{Collider, Shape};
use crate::particles::{Elastic, ParticleParams, Particles};
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
/// converges to the same implicit Euler solution (1e-6 of the spacing), as its residual says.
#[test]
fn every_global_solver_reaches_the_same_implicit_euler_step() {
    let run = |solver: GlobalSolver| {
        let mut body = block([5, 4, 4], 0.01, 2e4);
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
        let mut s = Solver::<f64>::new(p, Some(1)).unwrap();
        let stats = s.step(&mut [BodyMut::from(&mut body)]).unwrap();
        assert!(stats.converged, "{solver:?}: {} iterations", stats.iterations);
        (body.positions().to_vec(), stats.iterations)
    };
    let (reference, direct_iterations) = run(GlobalSolver::Direct);
    for solver in [GlobalSolver::Jacobi, GlobalSolver::Chebyshev, GlobalSolver::Position] {
        let (y, iterations) = run(solver);
        let worst = y
            .iter()
            .zip(&reference)
            .map(|(a, b)| (a - b).amax())
            .fold(0.0, f64::max);
        assert!(worst < 1e-8, "{solver:?} differs by {worst:e} m");
        assert!(iterations >= direct_iterations, "{solver:?}");
    }
}

/// A block dropped on a plane comes to rest on it: after 1.5 s its lowest particles keep their
/// margin (half a spacing) above the plane (1e-6 m) and the body is nearly still.
#[test]
fn a_block_dropped_on_a_plane_rests_on_it() {
    let mut body = block([4, 4, 4], 0.01, 1e5);
    let lifted = body.positions().iter().map(|x| x + Vector3::new(0.0, 0.0, 0.02)).collect();
    body.set_positions(lifted).unwrap();
    let mut p = params(GlobalSolver::Direct, 0.01);
    p.tol = 1e-6;
    let mut s = Solver::<f64>::new(p, Some(1)).unwrap();
    let plane = Shape::plane([0.0; 3], [0.0, 0.0, 1.0]).unwrap();
    s.add_collider(Collider::new(plane, 0.0, [0.0; 3]).unwrap()).unwrap();
    for _ in 0..150 {
        s.step(&mut [BodyMut::from(&mut body)]).unwrap();
    }
    let lowest = body.positions().iter().map(|p| p.z).fold(f64::MAX, f64::min);
    assert!((lowest - 0.005).abs() < 1e-6, "lowest particle at {lowest} m");
    let fastest = body.velocities().iter().map(|v| v.norm()).fold(0.0, f64::max);
    assert!(fastest < 1e-3, "still moving at {fastest} m/s");
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
            s.add_collider(Collider::new(plane, 0.3, [0.0; 3]).unwrap()).unwrap();
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
