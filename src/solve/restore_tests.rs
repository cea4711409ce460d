//! Save, restore and continue: which of the state a solver carries from one step to the next
//! changes results. Three layers of cloth drop onto a ball with contact; at step `K` the run
//! is interrupted (a piece of the solver's state dropped, or the bodies continued by a fresh
//! solver), and after `K + N` steps positions and velocities must equal those of the
//! uninterrupted run bit for bit.

use nalgebra::Vector3;

use crate::collider::{Collider, Shape};
use crate::contact::local_step::Piece;
use crate::contact::ContactParams;
use crate::membrane::Membrane;
use crate::mesh::TriangleMesh;
use crate::real::Real;

use super::{Acceleration, Forget, Method, Solver, SolverParams};

/// Steps before the interruption: the bottom layer is on the ball, the layers are in contact.
const K: usize = 12;
/// Steps after it.
const N: usize = 8;

/// Three 12 x 12 layers of soft cloth, 0.3 m wide, 5 mm apart and shifted against each other,
/// just above a ball.
fn layers() -> Vec<Membrane> {
    let params = super::tests::soft_params();
    (0..3)
        .map(|layer| {
            let mut m =
                Membrane::new(TriangleMesh::grid(12, 12, 0.3, 0.3).unwrap(), params).unwrap();
            let shift = Vector3::new(
                -0.15 + 0.004 * layer as f64,
                -0.15 + 0.003 * layer as f64,
                0.104 + 0.005 * layer as f64,
            );
            let lifted = m.positions().iter().map(|p| p + shift).collect();
            m.set_positions(lifted).unwrap();
            m
        })
        .collect()
}

fn params(acceleration: Acceleration, method: Method) -> SolverParams {
    SolverParams {
        dt: 2e-3,
        max_iters: 30,
        contact: Some(ContactParams::default()),
        acceleration,
        method,
        ..SolverParams::default()
    }
}

fn solver<T: Real>(params: SolverParams) -> Solver<T> {
    let mut solver = Solver::new(params, Some(2)).unwrap();
    solver
        .add_collider(Collider::fixed(
            Shape::sphere([0.0, 0.0, 0.0], 0.1).unwrap(),
        ))
        .unwrap();
    solver
}

/// How the run is interrupted after step `K`.
#[derive(Clone, Copy, Debug)]
enum Interrupt {
    /// Not at all.
    None,
    /// The solver drops one piece of its state.
    Forget(Forget),
    /// A fresh solver, built the same way, continues from what a saved state holds.
    Restore,
}

type State = Vec<(Vec<Vector3<f64>>, Vec<Vector3<f64>>)>;

fn run<T: Real>(params: SolverParams, interrupt: Interrupt) -> State {
    run_for::<T>(params, interrupt, (K, N))
}

/// [`run`] with `k` steps before the interruption and `n` after.
fn run_for<T: Real>(params: SolverParams, interrupt: Interrupt, (k, n): (usize, usize)) -> State {
    let mut bodies = layers();
    let mut solver = solver::<T>(params);
    let step = |solver: &mut Solver<T>, bodies: &mut Vec<Membrane>| {
        let mut list: Vec<_> = bodies.iter_mut().map(Into::into).collect();
        solver.step(&mut list).unwrap().contact.active_pairs
    };
    for _ in 0..k {
        step(&mut solver, &mut bodies);
    }
    match interrupt {
        Interrupt::None => {}
        Interrupt::Forget(what) => solver.forget(what),
        Interrupt::Restore => {
            let saved = solver.saved_state(&[]);
            let mut fresh = self::solver::<T>(params);
            fresh.set_clock(solver.clock());
            for c in 0..1 {
                let (base, target) = solver.collider_motion(c).unwrap();
                fresh.set_collider_motion(c, base, target).unwrap();
            }
            fresh.restore_state(saved).unwrap();
            solver = fresh;
        }
    }
    let active = (0..n)
        .map(|_| step(&mut solver, &mut bodies))
        .min()
        .unwrap();
    assert!(active > 0, "a step after the interruption has no contact");
    bodies
        .iter()
        .map(|b| (b.positions().to_vec(), b.velocities().to_vec()))
        .collect()
}

