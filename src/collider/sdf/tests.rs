//! The grid against exact distances: analytic box and sphere, brute force over triangles.

use std::collections::HashMap;

use nalgebra::Vector3;

use super::*;
use crate::geometry::distance::point_triangle_distance_squared;
use crate::test_rng::Rng;

/// Closed box mesh of half extents `h` at the origin (12 triangles, outward).
pub(crate) fn box_mesh(h: [f64; 3]) -> (Vec<[f64; 3]>, Vec<[i64; 3]>) {
    let v = (0..8)
        .map(|i| {
            let s = |bit: usize| if i & bit != 0 { 1.0 } else { -1.0 };
            [s(1) * h[0], s(2) * h[1], s(4) * h[2]]
        })
        .collect();
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let t = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    (v, t)
}

/// Icosphere of `radius` with `subdivisions` midpoint refinements (20 * 4^k triangles).
pub(crate) fn icosphere(subdivisions: usize, radius: f64) -> (Vec<[f64; 3]>, Vec<[i64; 3]>) {
    let g = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<Vector3<f64>> = [
        [-1.0, g, 0.0],
        [1.0, g, 0.0],
        [-1.0, -g, 0.0],
        [1.0, -g, 0.0],
        [0.0, -1.0, g],
        [0.0, 1.0, g],
        [0.0, -1.0, -g],
        [0.0, 1.0, -g],
        [g, 0.0, -1.0],
        [g, 0.0, 1.0],
        [-g, 0.0, -1.0],
        [-g, 0.0, 1.0],
    ]
    .iter()
    .map(|p| Vector3::from(*p).normalize())
    .collect();
    let mut t: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut mid: HashMap<(usize, usize), usize> = HashMap::new();
        let mut midpoint = |a: usize, b: usize, v: &mut Vec<Vector3<f64>>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                v.push(((v[a] + v[b]) / 2.0).normalize());
                v.len() - 1
            })
        };
        t = t
            .iter()
            .flat_map(|&[a, b, c]| {
                let ab = midpoint(a, b, &mut v);
                let bc = midpoint(b, c, &mut v);
                let ca = midpoint(c, a, &mut v);
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    (
        v.iter().map(|p| (p * radius).into()).collect(),
        t.iter().map(|f| f.map(|i| i as i64)).collect(),
    )
}

fn random_points(n: usize, seed: u64, half: f64) -> Vec<Vector3<f64>> {
    let mut rng = Rng::new(seed);
    let mut next = move || rng.uniform();
    (0..n)
        .map(|_| Vector3::new(next(), next(), next()) * half)
        .collect()
}

fn box_distance(h: &Vector3<f64>, x: &Vector3<f64>) -> f64 {
    let q = x.abs() - h;
    q.map(|c| c.max(0.0)).norm() + q.max().min(0.0)
}

/// Box mesh: every node holds the exact analytic box distance, sign included (1e-12 m);
/// the interpolated field is within 0.5 h of it within 3 h of the surface and within
/// sqrt(3) h everywhere in the grid (measured: 0.37 h for both, largest at the edges).
#[test]
fn box_mesh_field_matches_the_analytic_box() {
    let h = Vector3::new(0.4, 0.3, 0.2);
    let (v, t) = box_mesh(h.into());
    let grid = SdfGrid::build(v, t, 32, None).unwrap();
    let cell = grid.cell_size();
    assert!((cell - 0.8 / 32.0).abs() < 1e-15);
    let [nx, ny, _] = grid.dims();
    for (index, value) in grid.values.iter().enumerate() {
        let (i, j, k) = (index % nx, (index / nx) % ny, index / (nx * ny));
        let x = grid.origin + Vector3::new(i as f64, j as f64, k as f64) * cell;
        assert!((value - box_distance(&h, &x)).abs() < 1e-12, "node {x}");
    }
    let (mut near, mut far) = (0.0f64, 0.0f64);
    let (lo, hi) = grid.bounds();
    for x in random_points(20000, 3, 0.55) {
        if x != x.sup(&lo).inf(&hi) {
            continue;
        }
        let exact = box_distance(&h, &x);
        let err = (grid.signed_distance(&x) - exact).abs();
        if exact.abs() < 3.0 * cell {
            near = near.max(err);
        }
        far = far.max(err);
    }
    println!(
        "box mesh, h = {cell} m: max error {near:e} m within 3 h of the surface, {far:e} m overall"
    );
    assert!(near < 0.5 * cell, "{near} vs h {cell}");
    assert!(far < 3f64.sqrt() * cell, "{far} vs h {cell}");
}

/// Icosphere (1280 triangles, radius 0.5): nodes match the brute-force exact mesh distance
/// (1e-12 m) and are negative exactly inside; the interpolated field is within `h^2 / r` of the
/// exact mesh distance near the surface (measured: 0.95 h^2 / r), and within that plus the
/// chord error of the analytic sphere.
#[test]
fn icosphere_field_matches_exact_and_analytic_distances() {
    let r = 0.5;
    let (v, t) = icosphere(3, r);
    let corners: Vec<[Vector3<f64>; 3]> = t
        .iter()
        .map(|f| f.map(|i| Vector3::from(v[i as usize])))
        .collect();
    let exact = |x: &Vector3<f64>| -> f64 {
        corners
            .iter()
            .map(|[a, b, c]| point_triangle_distance_squared(x, a, b, c))
            .fold(f64::INFINITY, f64::min)
            .sqrt()
    };
    let grid = SdfGrid::build(v, t, 40, None).unwrap();
    let cell = grid.cell_size();
    let [nx, ny, _] = grid.dims();
    for index in (0..grid.values.len()).step_by(37) {
        let (i, j, k) = (index % nx, (index / nx) % ny, index / (nx * ny));
        let x = grid.origin + Vector3::new(i as f64, j as f64, k as f64) * cell;
        let e = exact(&x);
        let value = grid.values[index];
        assert!((value.abs() - e).abs() < 1e-12, "node {x}");
        // The mesh lies within the sphere, between radius 0.98 r (the flattest face) and r.
        if x.norm() < 0.97 * r {
            assert!(value < 0.0, "node {x} inside");
        } else if x.norm() > r {
            assert!(value > 0.0, "node {x} outside");
        }
    }
    // Chord error: the deepest point of a face below the sphere.
    let chord = r - corners
        .iter()
        .map(|[a, b, c]| ((a + b + c) / 3.0).norm())
        .fold(f64::INFINITY, f64::min);
    let (mut to_mesh, mut to_sphere) = (0.0f64, 0.0f64);
    for x in random_points(3000, 5, 0.6) {
        if (x.norm() - r).abs() > 3.0 * cell {
            continue;
        }
        let phi = grid.signed_distance(&x);
        to_mesh = to_mesh.max((phi.abs() - exact(&x)).abs());
        to_sphere = to_sphere.max((phi - (x.norm() - r)).abs());
    }
    println!(
        "icosphere, h = {cell:e} m: max error {to_mesh:e} m to the mesh, {to_sphere:e} m to the sphere (chord {chord:e} m)"
    );
    assert!(to_mesh < 1.5 * cell * cell / r, "{to_mesh}");
    assert!(to_sphere < chord + 1.5 * cell * cell / r, "{to_sphere}");
}

/// The normal is the normalised gradient of the interpolated field: central differences of
/// `phi` agree with `|grad phi| n` (1e-6), inside and outside the grid box.
#[test]
fn normal_is_the_gradient_of_the_interpolated_field() {
    let (v, t) = icosphere(2, 0.5);
    let grid = SdfGrid::build(v, t, 20, None).unwrap();
    let step = 1e-7;
    for x in random_points(2000, 9, 1.2) {
        let fd = Vector3::from_fn(|k, _| {
            let e = Vector3::ith(k, step);
            (grid.signed_distance(&(x + e)) - grid.signed_distance(&(x - e))) / (2.0 * step)
        });
        let (_, g) = grid.value_and_gradient(&x);
        assert!((fd - g).norm() < 1e-6, "{x}: {fd} vs {g}");
        assert!((grid.normal(&x) - g / g.norm()).norm() < 1e-12);
    }
}

/// Outside the grid box the field is `|x - p| + phi(p)`: continuous at the box, growing one
/// for one going straight out, and never below the exact distance.
#[test]
fn field_continues_outside_the_grid() {
    let h = Vector3::new(0.4, 0.3, 0.2);
    let (v, t) = box_mesh(h.into());
    let grid = SdfGrid::build(v, t, 16, Some(0.1)).unwrap();
    let (_, hi) = grid.bounds();
    let on_box = Vector3::new(0.1, 0.05, hi.z);
    let inside = grid.signed_distance(&(on_box - Vector3::z() * 1e-9));
    let out = grid.signed_distance(&(on_box + Vector3::z() * 2.0));
    assert!((grid.signed_distance(&on_box) - inside).abs() < 1e-8);
    assert!((out - grid.signed_distance(&on_box) - 2.0).abs() < 1e-12);
    for x in random_points(500, 4, 3.0) {
        assert!(grid.signed_distance(&x) >= box_distance(&h, &x) - 1e-12);
    }
}

/// Projection lands at the margin (within 1e-9 h above it) from inside and near the surface.
#[test]
fn projection_reaches_the_margin() {
    let (v, t) = icosphere(2, 0.5);
    let grid = SdfGrid::build(v, t, 24, None).unwrap();
    for x in random_points(500, 21, 0.6) {
        let p = grid.project(x, 0.01);
        let d = grid.signed_distance(&p);
        if grid.signed_distance(&x) < 0.01 {
            assert!(d >= 0.01 && d <= 0.01 + 1e-9 * grid.cell_size(), "{x}: {d}");
        } else {
            assert_eq!(p, x);
        }
    }
}

/// A mesh given inside out gives the same field; open, inconsistently oriented, flat and
/// badly sized inputs are refused with the offending edge, triangle or value named.
#[test]
fn orientation_is_fixed_and_bad_meshes_are_named() {
    let (v, t) = box_mesh([0.4, 0.3, 0.2]);
    let reversed: Vec<[i64; 3]> = t.iter().map(|f| [f[0], f[2], f[1]]).collect();
    let a = SdfGrid::build(v.clone(), t.clone(), 8, None).unwrap();
    let b = SdfGrid::build(v.clone(), reversed, 8, None).unwrap();
    assert_eq!(a.values, b.values);
    let err = |v: Vec<[f64; 3]>, t: Vec<[i64; 3]>, res: usize| {
        SdfGrid::build(v, t, res, None).unwrap_err().to_string()
    };
    let open: Vec<[i64; 3]> = t[..11].to_vec();
    assert!(err(v.clone(), open, 8).contains("not closed"));
    let mut flipped_one = t.clone();
    flipped_one[3] = [t[3][0], t[3][2], t[3][1]];
    assert!(err(v.clone(), flipped_one, 8).contains("same direction"));
    let mut out_of_range = t.clone();
    out_of_range[5][1] = 8;
    assert!(err(v.clone(), out_of_range, 8).contains("triangle 5"));
    let mut nan = v.clone();
    nan[2][1] = f64::NAN;
    assert!(err(nan, t.clone(), 8).contains("vertex 2"));
    assert!(err(v.clone(), t.clone(), 1).contains("resolution"));
    assert!(err(v.clone(), t.clone(), 100_000).contains("nodes"));
    // A flat closed mesh: a square's two sides, split along different diagonals.
    let flat_v = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
    ];
    let flat_t = vec![[0, 1, 3], [0, 3, 2], [0, 2, 1], [1, 2, 3]];
    assert!(err(flat_v, flat_t, 8).contains("no volume"));
}

