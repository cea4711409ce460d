//! GPU against CPU. Without an adapter these tests print why and pass, unless
//! `PERIDYN_REQUIRE_GPU=1`, which makes a missing adapter a failure (CI sets it).

use nalgebra::Vector3;

use crate::collider::{Collider, Shape};
use crate::error::{Divergence, Error};
use crate::material::Material;
use crate::membrane::{Membrane, MembraneParams};
use crate::mesh::TriangleMesh;
use crate::solve::{Acceleration, Solver, SolverParams};

use super::{GpuReal, GpuSolver};

/// A GPU solver, or None (with the reason printed) when there is no adapter and the
/// environment does not require one. With an adapter, any failure is a test failure.
fn gpu<T: GpuReal>(params: SolverParams) -> Option<GpuSolver<T>> {
    match super::gpu_info() {
        Ok(_) => Some(GpuSolver::new(params).unwrap()),
        Err(e) if std::env::var("PERIDYN_REQUIRE_GPU").as_deref() == Ok("1") => {
            panic!("PERIDYN_REQUIRE_GPU=1 but the GPU backend is unavailable: {e}")
        }
        Err(e) => {
            eprintln!("skipping GPU test: {e}");
            None
        }
    }
}

/// `max_i |a_i - b_i|` (m), reading `a` back from the device.
fn largest_difference(a: &mut Membrane, b: &Membrane) -> f64 {
    a.sync().unwrap();
    a.positions()
        .iter()
        .zip(b.positions())
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, f64::max)
}

fn cloth(n: usize, material: Material) -> Membrane {
    let params = MembraneParams {
        thickness: 1e-3,
        density: 300.0,
        material,
        bending: 1e-5,
        hourglass: 0.1,
        neighbors: 1,
    };
    Membrane::new(TriangleMesh::grid(n, n, 0.5, 0.5).unwrap(), params).unwrap()
}

/// Free fall is implicit Euler on the GPU too: `y_n = y_0 + h^2 g n (n + 1) / 2`.
#[test]
fn free_fall_is_implicit_euler() {
    let params = SolverParams {
        dt: 0.01,
        gravity: [0.5, -1.0, -9.81],
        ..SolverParams::default()
    };
    let Some(mut solver) = gpu::<f32>(params) else {
        return;
    };
    let mut body = cloth(6, Material::stretch_a3(1e4).unwrap());
    let x0 = body.positions().to_vec();
    let g = Vector3::from(params.gravity);
    for n in 1..=10u32 {
        let stats = solver.step(&mut [(&mut body).into()]).unwrap();
        assert!(body.is_pending(), "the step leaves the state on the device");
        body.sync().unwrap();
        assert!(stats.converged, "step {n}: {stats:?}");
        let drop = g * (params.dt * params.dt * (n * (n + 1)) as f64 / 2.0);
        for (y, x) in body.positions().iter().zip(&x0) {
            assert!((y - (x + drop)).norm() < 1e-5, "step {n}");
        }
    }
}

/// A pinned cloth draping onto a sphere above a floor: GPU and CPU in the same precision
/// agree within `tolerance` (m) over 40 steps, for both materials, with Chebyshev
/// acceleration and the recorded energies.
fn draping_cloth_matches_the_cpu<T: GpuReal>(tolerance: f64) {
    for material in [
        Material::stretch_a3(2e4).unwrap(),
        Material::neo_hookean_from_young(4e4, 0.3).unwrap(),
    ] {
        let params = SolverParams {
            dt: 2e-3,
            tol: 1e-5,
            max_iters: 40,
            acceleration: Acceleration::Chebyshev { rho: 0.9, delay: 3 },
            record_energy: true,
            ..SolverParams::default()
        };
        let Some(mut gpu) = gpu::<T>(params) else {
            return;
        };
        let mut cpu = Solver::<T>::new(params, Some(1)).unwrap();
        let colliders = [
            Collider::fixed(Shape::sphere([0.25, 0.25, -0.15], 0.12).unwrap()),
            Collider::fixed(Shape::plane([0.0, 0.0, -0.2], [0.0, 0.0, 1.0]).unwrap()),
        ];
        for c in colliders {
            gpu.add_collider(c.clone()).unwrap();
            cpu.add_collider(c).unwrap();
        }
        let mut a = cloth(10, material);
        a.pin(&[0, 9], None).unwrap();
        let mut b = cloth(10, material);
        b.pin(&[0, 9], None).unwrap();
        for step in 0..40 {
            let sa = gpu.step(&mut [(&mut a).into()]).unwrap();
            let sb = cpu.step(&mut [(&mut b).into()]).unwrap();
            assert!(
                sa.iterations.abs_diff(sb.iterations) <= 2,
                "step {step}: {} vs {} iterations",
                sa.iterations,
                sb.iterations
            );
            assert_eq!(sa.energies.len(), sa.iterations + 1);
        }
        let worst = largest_difference(&mut a, &b);
        assert!(
            worst < tolerance,
            "{} {material:?}: GPU and CPU differ by {worst} m",
            T::NAME
        );
        assert!(gpu.bytes_per_iteration().unwrap() > 0);
    }
}

