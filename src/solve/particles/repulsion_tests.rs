//! Tests of the repulsion between particle bodies ([`super::repulsion`]): no interpenetration,
//! momentum in a head-on collision, stacking under gravity, thread count.

use nalgebra::Vector3;

use crate::collider::{Collider, Shape};
use crate::particles::Particles;
use crate::real::Real;
use crate::solve::{BodyMut, GlobalSolver, Solver, SolverParams};

use super::repulsion::Repulsion;
use super::tests::block;
use crate::solve::clearance::Clearance;
use crate::solve::points::Points;

pub(super) const S: f64 = 0.01;

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
/// sticks): one local step takes away its slip and no more, its whole move (normal and
/// friction) leaving it where it started to 1e-5 of the slip (the contacts' tangent planes
/// tilting by the slip over the spacing; the friction also takes away the 0.44 slips of
/// sideways move that the tilted normal moves would add), where the moves of every contact
/// summed in full would carry it three slips the other way (issue 39). With the partners free
/// (each touching only that grain), the moves of all five sum to zero (to 1e-12 of the slip:
/// equal and opposite), and the grain keeps part of its slip (its partners take the rest).
#[test]
fn a_grain_sticking_to_four_partners_does_not_overshoot() {
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
        let points = grains(&sites, &[1.0; 5], &[false, pinned, pinned, pinned, pinned]);
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
    let left = slip + moves(true, 0.5)[0];
    assert!(
        left.norm() < 1e-5 * slip.norm(),
        "overshoot: the held grain keeps {left:?} of its slip {slip:?}"
    );
    let free = friction(false);
    let total: Vector3<f64> = free.iter().sum();
    assert!(total.norm() < 1e-12 * slip.norm(), "net move {total:?}");
    let left = slip + moves(false, 0.5)[0];
    assert!(left.z > 0.0 && left.z < slip.z, "{left:?} left of {slip:?}");
}

/// Grains of one granular body at rest at `sites` (m) with masses `mass` (kg), those
/// marked in `pinned` pinned: balls of half a spacing.
pub(super) fn grains(sites: &[Vector3<f64>], mass: &[f64], pinned: &[bool]) -> Points<f64> {
    let zeros = vec![Vector3::zeros(); sites.len()];
    Points {
        ids: vec![0],
        ranges: std::iter::once(0..sites.len()).collect(),
        origin: Vector3::zeros(),
        mass: mass.to_vec(),
        margin: vec![0.5 * S; sites.len()],
        y_start: sites.to_vec(),
        velocity: zeros.clone(),
        y_star: sites.to_vec(),
        y: sites.to_vec(),
        y_next: zeros,
        y_prev: Vec::new(),
        pinned: pinned.to_vec(),
        collides: vec![true; sites.len()],
        energy_chunks: Vec::new(),
        clearance: Clearance::default(),
    }
}

/// Newton's third law at the frictional contacts ([`super::grain_friction`], `mu_c` 0.5): a
/// cluster of six free grains of masses 1, 2, 1, 3, 1 and 0.5 kg touching 4, 2, 1, 1, 1 and 1
/// others (a grain with four partners, one of which touches a sixth), each proposed a
/// different move of about 1e-3 spacings (the sixth 0.1 spacings, so that its contact slides
/// and the others stick). Over ten iterations of the friction's multipliers, every
/// iteration's moves carry no net momentum (`sum_i m_i c_i` below 1e-12 of
/// `sum_i m_i |c_i|`), however different the two grains' contact counts (relaxed by each
/// grain's own count, `1 / n_i`, the test fails).
#[test]
fn the_friction_moves_keep_momentum_between_grains_of_different_contact_counts() {
    let d = 0.9 * S;
    let sites = [
        Vector3::zeros(),
        Vector3::new(d, 0.0, 0.0),
        Vector3::new(-d, 0.0, 0.0),
        Vector3::new(0.0, d, 0.0),
        Vector3::new(0.0, -d, 0.0),
        Vector3::new(2.0 * d - 0.05 * S, 0.0, 0.0),
    ];
    let mass = [1.0, 2.0, 1.0, 3.0, 1.0, 0.5];
    let points = grains(&sites, &mass, &[false; 6]);
    let mut repulsion = Repulsion::of(&points, vec![true], &[false; 6])
        .unwrap()
        .with_friction(&[0.5]);
    repulsion.start_step(&points, 1e-3, [0.0; 3]).unwrap();
    let delta: Vec<Vector3<f64>> = (0..6)
        .map(|i| {
            let k = i as f64;
            let size = if i == 5 { 0.1 * S } else { 1e-3 * S };
            Vector3::new((0.3 * k).sin(), (0.7 * k).cos(), 1.0 + 0.5 * k) * size
        })
        .collect();
    for iteration in 0..10 {
        repulsion.correct(&points, &delta, 1.0, |_| 1.0);
        repulsion.accept();
        let moves: Vec<Vector3<f64>> = (0..6).map(|i| repulsion.of_particle(i)).collect();
        let net: Vector3<f64> = moves.iter().zip(&mass).map(|(c, m)| c * *m).sum();
        let scale: f64 = moves.iter().zip(&mass).map(|(c, m)| c.norm() * m).sum();
        assert!(
            scale > 0.0 && net.norm() < 1e-12 * scale,
            "{iteration}: {net:?} of {scale}"
        );
    }
}

