//! Tests of the grains' rolling ([`super::grain_rolling`]): a grain on pinned grains rolls off
//! where the friction without turns holds it, the torque stays within its bound, a pair that
//! rolls freely is left no friction (no overshoot), the moves keep momentum, and a rolling
//! sand steps the same on one and two threads.

use nalgebra::Vector3;

use crate::collider::{Collider, Shape};
use crate::particles::Granular;
use crate::real::Real;
use crate::solve::points::Points;
use crate::solve::{BodyMut, Solver, SolverParams};

use super::repulsion::Repulsion;
use super::repulsion_tests::{grains, S};
use super::tests::block;

/// The moves (m) of the repulsion with contact friction `mu_c` and rolling resistance `mu_r`
/// (one granular body) after `iterations` accepted iterations of one step of 1 ms without
/// gravity, for the proposed moves `delta` (m) from `points` at rest.
fn moves(
    points: &Points<f64>,
    delta: &[Vector3<f64>],
    mu_c: f64,
    mu_r: Option<f64>,
    iterations: usize,
) -> Vec<Vector3<f64>> {
    let n = points.mass.len();
    let mut repulsion = Repulsion::of(points, vec![true], &vec![false; n])
        .unwrap()
        .with_friction(&[mu_c])
        .with_rolling(&[mu_r]);
    repulsion.start_step(points, 1e-3, [0.0; 3]).unwrap();
    for _ in 0..iterations {
        repulsion.correct(points, delta, 1.0, |_| 1.0);
        repulsion.accept();
    }
    (0..n).map(|i| repulsion.of_particle(i)).collect()
}

/// A grain on a tilted plane of pinned grains: a 3 x 3 patch (spacing `S`) tilted by `tilt`
/// degrees, with a free grain resting on its middle one (1e-3 spacings deep), proposed to
/// move by gravity's kick over a step of 10 ms (`h^2 g`, 0.98 mm, along the tilted vertical),
/// which presses it into its one contact and pulls it along the contact's tangent plane by
/// `tan(tilt)` of the push. After 30 iterations, in the tangent plane at the proposed
/// positions (`n` from the middle grain to the free one): the kick's tangential part and the
/// grain's tangential move (m), its friction move (m: the move with `mu_c` less the move
/// without friction) and its normal move (m, the move without friction).
struct OnPatch {
    kick: Vector3<f64>,
    moved: Vector3<f64>,
    friction: Vector3<f64>,
    normal: Vector3<f64>,
}

fn on_tilted_patch(tilt: f64, mu_c: f64, mu_r: Option<f64>) -> OnPatch {
    let b = tilt.to_radians();
    let up = Vector3::new(b.sin(), 0.0, b.cos());
    let mut sites: Vec<Vector3<f64>> = (-1..=1)
        .flat_map(|x| (-1..=1).map(move |y| (f64::from(x), f64::from(y))))
        .map(|(x, y)| Vector3::new(x * S * b.cos(), y * S, -x * S * b.sin()))
        .collect();
    sites.push(up * (0.999 * S));
    let pinned: Vec<bool> = (0..10).map(|i| i < 9).collect();
    let points = grains(&sites, &[1.0; 10], &pinned);
    let kick = Vector3::new(0.0, 0.0, -9.81 * 1e-4);
    let mut delta = vec![Vector3::zeros(); 10];
    delta[9] = kick;
    let n = (sites[9] + kick - sites[4]).normalize();
    let tangential = |v: Vector3<f64>| v - n * n.dot(&v);
    let with = moves(&points, &delta, mu_c, mu_r, 30)[9];
    let without = moves(&points, &delta, 0.0, None, 30)[9];
    OnPatch {
        kick: tangential(kick),
        moved: tangential(kick + with),
        friction: with - without,
        normal: without,
    }
}

/// A grain resting on a tilted plane of pinned grains (`on_tilted_patch`, tilt 20 degrees,
/// `mu_c` 1: `tan(20)` = 0.36 of its push pulls it along, within Coulomb's limit): without
/// turns the friction holds it (its tangential move under 1e-9 of the kick's tangential part,
/// 0.34 mm), while rolling freely (`mu_r` 0) its single contact can put no torque on it, so
/// the friction holds nothing (friction move under 1e-9 of it) and the grain moves along by
/// the kick's whole tangential part, as without friction: it rolls off.
#[test]
fn a_grain_on_a_tilted_plane_of_pinned_grains_rolls_off_where_friction_without_turns_holds_it() {
    let held = on_tilted_patch(20.0, 1.0, None);
    let along = held.kick.norm();
    assert!(along > 3e-4, "{along}");
    assert!(
        held.moved.norm() < 1e-9 * along,
        "held grain moved {:?}",
        held.moved
    );
    let rolled = on_tilted_patch(20.0, 1.0, Some(0.0));
    assert!(
        rolled.friction.norm() < 1e-9 * along,
        "friction move {:?}",
        rolled.friction
    );
    assert!(
        (rolled.moved - rolled.kick).norm() < 1e-9 * along,
        "moved {:?}",
        rolled.moved
    );
}

