//! Solver invariants: implicit Euler exactness in free fall, determinism across thread
//! counts, exact iteration counts, and divergence leaving the bodies untouched.

use nalgebra::Vector3;

use crate::collider::{Collider, Shape};
use crate::isa::Isa;
use crate::material::Material;
use crate::membrane::{Membrane, MembraneParams, Preconditioner};
use crate::mesh::TriangleMesh;
use crate::real::Real;

use super::{Acceleration, Solver, SolverParams};

/// The paper's stiff neo-Hookean cloth material (Fig. 13), 1 mm thick.
pub(crate) fn stiff_params() -> MembraneParams {
    MembraneParams {
        thickness: 1e-3,
        density: 300.0,
        material: Material::neo_hookean(4.8e7, 1.2e7).unwrap(),
        bending: 1e-5,
        hourglass: 0.1,
        neighbors: 1,
    }
}

/// A pinnable square cloth of 0.5 m with the paper's stiff neo-Hookean material (Fig. 13).
fn stiff_cloth(n: usize) -> Membrane {
    Membrane::new(TriangleMesh::grid(n, n, 0.5, 0.5).unwrap(), stiff_params()).unwrap()
}

/// A soft cloth of 1 mm (StretchA3, s0 = 1e4 Pa, 300 kg/m^3, light bending).
pub(super) fn soft_params() -> MembraneParams {
    MembraneParams {
        thickness: 1e-3,
        density: 300.0,
        material: Material::stretch_a3(1e4).unwrap(),
        bending: 1e-5,
        hourglass: 0.1,
        neighbors: 1,
    }
}

fn cloth(n: usize) -> Membrane {
    Membrane::new(TriangleMesh::grid(n, n, 0.5, 0.5).unwrap(), soft_params()).unwrap()
}

/// With no pins and no colliders every vertex follows implicit Euler exactly:
/// `y_n = y_0 + h^2 g n (n + 1) / 2`, `v_n = h g n`.
#[test]
fn free_fall_is_implicit_euler() {
    let mut body = cloth(6);
    let x0 = body.positions().to_vec();
    let params = SolverParams {
        dt: 0.01,
        gravity: [0.5, -1.0, -9.81],
        ..SolverParams::default()
    };
    let mut solver = Solver::<f64>::new(params, None).unwrap();
    let g = Vector3::from(params.gravity);
    for n in 1..=20u32 {
        solver.step(&mut [(&mut body).into()]).unwrap();
        let drop = g * (params.dt * params.dt * (n * (n + 1)) as f64 / 2.0);
        for (y, x) in body.positions().iter().zip(&x0) {
            assert!((y - (x + drop)).norm() < 1e-12, "step {n}");
        }
        for v in body.velocities() {
            assert!((v - g * (params.dt * n as f64)).norm() < 1e-12);
        }
    }
}

/// The result does not depend on the number of worker threads, bit for bit.
#[test]
fn one_and_two_threads_agree_bit_for_bit() {
    let run = |threads| {
        let mut body = cloth(30);
        body.pin(&(0..30).collect::<Vec<i64>>(), None).unwrap();
        let mut solver = Solver::<f64>::new(
            SolverParams {
                tol: 0.0,
                max_iters: 7,
                ..SolverParams::default()
            },
            Some(threads),
        )
        .unwrap();
        solver
            .add_collider(Collider::fixed(
                Shape::sphere([0.25, 0.3, -0.2], 0.15).unwrap(),
            ))
            .unwrap();
        for _ in 0..15 {
            solver.step(&mut [(&mut body).into()]).unwrap();
        }
        body.positions().to_vec()
    };
    assert_eq!(run(1), run(2));
}