/// The largest difference in position (m) between two states.
fn largest_difference(a: &State, b: &State) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(a, b)| a.0.iter().zip(&b.0))
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, f64::max)
}

fn assert_same<T: Real>(params: SolverParams, interrupt: Interrupt) {
    let straight = run::<T>(params, Interrupt::None);
    let interrupted = run::<T>(params, interrupt);
    assert!(
        straight == interrupted,
        "{interrupt:?} ({}) changes the positions by up to {:e} m after {N} steps",
        std::any::type_name::<T>(),
        largest_difference(&straight, &interrupted)
    );
}

const PLAIN: Acceleration = Acceleration::None;
const CHEBYSHEV: Acceleration = Acceleration::Chebyshev { rho: 0.9, delay: 2 };

/// A fresh solver given the bodies, clock, collider motion and the solver's saved state (the
/// contact warm start and rest gaps) continues the run bit for bit, in f64 and f32, with and
/// without Chebyshev.
#[test]
fn a_restored_solver_continues_bit_for_bit() {
    for acceleration in [PLAIN, CHEBYSHEV] {
        let params = params(acceleration, Method::Sissm);
        assert_same::<f64>(params, Interrupt::Restore);
        assert_same::<f32>(params, Interrupt::Restore);
    }
    assert_same::<f64>(params(PLAIN, Method::Descent), Interrupt::Restore);
}

/// Every piece of the state the solver carries over that is not saved is a cache: dropping it
/// changes no bit of the results.
#[test]
fn the_unsaved_cross_step_state_is_a_cache() {
    let pieces = [
        Forget::Workspace(Piece::BarrierIndex),
        Forget::Workspace(Piece::LiveList),
        Forget::Workspace(Piece::Allowances),
        Forget::Workspace(Piece::PairCache),
        Forget::Contact,
        Forget::Families,
    ];
    for what in pieces {
        assert_same::<f64>(params(PLAIN, Method::Sissm), Interrupt::Forget(what));
    }
    assert_same::<f64>(
        params(PLAIN, Method::Descent),
        Interrupt::Forget(Forget::Descent),
    );
}

/// The experiment behind the two tests above, printed: how far each piece moves the results
/// when dropped (`cargo test --release cross_step_state -- --ignored --nocapture`; the
/// environment variable `RESTORE_STEPS=k,n` sets the steps before and after the interruption).
#[test]
#[ignore]
fn cross_step_state_report() {
    let pieces = [
        Forget::Workspace(Piece::WarmStart),
        Forget::Workspace(Piece::BarrierIndex),
        Forget::Workspace(Piece::LiveList),
        Forget::Workspace(Piece::Allowances),
        Forget::Workspace(Piece::PairCache),
        Forget::Contact,
        Forget::Families,
        Forget::Descent,
    ];
    let steps = std::env::var("RESTORE_STEPS").map_or((K, N), |s| {
        let (k, n) = s.split_once(',').expect("RESTORE_STEPS=k,n");
        (k.parse().unwrap(), n.parse().unwrap())
    });
    for (method, acceleration) in [
        (Method::Sissm, PLAIN),
        (Method::Sissm, CHEBYSHEV),
        (Method::Descent, PLAIN),
    ] {
        let params = params(acceleration, method);
        let straight = run_for::<f64>(params, Interrupt::None, steps);
        let name = format!("{method:?} {acceleration:?}");
        for what in pieces {
            let forgotten = run_for::<f64>(params, Interrupt::Forget(what), steps);
            let d = largest_difference(&straight, &forgotten);
            println!("{name} {what:?}: {d:e} m");
        }
        let restored = run_for::<f64>(params, Interrupt::Restore, steps);
        let d = largest_difference(&straight, &restored);
        println!("{name} restore: {d:e} m");
    }
}
