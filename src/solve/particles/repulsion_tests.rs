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

/// The friction moves ([`super::grain_friction`]: the repulsion's moves with `mu_c` 0.5 less
/// those without) of a grain of a granular body that slips by 1e-3 spacings across four
/// pinned partners pressing on it from the sides (overlap 0.1 spacings, so every contact
/// sticks): one local step takes away its slip and no more (to 1e-5 of it, the contacts'
/// tangent planes tilting by the slip over the spacing), where the moves summed in full would
/// carry it three slips the other way. With the partners free (each touching only that
/// grain), the moves of all five sum to zero (to 1e-12 of the slip: equal and opposite).
/// Open (issue 39): the summed moves carry the held grain three slips back, so the first
/// check fails; this test fails once a fix makes it pass (then drop `should_panic`).
#[test]
#[should_panic(expected = "overshoot: the held grain")]
fn a_grain_sticking_to_four_partners_does_not_overshoot() {
    use crate::solve::clearance::Clearance;
    use crate::solve::points::Points;

    use super::repulsion::Repulsion;

    let d = 0.9 * S;
    let sites = vec![
        Vector3::zeros(),
        Vector3::new(d, 0.0, 0.0),
        Vector3::new(-d, 0.0, 0.0),
        Vector3::new(0.0, d, 0.0),
        Vector3::new(0.0, -d, 0.0),
    ];
    let slip = Vector3::new(0.0, 0.0, 1e-3 * S);
    let moves = |pinned: bool, mu: f64| -> Vec<Vector3<f64>> {
        let zeros = vec![Vector3::zeros(); 5];
        let points = Points::<f64> {
            ids: vec![0],
            ranges: std::iter::once(0..5).collect(),
            mass: vec![1.0; 5],
            margin: vec![0.5 * S; 5],
            y_start: sites.clone(),
            velocity: zeros.clone(),
            y_star: sites.clone(),
            y: sites.clone(),
            y_next: zeros,
            y_prev: Vec::new(),
            pinned: vec![false, pinned, pinned, pinned, pinned],
            collides: vec![true; 5],
            energy_chunks: Vec::new(),
            clearance: Clearance::default(),
        };
        let mut repulsion = Repulsion::of(&points, vec![true], &[false; 5])
            .unwrap()
            .with_friction(&[mu]);
        repulsion.start_step(&points, 1e-3, [0.0; 3]).unwrap();
        let mut delta = vec![Vector3::zeros(); 5];
        delta[0] = slip;
        repulsion.correct(&points, &delta, 1.0, |_| 1.0);
        (0..5).map(|i| repulsion.of_particle(i)).collect()
    };
    let friction = |pinned: bool| -> Vec<Vector3<f64>> {
        let (with, without) = (moves(pinned, 0.5), moves(pinned, 0.0));
        with.iter().zip(&without).map(|(a, b)| a - b).collect()
    };
    let held = friction(true);
    let left = slip + held[0];
    assert!(
        left.norm() < 1e-5 * slip.norm(),
        "overshoot: the held grain keeps {left:?} of its slip {slip:?}"
    );
    let free = friction(false);
    let total: Vector3<f64> = free.iter().sum();
    assert!(total.norm() < 1e-12 * slip.norm(), "net move {total:?}");
    let left = slip + free[0];
    assert!(left.z > 0.0 && left.z < slip.z, "{left:?} left of {slip:?}");
}
