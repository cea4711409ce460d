//! The particle-triangle projection on hand-made pairs: a violated pair is closed, its
//! reactions are equal and opposite in the global move's metric (round-off), each particle
//! keeps the side it started on, a particle over a crease is not pushed twice, and the result
//! does not depend on the thread count.

use nalgebra::Vector3;

use crate::geometry::vertex_index::index_by_vertex;
use crate::symmetric::SymmetricMatrix3;
use crate::test_rng::Rng;

use super::pairs::{Pair, PairList};
use super::prism::over_triangle;
use super::projection::{pass, Metric, Scratch};

/// The pairs `(particle, triangle)` with their sides, laid out as [`PairList::find`] does.
fn list(
    pairs: &[(u32, u32, i8)],
    particles: usize,
    vertices: usize,
    triangles: &[[u32; 3]],
) -> PairList {
    let mut list = PairList::default();
    list.pairs = pairs
        .iter()
        .map(|&(particle, triangle, side)| Pair {
            particle,
            triangle,
            side,
        })
        .collect();
    list.particle_start = (0..=particles as u32)
        .map(|i| pairs.iter().filter(|p| p.0 < i).count() as u32)
        .collect();
    index_by_vertex(
        list.pairs.iter().map(|p| triangles[p.triangle as usize]),
        vertices,
        &mut list.vertex_start,
        &mut list.vertex_entries,
    );
    list
}

struct Scene {
    triangles: Vec<[u32; 3]>,
    tau: Vec<f64>,
    radius: Vec<f64>,
    particle_inverse: Vec<f64>,
    vertex_inverse: Vec<SymmetricMatrix3<f64>>,
    particles: Vec<Vector3<f64>>,
    vertices: Vec<Vector3<f64>>,
}

impl Scene {
    /// The unit right triangle in the plane z = 0 (normal +z), free vertices of inverse mass
    /// `1 / vertex_mass`, and one particle of inverse mass 1 at `x`; radius 0.1, tau 0.02.
    fn one(x: Vector3<f64>, vertex_mass: f64) -> Self {
        Self {
            triangles: vec![[0, 1, 2]],
            tau: vec![0.02],
            radius: vec![0.1],
            particle_inverse: vec![1.0],
            vertex_inverse: vec![
                SymmetricMatrix3::from_diagonal(&Vector3::repeat(
                    1.0 / vertex_mass
                ));
                3
            ],
            particles: vec![x],
            vertices: vec![
                Vector3::new(0.0, 0.0, 0.0),
                Vector3::new(1.0, 0.0, 0.0),
                Vector3::new(0.0, 1.0, 0.0),
            ],
        }
    }

    /// One pass over `list`; the moves.
    fn pass(&mut self, list: &mut PairList) -> (f64, Vec<Vector3<f64>>, Vec<Vector3<f64>>) {
        let metric = Metric {
            triangles: &self.triangles,
            tau: &self.tau,
            radius: &self.radius,
            particle_inverse: &self.particle_inverse,
            vertex_inverse: &self.vertex_inverse,
        };
        let mut pm = vec![Vector3::zeros(); self.particles.len()];
        let mut vm = vec![Vector3::zeros(); self.vertices.len()];
        let worst = pass(
            list,
            &metric,
            &mut Scratch::default(),
            &mut self.particles,
            &mut self.vertices,
            &mut pm,
            &mut vm,
        );
        (worst, pm, vm)
    }

    /// `sum D dx` over every point (kg m): zero when the reactions balance.
    fn net_reaction(&self, pm: &[Vector3<f64>], vm: &[Vector3<f64>]) -> Vector3<f64> {
        let mut sum = Vector3::zeros();
        for (i, m) in pm.iter().enumerate() {
            sum += m / self.particle_inverse[i];
        }
        for (v, m) in vm.iter().enumerate() {
            let d = self.vertex_inverse[v].try_inverse().expect("free vertices");
            sum += d.mul_vector(m);
        }
        sum
    }