/// Without colliders the whole move runs in SIMD lanes; with a collider each lane finishes as
/// the per-vertex move does. A plane far below the cloth changes nothing, so both must give the same
/// positions, velocities and convergence measures bit for bit: in both precisions, for a stiff
/// and a soft material started stretched and crumpled (the step length cuts moves), plain and
/// Chebyshev-accelerated, with a pinned row and a vertex count that leaves a chunk a tail
/// shorter than a pack.
#[test]
fn a_far_collider_changes_no_bit_of_the_move() {
    fn run<T: Real>(
        body: fn(usize) -> Membrane,
        acceleration: Acceleration,
        far_plane: bool,
    ) -> (Vec<Vector3<f64>>, Vec<u64>) {
        let mut body = body(15);
        // Stretched by 30 % in x and crumpled in z.
        let stretched = body
            .positions()
            .iter()
            .map(|p| {
                Vector3::new(
                    1.3 * p.x,
                    p.y,
                    0.02 * (40.0 * p.x).sin() * (31.0 * p.y).cos(),
                )
            })
            .collect();
        body.set_positions(stretched).unwrap();
        body.pin(&(0..15).collect::<Vec<i64>>(), None).unwrap();
        let params = SolverParams {
            tol: 0.0,
            max_iters: 6,
            acceleration,
            // The paper's split preconditioner: its moves overshoot, so the step length cuts.
            preconditioner: Preconditioner::Paper,
            ..SolverParams::default()
        };
        let mut solver = Solver::<T>::new(params, Some(2)).unwrap();
        if far_plane {
            let plane = Shape::plane([0.0, 0.0, -100.0], [0.0, 0.0, 1.0]).unwrap();
            solver.add_collider(Collider::fixed(plane)).unwrap();
        }
        let mut measures = Vec::new();
        for _ in 0..6 {
            let stats = solver.step(&mut [(&mut body).into()]).unwrap();
            measures.push(stats.residual().to_bits());
            measures.extend(stats.moves.iter().map(|r| r.to_bits()));
        }
        let mut state = body.positions().to_vec();
        state.extend_from_slice(body.velocities());
        (state, measures)
    }
    let chebyshev = Acceleration::Chebyshev { rho: 0.9, delay: 2 };
    for body in [cloth as fn(usize) -> Membrane, stiff_cloth] {
        for acceleration in [Acceleration::None, chebyshev] {
            let start = body(15).positions().to_vec();
            let packed = run::<f32>(body, acceleration, false);
            assert!(packed.0[..start.len()] != start[..], "the cloth moved");
            let per_vertex = run::<f32>(body, acceleration, true);
            assert_eq!(packed.0, per_vertex.0, "f32 states");
            assert_eq!(packed.1, per_vertex.1, "f32 measures");
            assert_eq!(
                run::<f64>(body, acceleration, false),
                run::<f64>(body, acceleration, true),
                "f64"
            );
        }
    }
}

/// The AVX2 copy of the hot loops (kernel and move, see [`crate::isa`]) gives the portable
/// copy's positions and velocities bit for bit, in both precisions and for both materials, with
/// a pinned row, a collider and the step length in play.
#[test]
fn avx2_and_portable_copies_agree_bit_for_bit() {
    fn run<T: Real>(isa: Isa, body: fn(usize) -> Membrane) -> Vec<Vector3<f64>> {
        assert!(isa.force());
        let mut body = body(16);
        body.pin(&(0..16).collect::<Vec<i64>>(), None).unwrap();
        let params = SolverParams {
            tol: 0.0,
            max_iters: 7,
            ..SolverParams::default()
        };
        let mut solver = Solver::<T>::new(params, Some(2)).unwrap();
        solver
            .add_collider(Collider::fixed(
                Shape::sphere([0.25, 0.3, -0.1], 0.15).unwrap(),
            ))
            .unwrap();
        for _ in 0..8 {
            solver.step(&mut [(&mut body).into()]).unwrap();
        }
        let mut state = body.positions().to_vec();
        state.extend_from_slice(body.velocities());
        state
    }
    if !Isa::Avx2.force() {
        eprintln!("this CPU has no AVX2: nothing to compare");
        return;
    }
    for body in [cloth as fn(usize) -> Membrane, stiff_cloth] {
        let start = body(16).positions().to_vec();
        let portable = run::<f32>(Isa::Portable, body);
        assert!(portable[..start.len()] != start[..], "the cloth moved");
        assert_eq!(portable, run::<f32>(Isa::Avx2, body), "f32");
        assert_eq!(
            run::<f64>(Isa::Portable, body),
            run::<f64>(Isa::Avx2, body),
            "f64"
        );
    }
    Isa::reset();
}

