//! The samplers on a cube, a sphere and a square: counts against the lattice's expectation,
//! inside, spacing, coverage, determinism, thread-count invariance, bad input.

use nalgebra::Vector3;

use super::volume::Lattice;
use super::*;
use crate::collider::sdf::tests::{box_mesh, icosphere};
use crate::collider::MeshDistance;
use crate::geometry::find_horizons;
use crate::mesh::TriangleMesh;
use crate::test_rng::Rng;

type Mesh = (Vec<[f64; 3]>, Vec<[i64; 3]>);

fn area(mesh: &Mesh) -> f64 {
    let x = |i: i64| Vector3::from(mesh.0[i as usize]);
    mesh.1
        .iter()
        .map(|t| 0.5 * (x(t[1]) - x(t[0])).cross(&(x(t[2]) - x(t[0]))).norm())
        .sum()
}

fn distance(mesh: &Mesh) -> MeshDistance {
    MeshDistance::new(mesh.0.clone(), mesh.1.clone()).unwrap()
}

/// Bonds closer than `delta` (m) among the points.
fn pairs_closer_than(x: &[Vector3<f64>], delta: f64) -> usize {
    find_horizons(x, delta).unwrap().indices.len() / 2
}

fn volume(mesh: &Mesh, spacing: f64, jitter: f64, seed: u64) -> Vec<Vector3<f64>> {
    sample_volume(mesh.0.clone(), mesh.1.clone(), spacing, jitter, seed).unwrap()
}

/// Every lattice site (moved as the sampler moves it) with a negative exact distance, queried
/// one by one without the sampler's row certificates.
fn brute_force_volume(mesh: &Mesh, spacing: f64, jitter: f64, seed: u64) -> Vec<Vector3<f64>> {
    let d = distance(mesh);
    let (lo, hi) = d.bounds();
    let lattice = Lattice::over(lo, hi, spacing, 1e9).unwrap();
    let [nx, ny, nz] = lattice.dims;
    let mut out = Vec::new();
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let mut x = lattice.site(i, j, k);
                if jitter > 0.0 {
                    x += random::in_unit_ball(seed, [i as u64, j as u64, k as u64])
                        * (jitter * spacing);
                }
                if d.signed_distance_from(&x, 0).0 < 0.0 {
                    out.push(x);
                }
            }
        }
    }
    out
}

#[test]
fn a_unit_cube_holds_its_lattice_exactly() {
    let cube = box_mesh([0.5; 3]);
    let x = volume(&cube, 0.1, 0.0, 0);
    // Sites at the centres of the 10^3 cells of side 0.1: 1000 particles, 1 m^3.
    assert_eq!(x.len(), 1000);
    let d = distance(&cube);
    assert!(x.iter().all(|p| d.signed_distance_from(p, 0).0 < 0.0));
    assert!(x.iter().all(|p| p.amax() < 0.5 && p.amax() > 0.0));
    assert_eq!(pairs_closer_than(&x, 0.1 * (1.0 - 1e-9)), 0);
    // Each site's 6 lattice neighbours: 3 * 10 * 10 * 9 pairs.
    assert_eq!(pairs_closer_than(&x, 0.1 * (1.0 + 1e-9)), 2700);
}

#[test]
fn counts_match_the_volume_within_a_half_spacing_surface_layer() {
    // |N s^3 - V| <= A s / 2, and the row certificates lose no site.
    let cases: Vec<(Mesh, f64)> = vec![
        (box_mesh([0.525, 0.3, 0.2]), 0.1),
        (box_mesh([0.5; 3]), 0.07),
        (icosphere(3, 1.0), 0.1),
        (icosphere(2, 0.3), 0.013),
    ];
    for (mesh, s) in cases {
        let x = volume(&mesh, s, 0.0, 0);
        let (v, a) = (distance(&mesh).volume(), area(&mesh));
        let sampled = x.len() as f64 * s.powi(3);
        assert!(
            (sampled - v).abs() <= 0.5 * a * s,
            "N s^3 = {sampled} m^3 for V = {v} m^3 (A s / 2 = {})",
            0.5 * a * s
        );
        assert_eq!(x, brute_force_volume(&mesh, s, 0.0, 0));
        assert_eq!(pairs_closer_than(&x, s * (1.0 - 1e-9)), 0);
    }
    // A well-resolved sphere is much closer than the bound: within 1 %.
    let ball = icosphere(4, 1.0);
    let n = volume(&ball, 0.05, 0.0, 0).len() as f64;
    let v = distance(&ball).volume();
    assert!((n * 0.05f64.powi(3) / v - 1.0).abs() < 0.01, "{n}");
}