/// The repulsion of the granular bodies of `points`, with the contact friction coefficients
/// `mu_c` (per body), after one accepted iteration of a step of 1 ms without gravity in which
/// nothing is proposed to move (the contacts at the sites).
fn at_rest(points: &Points<f64>, mu_c: &[f64]) -> Repulsion<f64> {
    let n = points.mass.len();
    let mut repulsion = Repulsion::of(points, vec![true; mu_c.len()], &vec![false; n])
        .unwrap()
        .with_friction(mu_c);
    repulsion.start_step(points, 1e-3, [0.0; 3]).unwrap();
    repulsion.correct(points, &vec![Vector3::zeros(); n], 1.0, |_| 1.0);
    repulsion.accept();
    repulsion
}

/// The hold of a yielded grain by its contacts ([`Repulsion::sticks`], `mu_c` 0.5): a grain
/// pressed 0.1 spacings into a pinned one below it (overlap `g` 1e-3 m). Its contact takes
/// back a sideways move up to `mu_c min(g, |y* - y^t|)`: 1e-4 m with an inertial move of
/// 1e-3 m (limit 5e-4 m) but not with one of 1e-4 m (limit 5e-5 m), nor 6e-4 m sideways
/// with an inertial move of 2e-3 m (the overlap's limit, 5e-4 m); a move along the normal
/// has no sideways part. A grain touching nothing is not held.
#[test]
fn a_contact_holds_a_grain_whose_sideways_move_lies_within_coulombs_limit() {
    let sites = [
        Vector3::new(0.0, 0.0, 0.9 * S),
        Vector3::zeros(),
        Vector3::new(5.0 * S, 0.0, 0.0),
    ];
    let points = grains(&sites, &[1.0; 3], &[false, true, false]);
    let repulsion = at_rest(&points, &[0.5]);
    let sticks = |i: usize, d: Vector3<f64>, inertial: f64| {
        repulsion.sticks(&points.margin, i, &d, inertial)
    };
    let sideways = |d: f64| Vector3::new(d, 0.0, 0.0);
    assert!(sticks(0, sideways(1e-4), 1e-3));
    assert!(!sticks(0, sideways(1e-4), 1e-4));
    assert!(!sticks(0, sideways(6e-4), 2e-3));
    assert!(sticks(0, Vector3::new(0.0, 0.0, 5e-3), 1e-4));
    assert!(!sticks(2, Vector3::zeros(), 1e-3));
}

/// A grain is held only when every frictional contact can take back its move
/// ([`Repulsion::sticks`], `mu_c` 0.5, inertial move 1e-3 m): grain 0 pressed 0.1 spacings
/// into pinned grain 1 below it (overlap 1e-3 m, limit 5e-4 m) and 0.01 spacings into pinned
/// grain 2 beside it along x (overlap 1e-4 m, limit 5e-5 m). A move of 1e-4 m along y, across
/// both normals, passes the contact below and fails the one beside: not held. The same move
/// along x lies along the side contact's normal (no sideways part there) and within the limit
/// below: held. Without grain 2 the move along y is held, so the side contact alone decides.
#[test]
fn a_grain_is_held_only_when_all_its_frictional_contacts_hold() {
    let sites = [
        Vector3::new(0.0, 0.0, 0.9 * S),
        Vector3::zeros(),
        Vector3::new(0.99 * S, 0.0, 0.9 * S),
    ];
    let across = Vector3::new(0.0, 1e-4, 0.0);
    let along = Vector3::new(1e-4, 0.0, 0.0);
    for (beside, held_across) in [(true, false), (false, true)] {
        let mut sites = sites;
        if !beside {
            sites[2].x = 5.0 * S;
        }
        let points = grains(&sites, &[1.0; 3], &[false, true, true]);
        let repulsion = at_rest(&points, &[0.5]);
        assert_eq!(
            repulsion.sticks(&points.margin, 0, &across, 1e-3),
            held_across,
            "beside: {beside}"
        );
        assert!(repulsion.sticks(&points.margin, 0, &along, 1e-3));
    }
}

/// A frictionless partner neither holds nor frees a grain ([`Repulsion::sticks`]): the
/// contact's coefficient is the smaller of the two particles' (`mu_c` 0.5 for body 0, 0 for
/// body 1), so a pair with a frictionless particle has no friction and is skipped. Grain 0
/// as in the test above, its side partner (3) now of the frictionless body 1: the move of
/// 1e-4 m along y, beyond the side contact's limit had it friction, is held by the contact
/// below alone. Grain 2 (body 0) touches only the frictionless grain 3: it touches no
/// frictional partner and is not held, whatever its move.
#[test]
fn a_frictionless_partner_is_skipped_by_the_hold() {
    let sites = [
        Vector3::new(0.0, 0.0, 0.9 * S),
        Vector3::zeros(),
        Vector3::new(1.98 * S, 0.0, 0.9 * S),
        Vector3::new(0.99 * S, 0.0, 0.9 * S),
    ];
    let mut points = grains(&sites, &[1.0; 4], &[false, true, false, true]);
    points.ids = vec![0, 1];
    points.ranges = vec![0..3, 3..4];
    let repulsion = at_rest(&points, &[0.5, 0.0]);
    let across = Vector3::new(0.0, 1e-4, 0.0);
    assert!(repulsion.sticks(&points.margin, 0, &across, 1e-3));
    assert!(!repulsion.sticks(&points.margin, 2, &Vector3::zeros(), 1e-3));
}
