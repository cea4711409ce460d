//! GPU against CPU. Without an adapter these tests print why and pass, unless
//! `PERIDYN_REQUIRE_GPU=1`, which makes a missing adapter a failure (CI sets it).

use nalgebra::Vector3;

use crate::contact::{Collider, Shape};
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
        let stats = solver.step(&mut [&mut body]).unwrap();
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
            let sa = gpu.step(&mut [&mut a]).unwrap();
            let sb = cpu.step(&mut [&mut b]).unwrap();
            assert!(
                sa.iterations.abs_diff(sb.iterations) <= 2,
                "step {step}: {} vs {} iterations",
                sa.iterations,
                sb.iterations
            );
            assert_eq!(sa.energies.len(), sa.iterations + 1);
        }
        let worst = a
            .positions()
            .iter()
            .zip(b.positions())
            .map(|(p, q)| (p - q).norm())
            .fold(0.0, f64::max);
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
                    let moved = body
                        .positions()
                        .iter()
                        .map(|p| p + Vector3::new(0.1, 0.0, 0.2));
                    body.set_positions(moved.collect()).unwrap();
                }
                5 => {
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
        gpu.step(&mut [&mut a]).unwrap();
        cpu.step(&mut [&mut b]).unwrap();
        let worst = a
            .positions()
            .iter()
            .zip(b.positions())
            .map(|(p, q)| (p - q).norm())
            .fold(0.0, f64::max);
        assert!(worst < 1e-5, "step {step}: GPU and CPU differ by {worst} m");
    }
}