#[test]
fn jitter_moves_sites_within_its_radius_and_is_deterministic() {
    let ball = icosphere(3, 1.0);
    let (s, j) = (0.08, 0.3);
    let x = volume(&ball, s, j, 42);
    assert_eq!(x, volume(&ball, s, j, 42));
    assert_ne!(x, volume(&ball, s, j, 43));
    assert_eq!(x, brute_force_volume(&ball, s, j, 42));
    let d = distance(&ball);
    assert!(x.iter().all(|p| d.signed_distance_from(p, 0).0 < 0.0));
    assert_eq!(pairs_closer_than(&x, (1.0 - 2.0 * j) * s * (1.0 - 1e-9)), 0);
    // Some pair gets well below the spacing: the jitter is real.
    assert!(pairs_closer_than(&x, 0.8 * s) > 0);
    let (lo, hi) = d.bounds();
    let lattice = Lattice::over(lo, hi, s, 1e9).unwrap();
    for p in &x {
        let ijk = (p - lattice.first) / s;
        let site = lattice.site(
            ijk.x.round() as usize,
            ijk.y.round() as usize,
            ijk.z.round() as usize,
        );
        assert!((p - site).norm() <= j * s * (1.0 + 1e-12));
    }
    let count = (x.len() as f64 * s.powi(3) - d.volume()).abs();
    assert!(count <= 0.5 * area(&ball) * s);
}

#[test]
fn samples_do_not_depend_on_the_thread_count() {
    let ball = icosphere(3, 1.0);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                (
                    volume(&ball, 0.05, 0.2, 7),
                    sample_surface(ball.0.clone(), ball.1.clone(), 0.05, 7).unwrap(),
                )
            })
    };
    let one = run(1);
    assert_eq!(one, run(2));
    assert_eq!(one, run(3));
}

/// Checks the surface guarantees: on the surface, at least `s` apart, every point of the
/// surface within `1.38 s` of a particle (random points, brute force), about `0.7 A / s^2`
/// particles.
fn check_surface(mesh: &Mesh, x: &[Vector3<f64>], s: f64) {
    assert_eq!(pairs_closer_than(x, s * (1.0 - 1e-12)), 0);
    let a = area(mesh);
    let density = x.len() as f64 * s * s / a;
    assert!(
        (0.55..0.85).contains(&density),
        "{} particles: N s^2 / A = {density}",
        x.len()
    );
    let m = TriangleMesh::new(mesh.0.clone(), mesh.1.clone()).unwrap();
    let v = m.vertices();
    let mut rng = Rng::new(3);
    let mut worst = 0.0f64;
    for t in m.triangles() {
        for _ in 0..20 {
            let (mut u, mut w) = (0.5 * (rng.uniform() + 1.0), 0.5 * (rng.uniform() + 1.0));
            if u + w > 1.0 {
                (u, w) = (1.0 - u, 1.0 - w);
            }
            let [p0, p1, p2] = t.map(|i| v[i as usize]);
            let q = p0 + (p1 - p0) * u + (p2 - p0) * w;
            let nearest = x
                .iter()
                .map(|p| (p - q).norm())
                .fold(f64::INFINITY, f64::min);
            worst = worst.max(nearest);
        }
    }
    assert!(
        worst <= 1.38 * s,
        "a surface point {worst} m from every particle"
    );
}

