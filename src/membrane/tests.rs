//! Validation of the membrane energy and forces: exact gradients, invariances, and the
//! continuum response of affine states.

use nalgebra::{Rotation3, Vector3};

use crate::material::Material;
use crate::mesh::TriangleMesh;

use super::{Membrane, MembraneParams};
use crate::test_rng::Rng;

fn params(material: Material, bending: f64, hourglass: f64, neighbors: usize) -> MembraneParams {
    MembraneParams {
        thickness: 2e-3,
        density: 300.0,
        material,
        bending,
        hourglass,
        neighbors,
    }
}

/// A quarter cylinder of radius 0.3 m: a curved rest shape.
fn cylinder_patch() -> TriangleMesh {
    let flat = TriangleMesh::grid(6, 5, 0.4, 0.3).unwrap();
    let v = flat
        .vertices()
        .iter()
        .map(|p| {
            let angle = p.x / 0.3;
            [0.3 * angle.sin(), p.y, 0.3 * (1.0 - angle.cos())]
        })
        .collect();
    let t = flat
        .triangles()
        .iter()
        .map(|t| t.map(|i| i as i64))
        .collect();
    TriangleMesh::new(v, t).unwrap()
}

fn deform(m: &mut Membrane, noise: &mut Rng, amplitude: f64) {
    let rot = Rotation3::from_scaled_axis(Vector3::new(0.3, -0.2, 0.5));
    let y = m
        .positions()
        .iter()
        .map(|x| rot * (x * 1.1) + noise.vector() * amplitude)
        .collect();
    m.set_positions(y).unwrap();
}

/// `internal_forces` is minus the gradient of the energy, every term and the director's
/// dependence on the positions included (central differences, relative error < 1e-6).
#[test]
fn forces_are_the_exact_negative_gradient_of_the_energy() {
    let materials = [
        Material::stretch_a3(5e3).unwrap(),
        Material::neo_hookean(2e3, 3e3).unwrap(),
    ];
    let meshes = [
        TriangleMesh::grid(5, 4, 0.3, 0.2).unwrap(),
        cylinder_patch(),
    ];
    let mut noise = Rng::new(0x9e3779b97f4a7c15);
    for material in materials {
        for mesh in &meshes {
            for (bending, hourglass, k) in [(0.0, 0.0, 1), (1e-3, 0.5, 1), (2e-4, 0.2, 2)] {
                let mut m =
                    Membrane::new(mesh.clone(), params(material, bending, hourglass, k)).unwrap();
                deform(&mut m, &mut noise, 0.01);
                let forces = m.internal_forces().unwrap();
                let scale = forces.iter().map(|f| f.norm()).fold(0.0, f64::max);
                let y0 = m.positions().to_vec();
                for trial in 0..6 {
                    let dir: Vec<Vector3<f64>> = y0.iter().map(|_| noise.vector()).collect();
                    let eps = 1e-6;
                    let at = |s: f64, m: &mut Membrane| {
                        m.set_positions(y0.iter().zip(&dir).map(|(y, d)| y + d * s).collect())
                            .unwrap();
                        m.energy_terms().unwrap().total()
                    };
                    let fd = (at(eps, &mut m) - at(-eps, &mut m)) / (2.0 * eps);
                    let analytic: f64 =
                        -forces.iter().zip(&dir).map(|(f, d)| f.dot(d)).sum::<f64>();
                    let norm: f64 = dir.iter().map(|d| d.norm()).sum::<f64>() * scale;
                    assert!(
                        (fd - analytic).abs() <= 1e-6 * norm,
                        "{material:?} bending {bending} hourglass {hourglass} k {k} trial {trial}: fd {fd} vs {analytic}"
                    );
                }
                m.set_positions(y0).unwrap();
            }
        }
    }
}