#[test]
fn draping_cloth_matches_the_cpu_in_f32() {
    draping_cloth_matches_the_cpu::<f32>(1e-4);
}

/// f64 where the adapter has SHADER_F64 (skipped, saying so, where it does not).
#[test]
fn draping_cloth_matches_the_cpu_in_f64() {
    match super::gpu_info() {
        Ok(info) if !info.f64 => eprintln!("skipping f64 GPU test: {} lacks SHADER_F64", info.name),
        _ => draping_cloth_matches_the_cpu::<f64>(1e-9),
    }
}

/// Positions, velocities and pins changed between steps reach the device (which otherwise
/// keeps its own copy): GPU and CPU agree through teleports, kicks, unpinning, re-pinning and
/// moving pin targets.
#[test]
fn changes_between_steps_reach_the_device() {
    let params = SolverParams {
        dt: 5e-3,
        tol: 1e-6,
        max_iters: 30,
        ..SolverParams::default()
    };
    let Some(mut gpu) = gpu::<f32>(params) else {
        return;
    };
    let mut cpu = Solver::<f32>::new(params, Some(1)).unwrap();
    let material = Material::stretch_a3(1e4).unwrap();
    let (mut a, mut b) = (cloth(6, material), cloth(6, material));
    for step in 0..12 {
        for body in [&mut a, &mut b] {
            match step {
                0 => body.pin(&[0, 5], None).unwrap(),
                3 => {
                    body.sync().unwrap();
                    let moved = body
                        .positions()
                        .iter()
                        .map(|p| p + Vector3::new(0.1, 0.0, 0.2));
                    body.set_positions(moved.collect()).unwrap();
                }
                5 => {
                    body.sync().unwrap();
                    let kicked = body
                        .velocities()
                        .iter()
                        .map(|v| v + Vector3::new(0.0, 1.0, 0.0));
                    body.set_velocities(kicked.collect()).unwrap();
                }
                7 => body.unpin(Some(&[5])).unwrap(),
                9 => body
                    .pin(&[5], Some(&[Vector3::new(0.5, 0.0, 0.3)]))
                    .unwrap(),
                10 => {
                    let targets = [Vector3::new(0.1, 0.0, 0.3), Vector3::new(0.6, 0.0, 0.3)];
                    body.set_pin_targets(&targets).unwrap();
                }
                _ => {}
            }
        }
        gpu.step(&mut [(&mut a).into()]).unwrap();
        cpu.step(&mut [(&mut b).into()]).unwrap();
        // read back only every other step: the device keeps its own copy in between
        if step % 2 == 1 {
            let worst = largest_difference(&mut a, &b);
            assert!(worst < 1e-5, "step {step}: GPU and CPU differ by {worst} m");
        }
    }
}

/// The collider records have the size WGSL gives `struct Collider` (vec3 aligned to 16 bytes
/// in f32 and 32 in f64, mat3x3 columns likewise).
#[test]
fn collider_records_have_the_wgsl_size() {
    assert_eq!(std::mem::size_of::<<f32 as GpuReal>::Collider>(), 112);
    assert_eq!(std::mem::size_of::<<f64 as GpuReal>::Collider>(), 224);
}