/// The torque bound (`mu_r` 0.1, `mu_c` 1, the grain of `on_tilted_patch` on one contact, whose
/// friction move `F` puts the torque `R |F|` on it against the limit `mu_r R g`, `g` the
/// normal move): at 3 degrees of tilt (`tan(3)` = 0.052 of the push pulls it along, within
/// 0.1) the contact holds it (tangential move under 1e-9 of the kick's tangential part) with
/// `|F|` below `mu_r g`; at 10 degrees (`tan(10)` = 0.18) it rolls: `|F|` at `mu_r g` to 1e-9
/// (the torque on its bound), and its tangential move is the kick's less `|F|`.
#[test]
fn a_grains_friction_torque_stays_within_its_rolling_resistance() {
    let mu_r = 0.1;
    let held = on_tilted_patch(3.0, 1.0, Some(mu_r));
    let along = held.kick.norm();
    assert!(
        held.moved.norm() < 1e-9 * along,
        "moved {:?} at 3 degrees",
        held.moved
    );
    let limit = mu_r * held.normal.norm();
    assert!(
        held.friction.norm() < limit,
        "{:?} against {limit}",
        held.friction
    );
    let rolled = on_tilted_patch(10.0, 1.0, Some(mu_r));
    let (along, limit) = (rolled.kick.norm(), mu_r * rolled.normal.norm());
    let f = rolled.friction.norm();
    assert!(
        (f - limit).abs() < 1e-9 * limit,
        "friction {f} m against the limit {limit} m"
    );
    assert!(
        (rolled.moved.norm() - (along - f)).abs() < 1e-9 * along,
        "moved {:?} of {along} less {f}",
        rolled.moved
    );
}

/// Two free grains of 1 and 3 kg pressed 0.1 spacings together, proposed opposite sideways
/// moves (1e-3 spacings, inside Coulomb's limit): the two turn alike, and the turn's
/// relaxation counts the partner's turn, so rolling freely (`mu_r` 0) the friction, which
/// without turns keeps the pair from slipping (their moves' difference in the contact's
/// tangent plane under 1e-9 of the proposed slip), is gone after 40 iterations (friction moves under 1e-9 of the slip);
/// relaxed by a grain's own turn alone, the torque would flip sign at every iteration. Every
/// iteration's moves, with `mu_r` 0 and 0.05, carry no net momentum (below 1e-12 of
/// `sum_i m_i |c_i|`).
#[test]
fn a_rolling_pair_keeps_momentum_and_rolls_freely_without_resistance() {
    let sites = [Vector3::zeros(), Vector3::new(0.9 * S, 0.0, 0.0)];
    let mass = [1.0, 3.0];
    let points = grains(&sites, &mass, &[false, false]);
    let slip = Vector3::new(0.0, 0.0, 1e-3 * S);
    let delta = [slip * 0.75, -slip * 0.25];
    let n = ((sites[0] + delta[0]) - (sites[1] + delta[1])).normalize();
    let sideways = |c: &[Vector3<f64>]| {
        let v = (delta[0] + c[0]) - (delta[1] + c[1]);
        (v - n * n.dot(&v)).norm()
    };
    let stuck = moves(&points, &delta, 0.5, None, 40);
    assert!(
        sideways(&stuck) < 1e-9 * slip.z,
        "slip {}",
        sideways(&stuck)
    );
    let (free, frictionless) = (
        moves(&points, &delta, 0.5, Some(0.0), 40),
        moves(&points, &delta, 0.0, None, 40),
    );
    for (a, b) in free.iter().zip(&frictionless) {
        assert!((a - b).norm() < 1e-9 * slip.z, "friction move {:?}", a - b);
    }
    for mu_r in [0.0, 0.05] {
        for iterations in 1..=10 {
            let c = moves(&points, &delta, 0.5, Some(mu_r), iterations);
            let net = c[0] * mass[0] + c[1] * mass[1];
            let scale = c[0].norm() * mass[0] + c[1].norm() * mass[1];
            assert!(
                scale > 0.0 && net.norm() < 1e-12 * scale,
                "mu_r {mu_r}, {iterations}: {net:?} of {scale}"
            );
        }
    }
}

/// A 4^3 block of sand with contact friction 0.5 and rolling resistance 0.1 on a plane, under
/// gravity tilted to pull it sideways (3 m/s^2 along x), steps bit for bit the same on one and
/// two threads, in f32 and f64, over 15 steps of 2 ms.
#[test]
fn rolling_sand_steps_the_same_on_one_and_two_threads() {
    fn check<T: Real>() {
        let run = |threads, rolling_resistance| {
            let mut body = block([4, 4, 4], 0.01, 1e5);
            let material = Granular {
                contact_friction: 0.5,
                rolling_resistance,
                ..Granular::new(30.0, 0.0)
            };
            body.set_granular(material).unwrap();
            let params = SolverParams {
                dt: 2e-3,
                max_iters: 10,
                tol: 0.0,
                gravity: [3.0, 0.0, -9.81],
                ..SolverParams::default()
            };
            let mut s = Solver::<T>::new(params, Some(threads)).unwrap();
            let plane = Shape::plane([0.0, 0.0, -0.005], [0.0, 0.0, 1.0]).unwrap();
            s.add_collider(Collider::new(plane, 0.3, [0.0; 3]).unwrap())
                .unwrap();
            for _ in 0..15 {
                s.step(&mut [BodyMut::from(&mut body)]).unwrap();
            }
            body.positions().to_vec()
        };
        let rolling = run(1, Some(0.1));
        assert!(rolling == run(2, Some(0.1)), "{}", T::NAME);
        // The grains did turn: without rolling the block ends elsewhere.
        assert!(rolling != run(1, None), "{}", T::NAME);
    }
    check::<f32>();
    check::<f64>();
}