/// Rigid motions of flat and curved rest shapes store no energy and give no force; forces and
/// torques balance in any state.
#[test]
fn rigid_motion_is_free_and_forces_balance() {
    let mut noise = Rng::new(7);
    for mesh in [
        TriangleMesh::grid(6, 6, 0.5, 0.5).unwrap(),
        cylinder_patch(),
    ] {
        let mut m = Membrane::new(
            mesh,
            params(Material::neo_hookean(4e3, 1e3).unwrap(), 1e-3, 0.3, 1),
        )
        .unwrap();
        let rot = Rotation3::from_scaled_axis(Vector3::new(1.0, 2.0, -0.5));
        let shift = Vector3::new(3.0, -1.0, 2.0);
        let moved = m.positions().iter().map(|x| rot * x + shift).collect();
        m.set_positions(moved).unwrap();
        let f_max = m
            .internal_forces()
            .unwrap()
            .iter()
            .map(|f| f.norm())
            .fold(0.0, f64::max);
        assert!(
            m.energy_terms().unwrap().total().abs() < 1e-12,
            "{:?}",
            m.energy_terms().unwrap()
        );
        assert!(f_max < 1e-9, "rigid motion force {f_max}");
        deform(&mut m, &mut noise, 0.02);
        let f = m.internal_forces().unwrap();
        let scale = f.iter().map(|f| f.norm()).sum::<f64>();
        let total: Vector3<f64> = f.iter().sum();
        let torque: Vector3<f64> = f.iter().zip(m.positions()).map(|(f, y)| y.cross(f)).sum();
        assert!(total.norm() < 1e-12 * scale, "net force {total}");
        assert!(torque.norm() < 1e-12 * scale, "net torque {torque}");
    }
}

/// A flat sheet stretched uniformly by (l1, l2): every vertex sees those stretches, bending and
/// hourglass energies vanish, and the reaction on the right edge per rest cross-section equals
/// `dPsi/dl1` (the discrete model reproduces the continuum stress exactly for affine states).
#[test]
fn affine_stretch_reproduces_the_continuum_stress() {
    let (a, b, t) = (0.4, 0.3, 2e-3);
    for material in [
        Material::stretch_a3(5e3).unwrap(),
        Material::neo_hookean(2e3, 3e3).unwrap(),
    ] {
        let mut m = Membrane::new(
            TriangleMesh::grid(9, 7, a, b).unwrap(),
            params(material, 1e-3, 0.5, 1),
        )
        .unwrap();
        let (l1, l2) = (1.3, 0.9);
        let y = m
            .positions()
            .iter()
            .map(|x| Vector3::new(l1 * x.x, l2 * x.y, 0.0))
            .collect();
        m.set_positions(y).unwrap();
        for s in m.stretches().unwrap() {
            assert!((s[0] - l1).abs() < 1e-12 && (s[1] - l2).abs() < 1e-12 && s[2] == 1.0);
        }
        let e = m.energy_terms().unwrap();
        assert!(e.bending.abs() < 1e-20 && e.hourglass.abs() < 1e-20);
        let reaction: f64 = m
            .internal_forces()
            .unwrap()
            .iter()
            .zip(m.mesh().vertices())
            .filter(|(_, x)| (x.x - a).abs() < 1e-12)
            .map(|(f, _)| -f.x)
            .sum();
        let p11 = material.to_real::<f64>().stress([l1, l2, 1.0])[0];
        assert!(
            (reaction / (b * t) - p11).abs() < 1e-9 * p11.abs(),
            "{material:?}: {} vs {p11}",
            reaction / (b * t)
        );
    }
}

/// Pin indices are never truncated on the way in: an unpin of vertex 2^32 is refused, naming
/// it, and leaves vertex 0 pinned (it would wrap to 0 in 32 bits).
#[test]
fn unpin_refuses_indices_beyond_32_bits_without_wrapping() {
    let mut m = Membrane::new(
        TriangleMesh::grid(3, 3, 1.0, 1.0).unwrap(),
        params(Material::stretch_a3(1e4).unwrap(), 0.0, 0.0, 1),
    )
    .unwrap();
    m.pin(&[0, 4], None).unwrap();
    let error = m.unpin(Some(&[4, 1 << 32])).unwrap_err().to_string();
    assert!(error.contains("4294967296"), "{error}");
    assert_eq!(m.pins().len(), 2, "a refused unpin changes nothing");
    assert!(m.unpin(Some(&[-1])).is_err());
    m.unpin(Some(&[0])).unwrap();
    assert_eq!(m.pins().keys().collect::<Vec<_>>(), [&4]);
}