/// The params record has the size WGSL gives `struct Params` (rounded up to the alignment of
/// `vec3<real>`: 16 bytes in f32, 32 in f64).
#[test]
fn params_records_have_the_wgsl_size() {
    assert_eq!(std::mem::size_of::<<f32 as GpuReal>::Params>(), 64);
    assert_eq!(std::mem::size_of::<<f64 as GpuReal>::Params>(), 96);
}

/// A cloth thrown at 2e4 m/s against the default `max_speed` of 1e4 m/s: the step diverges
/// with a `TooFast` cause whose speed is the throw's (the first iterate moves it `h v` =
/// 200 m; gravity and the unstretched cloth change that by far less than 1 %), and the body
/// keeps its state.
fn thrown_cloth_is_too_fast<T: GpuReal>() {
    if T::NAME == "f64" && super::gpu_info().is_ok_and(|i| !i.f64) {
        eprintln!("skipping f64 GPU test: the adapter lacks SHADER_F64");
        return;
    }
    let params = SolverParams {
        dt: 1e-2,
        max_iters: 5,
        ..SolverParams::default()
    };
    let Some(mut solver) = gpu::<T>(params) else {
        return;
    };
    let mut body = cloth(5, Material::stretch_a3(1e4).unwrap());
    let throw = vec![Vector3::new(2e4, 0.0, 0.0); body.positions().len()];
    body.set_velocities(throw.clone()).unwrap();
    let x0 = body.positions().to_vec();
    match solver.step(&mut [(&mut body).into()]) {
        Err(Error::Diverged {
            cause: Divergence::TooFast { speed, limit },
            ..
        }) => {
            assert!((speed / 2e4 - 1.0).abs() < 1e-2, "speed {speed} m/s");
            assert_eq!(limit, SolverParams::DEFAULT_MAX_SPEED);
        }
        other => panic!("expected a TooFast divergence, got {other:?}"),
    }
    body.sync().unwrap();
    assert_eq!(body.positions(), &x0[..]);
    assert_eq!(body.velocities(), &throw[..]);
}

#[test]
fn thrown_cloth_is_too_fast_f32() {
    thrown_cloth_is_too_fast::<f32>();
}

#[test]
fn thrown_cloth_is_too_fast_f64() {
    thrown_cloth_is_too_fast::<f64>();
}

/// The time step of [`collider_parity`] (s).
const PARITY_DT: f64 = 2e-3;

/// GPU and CPU (same precision) step the same pinned cloth among `colliders` for `steps`
/// steps; returns the largest position difference (m) and the GPU's final positions, or None
/// without an adapter (or without SHADER_F64 for f64).
fn collider_parity<T: GpuReal>(
    colliders: &[Collider],
    pins: &[i64],
    steps: usize,
) -> Option<(f64, Vec<Vector3<f64>>)> {
    if T::NAME == "f64" && super::gpu_info().is_ok_and(|i| !i.f64) {
        eprintln!("skipping f64 GPU test: the adapter lacks SHADER_F64");
        return None;
    }
    let params = SolverParams {
        dt: PARITY_DT,
        tol: 1e-5,
        max_iters: 40,
        acceleration: Acceleration::Chebyshev { rho: 0.9, delay: 3 },
        ..SolverParams::default()
    };
    let mut gpu = gpu::<T>(params)?;
    let mut cpu = Solver::<T>::new(params, Some(1)).unwrap();
    for c in colliders {
        gpu.add_collider(c.clone()).unwrap();
        cpu.add_collider(c.clone()).unwrap();
    }
    let material = Material::stretch_a3(2e4).unwrap();
    let (mut a, mut b) = (cloth(10, material), cloth(10, material));
    if !pins.is_empty() {
        a.pin(pins, None).unwrap();
        b.pin(pins, None).unwrap();
    }
    for _ in 0..steps {
        gpu.step(&mut [(&mut a).into()]).unwrap();
        cpu.step(&mut [(&mut b).into()]).unwrap();
    }
    let worst = largest_difference(&mut a, &b);
    eprintln!("{}: GPU and CPU differ by {worst:.3e} m", T::NAME);
    Some((worst, a.positions().to_vec()))
}