/// `tol = 0` runs exactly `max_iters` iterations and never claims convergence.
#[test]
fn zero_tolerance_runs_every_iteration() {
    let mut body = cloth(5);
    body.pin(&[0, 1, 2], None).unwrap();
    let mut solver = Solver::<f32>::new(
        SolverParams {
            tol: 0.0,
            max_iters: 13,
            ..SolverParams::default()
        },
        None,
    )
    .unwrap();
    let stats = solver.step(&mut [(&mut body).into()]).unwrap();
    assert_eq!(
        (stats.iterations, stats.moves.len(), stats.converged),
        (13, 13, false)
    );
}

/// A step that overflows reports the vertex and leaves positions and velocities as they were.
#[test]
fn divergence_leaves_the_last_good_state() {
    let mut body = cloth(5);
    let mut solver = Solver::<f64>::new(SolverParams::default(), None).unwrap();
    solver.step(&mut [(&mut body).into()]).unwrap();
    let mut v = body.velocities().to_vec();
    v[3] = Vector3::new(1e307, -1e307, 1e307);
    body.set_velocities(v).unwrap();
    let (x, v) = (body.positions().to_vec(), body.velocities().to_vec());
    let err = solver.step(&mut [(&mut body).into()]).unwrap_err();
    assert!(matches!(err, crate::error::Error::Diverged { .. }), "{err}");
    assert_eq!(body.positions(), &x[..]);
    assert_eq!(body.velocities(), &v[..]);
    assert_eq!(solver.clock().steps, 1);
}

/// A cloth hanging from one edge, stepped once with a long time step: a problem the plain
/// iteration needs many iterations for.
fn hanging_step(params: SolverParams) -> (Vec<Vector3<f64>>, super::StepStats) {
    let mut body = cloth(12);
    body.pin(&(0..12).collect::<Vec<i64>>(), None).unwrap();
    let mut solver = Solver::<f64>::new(
        SolverParams {
            dt: 0.02,
            gravity: [0.0, -9.81, -3.0],
            ..params
        },
        None,
    )
    .unwrap();
    let stats = solver.step(&mut [(&mut body).into()]).unwrap();
    (body.positions().to_vec(), stats)
}

/// The measure's history has one entry per iteration and the step stopped at the first
/// iterate whose measure fell below `tol`.
fn stops_at_the_first_iterate_below_tol(stats: &super::StepStats, tol: f64) {
    let history = &stats.residuals;
    assert_eq!(history.len(), stats.iterations);
    assert!(stats.residual() < tol);
    assert!(
        history[..history.len() - 1].iter().all(|&e| e >= tol),
        "{history:?}"
    );
}

/// Chebyshev acceleration reaches the same implicit Euler solution in fewer iterations.
#[test]
fn chebyshev_converges_to_the_same_solution_faster() {
    let tight = SolverParams {
        tol: 1e-10,
        max_iters: 5000,
        acceleration: super::Acceleration::None,
        ..SolverParams::default()
    };
    let (plain, plain_stats) = hanging_step(tight);
    let accelerated = SolverParams {
        acceleration: super::Acceleration::Chebyshev {
            rho: 0.99,
            delay: 5,
        },
        ..tight
    };
    let (fast, fast_stats) = hanging_step(accelerated);
    assert!(plain_stats.converged && fast_stats.converged);
    for stats in [&plain_stats, &fast_stats] {
        stops_at_the_first_iterate_below_tol(stats, tight.tol);
    }
    assert!(
        fast_stats.iterations * 2 < plain_stats.iterations,
        "chebyshev {} vs plain {} iterations",
        fast_stats.iterations,
        plain_stats.iterations
    );
    let gap = plain
        .iter()
        .zip(&fast)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(gap < 1e-6, "solutions differ by {gap} m");
}

/// The recorded variational energy is E(y^0) .. E(y^K), falls overall, and ends at the minimum
/// (a perturbed converged state never has lower energy).
#[test]
fn recorded_energy_decreases_to_its_minimum() {
    let params = SolverParams {
        tol: 1e-9,
        max_iters: 3000,
        record_energy: true,
        ..SolverParams::default()
    };
    let (_, stats) = hanging_step(params);
    assert_eq!(stats.energies.len(), stats.iterations + 1);
    let (first, last) = (stats.energies[0], *stats.energies.last().unwrap());
    assert!(last < first, "energy rose from {first} to {last}");
    let min = stats.energies.iter().cloned().fold(f64::INFINITY, f64::min);
    assert!(
        last - min <= 1e-9 * first.abs().max(1.0),
        "final {last} above minimum {min}"
    );
}