#[test]
fn a_sphere_surface_gets_one_layer_at_the_spacing() {
    let ball = icosphere(3, 1.0);
    let s = 0.1;
    let x = sample_surface(ball.0.clone(), ball.1.clone(), s, 1).unwrap();
    check_surface(&ball, &x, s);
    let d = distance(&ball);
    assert!(x
        .iter()
        .all(|p| d.signed_distance_from(p, 0).0.abs() < 1e-12));
    assert_eq!(
        x,
        sample_surface(ball.0.clone(), ball.1.clone(), s, 1).unwrap()
    );
    assert_ne!(
        x,
        sample_surface(ball.0.clone(), ball.1.clone(), s, 2).unwrap()
    );
}

#[test]
fn an_open_square_and_a_cube_surface_are_covered() {
    let grid = TriangleMesh::grid(4, 6, 1.0, 2.0).unwrap();
    let square: Mesh = (
        grid.vertices().iter().map(|v| [v.x, v.y, v.z]).collect(),
        grid.triangles().iter().map(|t| t.map(i64::from)).collect(),
    );
    let s = 0.05;
    let x = sample_surface(square.0.clone(), square.1.clone(), s, 0).unwrap();
    assert!(x
        .iter()
        .all(|p| p.z == 0.0 && (0.0..=1.0).contains(&p.x) && (0.0..=2.0).contains(&p.y)));
    check_surface(&square, &x, s);
    let cube = box_mesh([0.5; 3]);
    let x = sample_surface(cube.0.clone(), cube.1.clone(), 0.1, 0).unwrap();
    check_surface(&cube, &x, 0.1);
}

#[test]
fn bad_input_names_the_culprit() {
    let cube = box_mesh([0.5; 3]);
    let volume_error = |mesh: &Mesh, s: f64, j: f64| {
        sample_volume(mesh.0.clone(), mesh.1.clone(), s, j, 0)
            .unwrap_err()
            .to_string()
    };
    let surface_error = |mesh: &Mesh, s: f64| {
        sample_surface(mesh.0.clone(), mesh.1.clone(), s, 0)
            .unwrap_err()
            .to_string()
    };
    for s in [0.0, -0.1, f64::NAN, f64::INFINITY] {
        assert!(volume_error(&cube, s, 0.0).contains("spacing"));
        assert!(surface_error(&cube, s).contains("spacing"));
    }
    for j in [-0.1, 0.5, f64::NAN] {
        assert!(volume_error(&cube, 0.1, j).contains("jitter"));
    }
    // Open: a face missing.
    let open = (cube.0.clone(), cube.1[..11].to_vec());
    let e = volume_error(&open, 0.1, 0.0);
    assert!(e.contains("edge") || e.contains("closed"), "{e}");
    // Degenerate: a collapsed vertex makes two triangles flat.
    let mut flat = cube.clone();
    flat.0[1] = flat.0[0];
    let e = volume_error(&flat, 0.1, 0.0);
    assert!(!e.is_empty());
    let e = surface_error(&flat, 0.1);
    assert!(e.contains("degenerate") || e.contains("duplicate"), "{e}");
    let e = surface_error(&(vec![[0.0; 3]; 2], vec![[0, 1, 1]]), 0.1);
    assert!(e.contains("3 vertices"), "{e}");
    // Too many: named by count.
    let e = volume_error(&cube, 1e-4, 0.0);
    assert!(e.contains("1.000e12 particles"), "{e}");
    let e = surface_error(&cube, 1e-5);
    assert!(e.contains("candidate points"), "{e}");
    // A needle along a diagonal: 1e4 particles but 2e11 lattice sites in its box.
    let (v, t) = box_mesh([5e3, 0.5, 0.5]);
    let turn = nalgebra::Rotation3::rotation_between(&Vector3::x(), &Vector3::repeat(1.0)).unwrap();
    let needle = (
        v.iter()
            .map(|p| (turn * Vector3::from(*p)).into())
            .collect(),
        t,
    );
    let e = volume_error(&needle, 1.0, 0.0);
    assert!(e.contains("lattice"), "{e}");
}
