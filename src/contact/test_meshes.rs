//! Meshes and brute-force searches that the contact tests share.

use nalgebra::Vector3;

use super::broad_phase::ContactMesh;
use super::primitive_pairs::{close_primitive_pairs, Pair};
use crate::geometry::distance::tests::Rng;

/// Brute force: every triangle pair of `mesh` that may touch, and every primitive pair
/// they hold (whatever their distance at `positions`).
pub(super) fn brute_force_pairs(
    mesh: &ContactMesh,
    positions: &[Vector3<f64>],
) -> (Vec<(u32, u32)>, Vec<Pair>) {
    let nt = mesh.triangles.len();
    let all: Vec<(u32, u32)> = (0..nt)
        .flat_map(|a| (a + 1..nt).map(move |b| (a, b)))
        .filter(|&(a, b)| mesh.may_touch(a, b))
        .map(|(a, b)| (a as u32, b as u32))
        .collect();
    let mut every = Vec::new();
    close_primitive_pairs(
        mesh,
        None,
        &all,
        positions,
        |_| f64::INFINITY,
        |_, _| true,
        &mut every,
    );
    let mut every: Vec<Pair> = every.into_iter().flatten().map(|(p, _)| p).collect();
    every.sort_unstable();
    every.dedup();
    (all, every)
}

/// The triangles of a grid of `side x side` vertices (numbered row by row), two per quad.
pub(super) fn grid_triangles(side: u32) -> Vec<[u32; 3]> {
    let quads = (0..side - 1).flat_map(|j| (0..side - 1).map(move |i| j * side + i));
    quads
        .flat_map(|v| [[v, v + 1, v + side], [v + 1, v + side + 1, v + side]])
        .collect()
}

/// The triangles of two copies of a mesh of `n` vertices and triangles `triangles` (the
/// second's vertices numbered after the first's), and the body of each (0 and 1).
pub(super) fn two_copies(triangles: &[[u32; 3]], n: u32) -> (Vec<[u32; 3]>, Vec<u32>) {
    let both: Vec<[u32; 3]> = triangles
        .iter()
        .copied()
        .chain(triangles.iter().map(|t| t.map(|v| v + n)))
        .collect();
    let body = (0..both.len())
        .map(|t| u32::from(t >= triangles.len()))
        .collect();
    (both, body)
}

/// A rolled-up grid of `n x n` vertices (a spiral of one and a half turns, its layers
/// `gap` (m) apart, jittered by up to 3 mm) and its triangles.
pub(super) fn spiral(n: u32, gap: f64, rng: &mut Rng) -> (Vec<Vector3<f64>>, Vec<[u32; 3]>) {
    let mut x = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let theta = 3.0 * std::f64::consts::PI * f64::from(i) / f64::from(n - 1);
            let r = 0.1 + gap * theta / (2.0 * std::f64::consts::PI);
            let (u, v) = (r * theta.cos(), r * theta.sin());
            x.push(Vector3::new(u, f64::from(j) * 0.04, v) + rng.vector() * 0.003);
        }
    }
    let mut triangles = Vec::new();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let v = j * n + i;
            triangles.push([v, v + 1, v + n + 1]);
            triangles.push([v, v + n + 1, v + n]);
        }
    }
    (x, triangles)
}