/// A sheet resting on a slope of angle theta with Coulomb friction mu slides down with the
/// acceleration `g (sin theta - mu cos theta)` that implicit Euler predicts when
/// `mu < tan theta`, and stays put when `mu > tan theta`; it never leaves the slope.
#[test]
fn a_sheet_on_a_slope_obeys_coulomb_friction() {
    let theta: f64 = 0.4;
    let rotation = nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), theta);
    let normal = rotation * Vector3::z();
    let params = SolverParams {
        dt: 0.01,
        tol: 1e-10,
        max_iters: 2000,
        ..SolverParams::default()
    };
    let g = Vector3::from(params.gravity);
    let down_slope = (g - normal * normal.dot(&g)).normalize();
    for mu in [0.0, 0.2, 0.6] {
        let mut body = cloth(8);
        let half = body.params().thickness / 2.0;
        let placed = body
            .positions()
            .iter()
            .map(|x| rotation * x + normal * half)
            .collect();
        body.set_positions(placed).unwrap();
        let mut solver = Solver::<f64>::new(params, None).unwrap();
        let slope = Shape::plane([0.0; 3], normal.into()).unwrap();
        solver
            .add_collider(Collider::new(slope, mu, [0.0; 3]).unwrap())
            .unwrap();
        let along = (g.norm() * (theta.sin() - mu * theta.cos())).max(0.0);
        for n in 1..=10 {
            assert!(solver.step(&mut [(&mut body).into()]).unwrap().converged);
            for (v, y) in body.velocities().iter().zip(body.positions()) {
                let expected = down_slope * (along * params.dt * n as f64);
                assert!(
                    (v - expected).norm() < 1e-7,
                    "mu {mu}, step {n}: v = {v}, expected {expected}"
                );
                assert!((y.dot(&normal) - half).abs() < 1e-9);
            }
        }
    }
}

/// Contact in the solver: a sheet dropped onto another resting on the ground stays above it
/// (every upper vertex over the lower sheet above the lower sheet's highest point, which is
/// flat), in f64 and f32, plain and with Chebyshev's extrapolation, with no vertex inside the
/// ground's margin after any step (every step ends on a local step's result, so this holds
/// whatever the extrapolation does between iterations; its own collider rule is tested by
/// `the_extrapolation_keeps_a_vertex_that_could_reach_into_a_collider`), and the step reports
/// the contact figures; without contact it falls through.
#[test]
fn contact_keeps_a_falling_sheet_above_a_resting_one() {
    use crate::contact::ContactParams;
    fn run<T: crate::real::Real>(
        contact: Option<ContactParams>,
        acceleration: super::Acceleration,
    ) -> (f64, f64, usize) {
        let mut lower = cloth(6);
        let mut upper = cloth(6);
        let lifted: Vec<_> = upper
            .positions()
            .iter()
            .map(|p| p + Vector3::new(0.02, 0.03, 0.01))
            .collect();
        upper.set_positions(lifted).unwrap();
        upper
            .set_velocities(vec![Vector3::new(0.0, 0.0, -1.0); 36])
            .unwrap();
        let mut solver = Solver::<T>::new(
            SolverParams {
                dt: 2e-3,
                max_iters: 10,
                contact,
                acceleration,
                ..SolverParams::default()
            },
            None,
        )
        .unwrap();
        solver
            .add_collider(Collider::fixed(
                Shape::plane([0.0; 3], [0.0, 0.0, 1.0]).unwrap(),
            ))
            .unwrap();
        let mut active = 0;
        for _ in 0..20 {
            let stats = solver
                .step(&mut [(&mut lower).into(), (&mut upper).into()])
                .unwrap();
            active = active.max(stats.contact.active_pairs);
            let margin = lower.params().thickness / 2.0;
            for p in lower.positions().iter().chain(upper.positions()) {
                assert!(
                    p.z >= margin - 1e-6,
                    "{} m below the ground's margin",
                    margin - p.z
                );
            }
        }
        // The upper sheet's vertices over the lower one (its overhang may drape down past
        // the lower sheet's edge), and the lower sheet's top.
        let over = |p: &&Vector3<f64>| (0.0..=0.5).contains(&p.x) && (0.0..=0.5).contains(&p.y);
        let upper_low = upper
            .positions()
            .iter()
            .filter(over)
            .map(|p| p.z)
            .fold(f64::INFINITY, f64::min);
        let lower_top = lower
            .positions()
            .iter()
            .map(|p| p.z)
            .fold(f64::NEG_INFINITY, f64::max);
        (upper_low, lower_top, active)
    }
    let params = ContactParams {
        thickness: 2e-3,
        d_hat: 4e-3,
        ..ContactParams::default()
    };
    let chebyshev = super::Acceleration::Chebyshev { rho: 0.9, delay: 2 };
    let plain = super::Acceleration::None;
    for (upper, lower, active) in [
        run::<f64>(Some(params), plain),
        run::<f32>(Some(params), plain),
        run::<f64>(Some(params), chebyshev),
        run::<f32>(Some(params), chebyshev),
    ] {
        assert!(active > 0);
        assert!(
            upper - lower > params.eps * params.thickness,
            "{upper} vs {lower}"
        );
    }
    let (upper, lower, active) = run::<f64>(None, plain);
    assert_eq!(active, 0);
    assert!(
        upper < lower,
        "without contact the sheets should pass through each other"
    );
}