/// A turned box and a capsule under a cloth pinned at two corners.
fn box_and_capsule() -> Vec<Collider> {
    let turn = nalgebra::Rotation3::from_scaled_axis(Vector3::new(0.2, -0.3, 0.5)).into_inner();
    let rows: [[f64; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| turn[(r, c)]));
    vec![
        Collider::fixed(Shape::cuboid([0.15, 0.25, -0.12], [0.08, 0.1, 0.05], rows).unwrap()),
        Collider::fixed(Shape::capsule([0.25, 0.05, -0.1], [0.4, 0.45, -0.14], 0.04).unwrap()),
    ]
}

/// Box and capsule: 60 steps of a cloth draping over them, GPU against CPU; the cloth rests
/// outside both.
fn box_and_capsule_match_the_cpu<T: GpuReal>(tolerance: f64) {
    let colliders = box_and_capsule();
    let Some((worst, y)) = collider_parity::<T>(&colliders, &[0, 9], 60) else {
        return;
    };
    assert!(
        worst < tolerance,
        "{}: GPU and CPU differ by {worst} m",
        T::NAME
    );
    for c in &colliders {
        let closest = y
            .iter()
            .map(|p| c.signed_distance(p, 0.0))
            .fold(f64::INFINITY, f64::min);
        assert!(
            closest > 0.5e-3 - 1e-5,
            "{c:?}: a vertex is {closest} m from it"
        );
        assert!(
            closest < 0.02,
            "the cloth did not reach {c:?} ({closest} m)"
        );
    }
}

#[test]
fn box_and_capsule_match_the_cpu_in_f32() {
    box_and_capsule_match_the_cpu::<f32>(1e-4);
}

#[test]
fn box_and_capsule_match_the_cpu_in_f64() {
    box_and_capsule_match_the_cpu::<f64>(1e-9);
}

/// Friction and motion: a free cloth on a sticky slope (plane) while a sphere rises into it
/// from below; GPU against CPU in f32.
#[test]
fn friction_and_moving_colliders_match_the_cpu() {
    let slope = Shape::plane([0.0, 0.0, -0.05], [0.3, 0.0, 1.0]).unwrap();
    let colliders = [
        Collider::new(slope, 0.8, [0.0; 3]).unwrap(),
        Collider::new(
            Shape::sphere([0.25, 0.25, -0.2], 0.1).unwrap(),
            0.3,
            [0.0, 0.0, 0.6],
        )
        .unwrap(),
    ];
    let Some((worst, _)) = collider_parity::<f32>(&colliders, &[], 60) else {
        return;
    };
    assert!(worst < 1e-4, "GPU and CPU differ by {worst} m");
}

/// A fast impact: a 4 mm plate comes at the cloth from 5 m away in one step, slanted (2500
/// m/s up, 1500 m/s along), its centre ending 1 cm above it. In the plate's frame every
/// vertex's path
/// starts metres out (the step's start carried by the plate's displacement) and crosses the
/// plate, so each is kept on the near face: the cloth is carried on the plate's upper face at
/// its margin, not left behind under it, on the GPU as on the CPU (within 10 um). Without the
/// carry the GPU leaves the cloth under the plate, 12 mm below its upper face. (The trace's `TOUCH_DISTANCE` does not show
/// here: the iterations after the first projection start next to the plate.)
#[test]
fn a_plate_from_metres_away_lands_the_cloth_on_its_margin_as_on_the_cpu() {
    let (centre_z, half_thickness, velocity) = (-4.99, 0.002, [1500.0, 0.0, 2500.0]);
    let plate = Shape::cuboid(
        [0.25 - velocity[0] * PARITY_DT, 0.25, centre_z],
        [1.0, 1.0, half_thickness],
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    )
    .unwrap();
    let colliders = [Collider::new(plate, 0.0, velocity).unwrap()];
    let Some((worst, y)) = collider_parity::<f32>(&colliders, &[], 1) else {
        return;
    };
    assert!(worst < 1e-5, "GPU and CPU differ by {worst} m");
    // The plate's upper face after the step (1.2 cm up); the cloth's margin is 0.5 mm.
    let face = centre_z + velocity[2] * PARITY_DT + half_thickness;
    for (i, p) in y.iter().enumerate() {
        let height = p.z - face;
        assert!(
            (0.5e-3 - 1e-5..0.6e-3).contains(&height),
            "vertex {i} ended {height} m above the face"
        );
    }
}