/// Build cost: a 20480-triangle sphere on a grid of about 100K nodes; the nodes agree with
/// brute force on a sample. Prints the build time.
#[test]
fn large_mesh_builds_fast_and_exactly() {
    let (v, t) = icosphere(5, 0.5);
    let started = std::time::Instant::now();
    let grid = SdfGrid::build(v.clone(), t.clone(), 38, None).unwrap();
    let seconds = started.elapsed().as_secs_f64();
    let nodes = grid.values.len();
    println!(
        "{} triangles, {nodes} nodes {:?}: built in {seconds:.3} s on {} threads",
        t.len(),
        grid.dims(),
        rayon::current_num_threads()
    );
    assert!(nodes > 90_000);
    let corners: Vec<[Vector3<f64>; 3]> = t
        .iter()
        .map(|f| f.map(|i| Vector3::from(v[i as usize])))
        .collect();
    let [nx, ny, _] = grid.dims();
    for index in (0..nodes).step_by(997) {
        let (i, j, k) = (index % nx, (index / nx) % ny, index / (nx * ny));
        let x = grid.origin + Vector3::new(i as f64, j as f64, k as f64) * grid.cell_size();
        let e = corners
            .iter()
            .map(|[a, b, c]| point_triangle_distance_squared(&x, a, b, c))
            .fold(f64::INFINITY, f64::min)
            .sqrt();
        assert!((grid.values[index].abs() - e).abs() < 1e-12);
    }
}