    /// The height of particle `i` above triangle `t`'s plane (m).
    fn height(&self, i: usize, t: usize) -> f64 {
        let [a, b, c] = self.triangles[t].map(|v| self.vertices[v as usize]);
        over_triangle(&self.particles[i], &a, &b, &c)
            .expect("over the triangle")
            .height
    }
}

/// A particle 0.05 m above the centroid, gap 0.12 m: one pass lifts it to the gap exactly
/// (the free triangle translates along its normal, each vertex taking a third), the particle
/// moving `1 / (1 + 3 (1/3)^2 / 2)` of the violation, and the net reaction is zero to
/// round-off.
#[test]
fn a_violated_pair_is_closed_with_balanced_reactions() {
    let third = 1.0 / 3.0;
    let mut scene = Scene::one(Vector3::new(third, third, 0.05), 2.0);
    let mut list = list(&[(0, 0, 1)], 1, 3, &scene.triangles);
    let (worst, pm, vm) = scene.pass(&mut list);
    assert!((worst - 0.07 / 0.12).abs() < 1e-12, "{worst}");
    assert!(
        (scene.height(0, 0) - 0.12).abs() < 1e-12,
        "{}",
        scene.height(0, 0)
    );
    assert!(scene.net_reaction(&pm, &vm).norm() < 1e-15);
    assert!((pm[0].z - 0.06).abs() < 1e-12, "{}", pm[0].z);
    assert!(vm.iter().all(|m| (m.z + 0.01).abs() < 1e-12), "{vm:?}");
    let (worst, pm, _) = scene.pass(&mut list);
    assert!(worst < 1e-12 && pm[0].norm() == 0.0);
}

/// Random triangles, particles and symmetric positive definite metrics: after a pass the
/// reactions `D dx` of every point sum to zero to round-off (momentum is not created).
#[test]
fn the_reactions_sum_to_zero_for_random_metrics() {
    let mut rng = Rng::new(11);
    for _ in 0..20 {
        let mut scene = Scene::one(Vector3::zeros(), 1.0);
        scene.vertices = (0..6).map(|_| rng.vector()).collect();
        scene.triangles = vec![[0, 1, 2], [2, 3, 4], [1, 4, 5]];
        scene.tau = vec![0.3, 0.2, 0.25];
        scene.vertex_inverse = (0..6)
            .map(|_| {
                let (d, u) = (rng.vector(), rng.vector() * 0.3);
                let spd = SymmetricMatrix3 {
                    diagonal: [d.x + 1.0, d.y + 1.0, d.z + 1.0],
                    upper: [u.x, u.y, u.z],
                };
                spd.try_inverse().expect("diagonally dominant")
            })
            .collect();
        scene.particles = (0..4).map(|_| rng.vector()).collect();
        scene.radius = vec![0.3; 4];
        scene.particle_inverse = (0..4).map(|_| 0.5 + rng.uniform()).collect();
        let pairs: Vec<(u32, u32, i8)> = (0..4u32)
            .flat_map(|p| (0..3u32).map(move |t| (p, t, 0)))
            .collect();
        let mut list = list(&pairs, 4, 6, &scene.triangles);
        let (_, pm, vm) = scene.pass(&mut list);
        let scale: f64 = pm.iter().chain(&vm).map(|m| m.norm()).sum();
        assert!(scene.net_reaction(&pm, &vm).norm() <= 1e-13 * scale.max(1e-300));
    }
}

/// A particle that started above the plane (side +1) and is now below it is lifted to the
/// gap above; one that started below (side -1) is pushed to the gap below.
#[test]
fn each_particle_keeps_the_side_it_started_on() {
    for (side, z) in [(1i8, -0.04), (-1, 0.04), (1, -0.3)] {
        let mut scene = Scene::one(Vector3::new(0.2, 0.3, z), 1.0);
        scene.vertex_inverse = vec![SymmetricMatrix3::zeros(); 3];
        let mut list = list(&[(0, 0, side)], 1, 3, &scene.triangles);
        scene.pass(&mut list);
        let height = scene.height(0, 0);
        assert!(
            (height - f64::from(side) * 0.12).abs() < 1e-12,
            "{side} {z}: {height}"
        );
    }
}