/// Chebyshev's extrapolation of a local step's result moves a vertex away from colliders, and
/// keeps in place one whose extrapolated move could reach into a collider (the ground, at a
/// margin of 1 mm): the global step's collider projection needs an iterate outside them.
#[test]
fn the_extrapolation_keeps_a_vertex_that_could_reach_into_a_collider() {
    use crate::collider::MovingCollider;
    let ground = MovingCollider::new(Collider::fixed(
        Shape::plane([0.0; 3], [0.0, 0.0, 1.0]).unwrap(),
    ))
    .during_step::<f64>(0.0, 1e-3);
    let (w, margin) = (1.5, 1e-3);
    // From 5 mm up towards the ground by 2 mm, extrapolated by a further 1 mm: 2 mm up, clear.
    let (previous, z) = (Vector3::new(0.1, 0.2, 7e-3), Vector3::new(0.1, 0.2, 5e-3));
    let grounds = std::slice::from_ref(&ground);
    let far = super::collider_passes::extrapolated(&z, &previous, w, margin, grounds);
    assert!(
        (far - Vector3::new(0.1, 0.2, 4e-3)).norm() < 1e-15,
        "{far:?}"
    );
    // 1.8 mm up: the extra 1 mm would end within the margin (and sideways too).
    let (previous, z) = (
        Vector3::new(0.0, 0.0, 3.8e-3),
        Vector3::new(1e-3, 0.0, 1.8e-3),
    );
    let near = super::collider_passes::extrapolated(&z, &previous, w, margin, grounds);
    assert_eq!(near, z);
    // With no collider the same vertex is extrapolated.
    let free = super::collider_passes::extrapolated(&z, &previous, w, margin, &[]);
    assert!(
        (free - Vector3::new(1.5e-3, 0.0, 0.8e-3)).norm() < 1e-15,
        "{free:?}"
    );
}

/// A sheet lying on a moving plate with friction is carried along with it.
#[test]
fn friction_carries_a_sheet_on_a_moving_plate() {
    let params = SolverParams {
        dt: 0.01,
        tol: 1e-10,
        max_iters: 2000,
        ..SolverParams::default()
    };
    let mut body = cloth(6);
    let half = body.params().thickness / 2.0;
    let placed = body
        .positions()
        .iter()
        .map(|x| x + Vector3::z() * half)
        .collect();
    body.set_positions(placed).unwrap();
    let mut solver = Solver::<f64>::new(params, None).unwrap();
    let plate = Shape::plane([0.0; 3], [0.0, 0.0, 1.0]).unwrap();
    solver
        .add_collider(Collider::new(plate, 1.0, [0.3, 0.0, 0.0]).unwrap())
        .unwrap();
    for _ in 0..5 {
        solver.step(&mut [(&mut body).into()]).unwrap();
    }
    for v in body.velocities() {
        assert!((v - Vector3::new(0.3, 0.0, 0.0)).norm() < 1e-7, "v = {v}");
    }
}

