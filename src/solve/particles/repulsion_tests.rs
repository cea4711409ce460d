//! Tests of the repulsion between particle bodies ([`super::repulsion`]): no interpenetration,
//! momentum in a head-on collision, stacking under gravity, thread count.

use nalgebra::Vector3;

use crate::collider::{Collider, Shape};
use crate::particles::Particles;
use crate::real::Real;
use crate::solve::{BodyMut, GlobalSolver, Solver, SolverParams};

use super::tests::block;

const S: f64 = 0.01;

/// A 4^3 block of spacing `S` moved by `offset` (m) at `velocity` (m/s).
fn moving_block(offset: Vector3<f64>, velocity: Vector3<f64>) -> Particles {
    let mut body = block([4, 4, 4], S, 1e5);
    let x = body.positions().iter().map(|p| p + offset).collect();
    body.set_positions(x).unwrap();
    body.set_velocities(vec![velocity; body.num_particles()])
        .unwrap();
    body
}

/// The smallest distance between a particle of `a` and one of `b` (m).
fn closest(a: &Particles, b: &Particles) -> f64 {
    a.positions()
        .iter()
        .flat_map(|p| b.positions().iter().map(move |q| (p - q).norm()))
        .fold(f64::MAX, f64::min)
}

fn momentum(body: &Particles) -> Vector3<f64> {
    body.velocities().iter().sum::<Vector3<f64>>() * body.particle_mass()
}

fn zero_gravity(solver: GlobalSolver) -> SolverParams {
    SolverParams {
        dt: 0.005,
        gravity: [0.0; 3],
        global_solver: solver,
        max_iters: 300,
        tol: 1e-7,
        ..SolverParams::default()
    }
}

/// Two blocks meet head-on at 1 m/s each in zero gravity (with an offset across, so that
/// particles meet off-centre): no two particles of different bodies come closer than 0.9
/// spacings at the end of any step (the constraint's distance is one spacing), the total
/// momentum stays zero within 1e-3 of one block's, and afterwards they no longer approach.
#[test]
fn two_blocks_collide_head_on_without_interpenetration_and_keep_their_momentum() {
    for solver in [GlobalSolver::Chebyshev, GlobalSolver::Jacobi] {
        let v = 1.0;
        let mut a = moving_block(Vector3::zeros(), Vector3::new(v, 0.0, 0.0));
        let mut b = moving_block(
            Vector3::new(4.5 * S, 0.3 * S, 0.0),
            Vector3::new(-v, 0.0, 0.0),
        );
        let one = momentum(&a).norm();
        let mut s = Solver::<f64>::new(zero_gravity(solver), Some(1)).unwrap();
        let mut nearest = f64::MAX;
        for _ in 0..40 {
            s.step(&mut [BodyMut::from(&mut a), BodyMut::from(&mut b)])
                .unwrap();
            nearest = nearest.min(closest(&a, &b));
        }
        assert!(nearest >= 0.9 * S, "{solver:?}: {nearest} m");
        let total = momentum(&a) + momentum(&b);
        assert!(total.norm() < 1e-3 * one, "{solver:?}: {total:?} of {one}");
        let approach = (momentum(&a) - momentum(&b)).x / (2.0 * one);
        assert!(
            approach <= 1e-3,
            "{solver:?}: still approaching ({approach})"
        );
    }
}

/// A block dropped on a block resting on the ground stacks on it: no pair comes closer than
/// 0.9 spacings at the end of any step, and the vertical gap between the upper block's lowest
/// particles and the lower block's highest settles within 5 % of where pairs one spacing
/// apart (the constraint's distance) put it.
///
/// The upper block is offset by half a spacing along x and y, so that each of its lowest
/// particles sits in a hollow between four of the lower block's: a stable rest. (Offset along
/// x only, each would sit on a ridge between two, a saddle: there a sideways offset `e` grows
/// some 1.3 times per step, from round-off (1e-16 m) as from 1e-9 m, until the block slides
/// half a spacing into the hollows, with this solver as with the one before it.)
#[test]
fn a_block_dropped_on_another_stacks_on_it() {
    let mut lower = moving_block(Vector3::new(0.0, 0.0, 0.5 * S), Vector3::zeros());
    let mut upper = moving_block(Vector3::new(0.5 * S, 0.5 * S, 5.0 * S), Vector3::zeros());
    let p = SolverParams {
        dt: 0.01,
        global_solver: GlobalSolver::Chebyshev,
        max_iters: 300,
        tol: 1e-7,
        ..SolverParams::default()
    };
    let mut s = Solver::<f64>::new(p, Some(1)).unwrap();
    let plane = Shape::plane([0.0; 3], [0.0, 0.0, 1.0]).unwrap();
    s.add_collider(Collider::new(plane, 0.0, [0.0; 3]).unwrap())
        .unwrap();
    for _ in 0..120 {
        s.step(&mut [BodyMut::from(&mut lower), BodyMut::from(&mut upper)])
            .unwrap();
        assert!(closest(&lower, &upper) >= 0.9 * S);
    }
    let top = lower
        .positions()
        .iter()
        .map(|p| p.z)
        .fold(f64::MIN, f64::max);
    let bottom = upper
        .positions()
        .iter()
        .map(|p| p.z)
        .fold(f64::MAX, f64::min);
    assert!(
        // Offset by half a spacing along x and y, each upper particle sits among four lower
        // ones: pairs one spacing apart leave a vertical gap of sqrt(1 - 1/4 - 1/4) spacings.
        ((bottom - top) / (0.5f64.sqrt() * S) - 1.0).abs() < 0.05,
        "gap {} m",
        bottom - top
    );
}

#[test]
fn colliding_bodies_step_the_same_on_one_and_two_threads() {
    fn check<T: Real>() {
        let run = |threads| {
            let mut a = moving_block(Vector3::zeros(), Vector3::new(1.0, 0.0, 0.0));
            let mut b = moving_block(Vector3::new(4.5 * S, 0.3 * S, 0.1 * S), Vector3::zeros());
            let mut p = zero_gravity(GlobalSolver::Chebyshev);
            p.max_iters = 30;
            let mut s = Solver::<T>::new(p, Some(threads)).unwrap();
            for _ in 0..10 {
                s.step(&mut [BodyMut::from(&mut a), BodyMut::from(&mut b)])
                    .unwrap();
            }
            [a.positions().to_vec(), b.positions().to_vec()]
        };
        assert!(run(1) == run(2), "{}", T::NAME);
    }
    check::<f32>();
    check::<f64>();
}