/// A particle over the shared edge of two coplanar fixed triangles is in two violated pairs:
/// mass splitting lifts it to the gap in one pass, not twice as far.
#[test]
fn a_particle_over_a_crease_is_not_pushed_twice() {
    let mut scene = Scene::one(Vector3::new(0.5, 0.5, 0.02), 1.0);
    scene.vertices.push(Vector3::new(1.0, 1.0, 0.0));
    scene.triangles.push([1, 3, 2]);
    scene.tau.push(0.02);
    scene.vertex_inverse = vec![SymmetricMatrix3::zeros(); 4];
    let mut list = list(&[(0, 0, 1), (0, 1, 1)], 1, 4, &scene.triangles);
    scene.pass(&mut list);
    assert!(
        (scene.particles[0].z - 0.12).abs() < 1e-12,
        "{}",
        scene.particles[0].z
    );
}

/// A particle beside the triangle (its projection outside the prism) is left alone, and its
/// pair takes a side only once the particle is over the triangle.
#[test]
fn a_particle_beside_the_triangle_is_left_alone() {
    let mut scene = Scene::one(Vector3::new(1.5, 1.5, 0.0), 1.0);
    let mut list = list(&[(0, 0, 0)], 1, 3, &scene.triangles);
    let (worst, pm, vm) = scene.pass(&mut list);
    assert_eq!(worst, 0.0);
    assert!(pm[0] == Vector3::zeros() && vm.iter().all(|m| *m == Vector3::zeros()));
    assert_eq!(list.pairs[0].side, 0);
    scene.particles[0] = Vector3::new(0.2, 0.2, -0.5);
    scene.pass(&mut list);
    assert_eq!(list.pairs[0].side, -1);
}

/// The same pass on one and on two threads gives the same bits.
#[test]
fn a_pass_is_the_same_on_any_thread_count() {
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| {
            let mut rng = Rng::new(5);
            let mut scene = Scene::one(Vector3::zeros(), 1.0);
            let (nx, n) = (20u32, 400usize);
            scene.vertices = (0..=nx)
                .flat_map(|i| {
                    (0..=nx).map(move |j| Vector3::new(f64::from(i), f64::from(j), 0.0) * 0.05)
                })
                .collect();
            scene.triangles = (0..nx)
                .flat_map(|i| {
                    (0..nx).flat_map(move |j| {
                        let v = i * (nx + 1) + j;
                        [[v, v + nx + 1, v + 1], [v + 1, v + nx + 1, v + nx + 2]]
                    })
                })
                .collect();
            let vertices = scene.vertices.len();
            scene.tau = vec![0.002; scene.triangles.len()];
            scene.vertex_inverse =
                vec![SymmetricMatrix3::from_diagonal(&Vector3::repeat(3.0)); vertices];
            scene.particles = (0..n)
                .map(|_| Vector3::new(rng.uniform(), rng.uniform(), rng.uniform() * 0.04 - 0.01))
                .collect();
            scene.radius = vec![0.02; n];
            scene.particle_inverse = vec![10.0; n];
            let pairs: Vec<(u32, u32, i8)> = (0..n as u32)
                .flat_map(|p| (0..scene.triangles.len() as u32).map(move |t| (p, t, 1)))
                .filter(|&(p, t, _)| {
                    let [a, b, c] = scene.triangles[t as usize].map(|v| scene.vertices[v as usize]);
                    over_triangle(&scene.particles[p as usize], &a, &b, &c).is_some()
                })
                .collect();
            let mut list = list(&pairs, n, vertices, &scene.triangles);
            for _ in 0..5 {
                scene.pass(&mut list);
            }
            (scene.particles, scene.vertices)
        })
    };
    assert!(run(1) == run(2));
}