/// Inner Jacobi sweeps (Fig. 6) and the descent baseline (plain and Chebyshev) solve the same
/// implicit Euler step: every variant converges to SISSM's positions within 1e-6 m (the
/// steps move the cloth by centimetres), and more inner sweeps need fewer iterations.
#[test]
fn inner_sweeps_and_descent_reach_the_same_solution() {
    let tight = SolverParams {
        tol: 1e-9,
        max_iters: 20000,
        acceleration: super::Acceleration::None,
        ..SolverParams::default()
    };
    let (reference, plain) = hanging_step(tight);
    let (swept, inner) = hanging_step(SolverParams {
        inner_iters: 4,
        ..tight
    });
    let (descended, descent) = hanging_step(SolverParams {
        method: super::Method::Descent,
        ..tight
    });
    let (accelerated, chebyshev) = hanging_step(SolverParams {
        method: super::Method::Descent,
        acceleration: super::Acceleration::Chebyshev {
            rho: 0.99,
            delay: 3,
        },
        ..tight
    });
    assert!(plain.converged && inner.converged && descent.converged && chebyshev.converged);
    assert!(
        inner.iterations < plain.iterations,
        "inner {} vs plain {}",
        inner.iterations,
        plain.iterations
    );
    for other in [&swept, &descended, &accelerated] {
        let gap = reference
            .iter()
            .zip(other)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        assert!(gap < 1e-6, "solutions differ by {gap} m");
    }
}

/// A stiff pinned cloth (the paper's neo-Hookean, s0 = 4.8e7 Pa, 1 mm thick, h = 5 ms) on
/// which the descent baseline's unit step overshoots: the line search keeps the variational
/// energy from ever rising (to 1e-12 relative), plain and Chebyshev-accelerated, and the
/// energy does come down.
#[test]
fn descent_energy_never_rises_on_a_stiff_cloth() {
    for acceleration in [
        super::Acceleration::None,
        super::Acceleration::Chebyshev {
            rho: 0.99,
            delay: 3,
        },
    ] {
        let mut body = stiff_cloth(10);
        body.pin(&(0..10).collect::<Vec<i64>>(), None).unwrap();
        let mut solver = Solver::<f64>::new(
            SolverParams {
                dt: 5e-3,
                method: super::Method::Descent,
                acceleration,
                tol: 0.0,
                max_iters: 60,
                record_energy: true,
                ..SolverParams::default()
            },
            None,
        )
        .unwrap();
        let stats = solver.step(&mut [(&mut body).into()]).unwrap();
        let e = &stats.energies;
        for pair in e.windows(2) {
            assert!(
                pair[1] <= pair[0] + 1e-12 * pair[0].abs(),
                "{acceleration:?}: energy rose from {} to {}",
                pair[0],
                pair[1]
            );
        }
        assert!(
            e[e.len() - 1] < e[0] - 1e-3 * e[0].abs(),
            "{acceleration:?}: energy {} -> {}",
            e[0],
            e[e.len() - 1]
        );
    }
}

/// The descent baseline is its own iteration, not SISSM under another name: from the same
/// start its iterates and energies differ from SISSM's after one iteration (by more than a
/// millimetre and 1e-6 of the energy). Before the Hessian-diagonal preconditioner, descent
/// used SISSM's `D` with a unit step that was always accepted, and reproduced SISSM's iterates.
#[test]
fn descent_iterates_differ_from_sissm() {
    let one = |method| {
        hanging_step(SolverParams {
            method,
            tol: 0.0,
            max_iters: 1,
            record_energy: true,
            step_length: false,
            ..SolverParams::default()
        })
    };
    let (sissm, sissm_stats) = one(super::Method::Sissm);
    let (descent, descent_stats) = one(super::Method::Descent);
    let gap = sissm
        .iter()
        .zip(&descent)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(gap > 1e-3, "iterates differ by only {gap} m");
    let (a, b) = (sissm_stats.energies[1], descent_stats.energies[1]);
    assert!(
        (a - b).abs() > 1e-6 * a.abs(),
        "energies after one iteration: SISSM {a}, descent {b}"
    );
}

/// A three-layer contact drop like `peridyn.paper_scenes.cloths_over_ball(layers=3, n=16,
/// size=0.5, dt=2e-3, drop=2e-3)`: the layers touch each other (and the contact local step's
/// Jacobi metric comes into play) from about step 19 on, with friction 0.4 between them (so the
/// local step's friction pass runs too). The positions after every step, on a pool of `threads`
/// threads.
fn three_layers_over_ball(threads: usize, steps: usize) -> Vec<Vec<Vector3<f64>>> {
    use crate::contact::ContactParams;
    let (n, size, xi, radius, drop) = (16usize, 0.5, 1.5e-3, 0.15, 2e-3);
    let d_hat = 4.0 * xi;
    let gap = 1.5 * (xi + d_hat);
    let params = MembraneParams {
        thickness: 1e-3,
        density: 300.0,
        material: Material::stretch_a3(12000.0).unwrap(),
        bending: 0.1 * 2.0 * 12000.0 * 1e-9 / 12.0,
        hourglass: MembraneParams::DEFAULT_HOURGLASS,
        neighbors: 1,
    };
    let mut bodies: Vec<Membrane> = (0..3)
        .map(|k| {
            let z = 2.0 * radius + drop + k as f64 * gap;
            let mut mesh = TriangleMesh::grid(n, n, size, size).unwrap();
            let shifted = mesh
                .vertices()
                .iter()
                .map(|p| [p.x - size / 2.0, p.y - size / 2.0, z])
                .collect();
            mesh = TriangleMesh::new(
                shifted,
                mesh.triangles().iter().map(|t| t.map(i64::from)).collect(),
            )
            .unwrap();
            let mut body = Membrane::new(mesh, params).unwrap();
            body.set_friction(0.4).unwrap();
            body
        })
        .collect();
    let contact = ContactParams {
        thickness: xi,
        d_hat,
        ..ContactParams::default()
    };
    let mut solver = Solver::<f64>::new(
        SolverParams {
            dt: 2e-3,
            contact: Some(contact),
            ..SolverParams::default()
        },
        Some(threads),
    )
    .unwrap();
    let ball = Shape::sphere([0.0, 0.0, radius], radius).unwrap();
    let ground = Shape::plane([0.0; 3], [0.0, 0.0, 1.0]).unwrap();
    for shape in [ball, ground] {
        solver
            .add_collider(Collider::new(shape, 0.3, [0.0; 3]).unwrap())
            .unwrap();
    }
    (0..steps)
        .map(|_| {
            let mut list: Vec<_> = bodies.iter_mut().map(Into::into).collect();
            solver.step(&mut list).unwrap();
            bodies.iter().flat_map(|b| b.positions().to_vec()).collect()
        })
        .collect()
}

/// The first step at which two histories differ in some bit, and the largest difference then
/// (m).
fn first_difference(a: &[Vec<Vector3<f64>>], b: &[Vec<Vector3<f64>>]) -> Option<(usize, f64)> {
    a.iter().zip(b).enumerate().find_map(|(step, (x, y))| {
        let bits = |p: &Vector3<f64>| p.map(f64::to_bits);
        x.iter().zip(y).any(|(p, q)| bits(p) != bits(q)).then(|| {
            let most = x
                .iter()
                .zip(y)
                .map(|(p, q)| (p - q).norm())
                .fold(0.0, f64::max);
            (step, most)
        })
    })
}

/// Contact does not make the result depend on the number of threads, nor vary from run to run
/// (a rayon `reduce` behind the Jacobi metric of the contact local step once did, from the
/// first contact on, by 1e-16 m).
#[test]
fn a_contact_drop_agrees_bit_for_bit_across_threads_and_runs() {
    let steps = 50;
    let one = three_layers_over_ball(1, steps);
    for threads in [2, 3, 4] {
        let other = three_layers_over_ball(threads, steps);
        assert_eq!(
            first_difference(&one, &other),
            None,
            "1 vs {threads} threads"
        );
    }
    for run in 0..5 {
        let again = three_layers_over_ball(2, steps);
        assert_eq!(first_difference(&one, &again), None, "2 threads, run {run}");
    }
}
