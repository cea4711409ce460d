//! The contact local step: Algorithm 2 of Lu et al. 2023 (section 6).
//!
//! Given the last intersection-free positions `z^{k-1}` ("safe") and the positions `y^k` after
//! a global step, it looks for `z` near `y^k` that keeps every pair of primitives apart,
//! minimising eq. 47, `sum_i |z_i - y_i^k|^2 / 2 + mu sum_c B(f(d_c) - xi)`, by gradient descent:
//!
//! 1. broad phase: candidate triangle pairs over the motion `z^{k-1} -> y^k`, expanded into
//!    6 point-triangle and 9 edge-edge primitive pairs per triangle pair (deduplicated);
//! 2. per iteration `m`: additive CCD of every primitive pair between `z^{k-1}` and `z^m`
//!    (lines 4-12); a vertex whose smallest time of impact `t_i` is in `(threshold, 1)` is
//!    clamped to `z^{k-1} + t_i (z^m - z^{k-1})` (lines 13-18);
//! 3. distances and closest-point weights of the pairs (lines 19-23), and the descent
//!    direction of eq. 49, `g_i = -mu sum_c alpha_c^i B'(f(d_c) - xi) n_c + y_i^k - z_i`, where
//!    `alpha_c^i` is vertex `i`'s barycentric weight in pair `c` and `n_c` the unit separation;
//!    following the paper, the barrier slope is taken at the rescaled gap of eq. 51 so that it
//!    stays bounded, `|B'| <= |B'(eps xi)|`;
//! 4. the step `lambda = min(1, eps xi / (mu alpha_0 ceil|B'| + D))` of eq. 53 with `alpha_0`
//!    the largest `sum_c alpha_c^i` and `D` the largest `|y_i^k - z_i|` of this iteration,
//!    which keeps every move below `eps xi`; stop when the largest move is below
//!    [`STOP_FRACTION`] `eps xi` or after `max_iters` iterations.
//!
//! A final guarantee pass (not in the paper, which leaves vertices with a small time of impact
//! unclamped): additive CCD from `z^{k-1}` to `z` once more, with the pair's separation floor
//! `min(eps xi, 0.9 d(z^{k-1}))`, clamping every vertex of a colliding pair to its time of
//! impact (repeated until no pair collides; after [`CLAMP_PASSES`] passes the remaining
//! vertices fall back to `z^{k-1}`). So if `z^{k-1}` is free of intersections, so is `z`, and
//! pairs that were `eps xi` apart stay so.

use std::time::Instant;

use nalgebra::Vector3;
use rayon::prelude::*;

use super::barrier::Barrier;
use super::broad_phase::{candidate_pairs, ContactMesh};
use super::ccd::{edge_edge_ccd, point_triangle_ccd, AdditiveCcd};
use super::distance::{edge_edge_closest, point_triangle_closest, Closest};
use crate::error::{check_param, invalid, Result};

/// Contact parameters (SI units). Defaults follow Table 1 of the paper (cloths over a ball):
/// `xi = 1.5 mm`, `d_hat = 4 xi`, `eps = 0.1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactParams {
    /// Contact thickness `xi` (m): mid-surfaces of two primitives stay at least `xi` apart in
    /// the barrier's view, and never closer than `eps xi`.
    pub thickness: f64,
    /// Barrier range `d_hat` (m), measured on the gap `f(d) - xi`.
    pub d_hat: f64,
    /// Minimal separation multiplier `eps` (eq. 51): also caps every descent move at `eps xi`.
    pub eps: f64,
    /// Barrier weight `mu` of eq. 47 (dimensionless: the barrier is in m^2 like the proximal
    /// term). Not in Table 1; 1 balances the two terms of eq. 47 at gaps of about `d_hat / 2`.
    pub weight: f64,
    /// Cap on descent iterations per local step.
    pub max_iters: usize,
    /// Times of impact at or below this are not clamped inside the descent (avoids the
    /// sticking of clamping at tiny times; Algorithm 2, line 15). In `[0, 1)`.
    pub toi_threshold: f64,
    /// The additive CCD (`s = 0.1`, `t_c = 0.95` as in the paper).
    pub ccd: AdditiveCcd,
}

impl Default for ContactParams {
    fn default() -> Self {
        let thickness = 1.5e-3;
        Self {
            thickness,
            d_hat: 4.0 * thickness,
            eps: 0.1,
            weight: 1.0,
            max_iters: 32,
            toi_threshold: 0.1,
            ccd: AdditiveCcd::default(),
        }
    }
}

impl ContactParams {
    /// Checks every parameter, naming the first bad one.
    pub fn validate(&self) -> Result<()> {
        check_param(
            "thickness",
            self.thickness,
            |v| v > 0.0,
            "a finite thickness > 0 m",
        )?;
        check_param("d_hat", self.d_hat, |v| v > 0.0, "a finite range > 0 m")?;
        check_param("eps", self.eps, |v| v > 0.0 && v < 1.0, "in (0, 1)")?;
        check_param("weight", self.weight, |v| v > 0.0, "a finite weight > 0")?;
        check_param(
            "toi_threshold",
            self.toi_threshold,
            |v| (0.0..1.0).contains(&v),
            "in [0, 1)",
        )?;
        check_param("ccd s", self.ccd.s, |v| v > 0.0 && v < 1.0, "in (0, 1)")?;
        check_param(
            "ccd t_c",
            self.ccd.t_c,
            |v| v > 0.0 && v <= 1.0,
            "in (0, 1]",
        )?;
        if self.max_iters < 1 {
            return Err(invalid!(
                "contact max_iters must be >= 1, got {}",
                self.max_iters
            ));
        }
        Ok(())
    }

    fn barrier(&self) -> Barrier {
        Barrier {
            thickness: self.thickness,
            d_hat: self.d_hat,
            eps: self.eps,
        }
    }
}

/// A local step stops once its largest move is below this fraction of `eps xi`.
pub const STOP_FRACTION: f64 = 1e-2;

/// Passes of the final clamp before the remaining colliding vertices fall back to safety.
pub const CLAMP_PASSES: usize = 16;

/// What one local step did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ContactStats {
    /// Candidate triangle pairs from the broad phase.
    pub candidate_pairs: usize,
    /// Primitive pairs within the barrier's reach at the end.
    pub active_pairs: usize,
    /// Descent iterations.
    pub iterations: usize,
    /// Vertices clamped by the final guarantee pass.
    pub clamped: usize,
    /// Milliseconds in the broad phase, the CCD and the descent (distances and updates).
    pub broad_phase_ms: f64,
    pub ccd_ms: f64,
    pub descent_ms: f64,
}

impl ContactStats {
    /// Sums the counts and times of two local steps (active pairs: the later one's).
    pub fn accumulate(&mut self, other: &ContactStats) {
        self.candidate_pairs = self.candidate_pairs.max(other.candidate_pairs);
        self.active_pairs = other.active_pairs;
        self.iterations += other.iterations;
        self.clamped += other.clamped;
        self.broad_phase_ms += other.broad_phase_ms;
        self.ccd_ms += other.ccd_ms;
        self.descent_ms += other.descent_ms;
    }
}

/// A primitive pair: point-triangle `[p, t0, t1, t2]` or edge-edge `[a0, a1, b0, b1]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Pair {
    edge_edge: bool,
    v: [u32; 4],
}

impl Pair {
    fn points(&self, x: &[Vector3<f64>]) -> [Vector3<f64>; 4] {
        self.v.map(|i| x[i as usize])
    }

    fn closest(&self, x: &[Vector3<f64>]) -> Closest {
        let p = self.points(x);
        if self.edge_edge {
            edge_edge_closest(&p[0], &p[1], &p[2], &p[3])
        } else {
            point_triangle_closest(&p[0], &p[1], &p[2], &p[3])
        }
    }

    fn ccd(
        &self,
        start: &[Vector3<f64>],
        end: &[Vector3<f64>],
        min: f64,
        ccd: &AdditiveCcd,
    ) -> Option<f64> {
        let (a, b) = (self.points(start), self.points(end));
        if self.edge_edge {
            edge_edge_ccd(&a, &b, min, ccd)
        } else {
            point_triangle_ccd(&a, &b, min, ccd)
        }
    }
}

/// The 6 point-triangle and 9 edge-edge pairs of the candidate triangle pairs, deduplicated
/// (an edge or a vertex belongs to several triangles).
fn primitive_pairs(triangles: &[[u32; 3]], candidates: &[(u32, u32)]) -> Vec<Pair> {
    let edge = |t: &[u32; 3], k: usize| {
        let (a, b) = (t[k], t[(k + 1) % 3]);
        [a.min(b), a.max(b)]
    };
    let mut pairs: Vec<Pair> = candidates
        .par_iter()
        .flat_map_iter(|&(i, j)| {
            let (ti, tj) = (&triangles[i as usize], &triangles[j as usize]);
            let mut out = Vec::with_capacity(15);
            for (a, b) in [(ti, tj), (tj, ti)] {
                for &p in a {
                    out.push(Pair {
                        edge_edge: false,
                        v: [p, b[0], b[1], b[2]],
                    });
                }
            }
            for ki in 0..3 {
                for kj in 0..3 {
                    let (ea, eb) = (edge(ti, ki), edge(tj, kj));
                    let (ea, eb) = if ea <= eb { (ea, eb) } else { (eb, ea) };
                    out.push(Pair {
                        edge_edge: true,
                        v: [ea[0], ea[1], eb[0], eb[1]],
                    });
                }
            }
            out
        })
        .collect();
    pairs.par_sort_unstable();
    pairs.dedup();
    pairs
}

fn millis(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

/// Smallest time of impact per vertex over the pairs that collide (1 where none).
fn vertex_toi(pairs: &[Pair], toi: &[Option<f64>], n: usize) -> Vec<f64> {
    let mut t = vec![1.0f64; n];
    for (pair, hit) in pairs.iter().zip(toi) {
        if let Some(time) = hit {
            for &v in &pair.v {
                t[v as usize] = t[v as usize].min(*time);
            }
        }
    }
    t
}

/// Runs the local step: `positions` holds `y^k` on entry and `z` on return; `safe` is
/// `z^{k-1}`, free of intersections; `fixed` vertices are never moved. `keep_out(i, z_i)`
/// projects a vertex out of the colliders after every descent move, so the barrier cannot
/// push a membrane into a collider (the final clamp then only interpolates between positions
/// outside them).
pub fn project(
    safe: &[Vector3<f64>],
    positions: &mut [Vector3<f64>],
    fixed: &[bool],
    mesh: &ContactMesh,
    params: &ContactParams,
    keep_out: &(dyn Fn(usize, &mut Vector3<f64>) + Sync),
) -> ContactStats {
    let mut stats = ContactStats::default();
    let barrier = params.barrier();
    let (xi, eps, mu) = (params.thickness, params.eps, params.weight);
    let reach = barrier.reach();
    let n = positions.len();

    let t = Instant::now();
    let candidates = candidate_pairs(safe, positions, mesh, reach);
    let mut pairs = primitive_pairs(mesh.triangles, &candidates);
    stats.candidate_pairs = candidates.len();
    stats.broad_phase_ms += millis(t);
    if pairs.is_empty() {
        return stats;
    }

    let target: Vec<Vector3<f64>> = positions.to_vec();
    let z = positions;
    let bound = barrier.derivative_bound();
    let mut drift = vec![0.0f64; n];
    let mut force = vec![Vector3::zeros(); n];
    let mut alpha = vec![0.0f64; n];
    // Vertices moved since the last CCD: a pair none of whose vertices moved keeps its time.
    let mut changed = vec![true; n];
    let mut toi: Vec<Option<f64>> = vec![None; pairs.len()];
    // After the first iteration a vertex moves at most `eps xi` per iteration (eq. 53), so
    // only pairs that were within `(1 + 4 eps) xi` can reach `xi`: the others skip the CCD.
    let mut near = vec![true; pairs.len()];
    let near_distance = (1.0 + 4.0 * eps) * xi;
    for _ in 0..params.max_iters {
        // Lines 4-18: CCD between the safe positions and z^m, clamp above the threshold.
        let t = Instant::now();
        toi.par_iter_mut()
            .zip(&pairs)
            .zip(&near)
            .for_each(|((hit, p), &near)| {
                if !near {
                    *hit = None;
                } else if p.v.iter().any(|&v| changed[v as usize]) {
                    *hit = p.ccd(safe, z, xi, &params.ccd);
                }
            });
        let per_vertex = vertex_toi(&pairs, &toi, n);
        z.par_iter_mut()
            .zip(changed.par_iter_mut())
            .enumerate()
            .for_each(|(i, (zi, moved))| {
                let ti = per_vertex[i];
                *moved = !fixed[i] && ti < 1.0 && ti > params.toi_threshold;
                if *moved {
                    *zi = safe[i] + (*zi - safe[i]) * ti;
                }
            });
        stats.ccd_ms += millis(t);

        // Lines 19-27: distances, weights and the descent direction of eq. 49.
        let t = Instant::now();
        let found: Vec<Closest> = pairs.par_iter().map(|p| p.closest(z)).collect();
        force.iter_mut().for_each(|f| *f = Vector3::zeros());
        alpha.iter_mut().for_each(|a| *a = 0.0);
        for ((pair, c), near) in pairs.iter().zip(&found).zip(near.iter_mut()) {
            let d = c.separation.norm();
            *near = d < near_distance;
            if d >= reach || d == 0.0 {
                continue;
            }
            let push = -mu * barrier.derivative(barrier.gap(d));
            let normal = c.separation / d;
            for (&v, &w) in pair.v.iter().zip(&c.weights) {
                force[v as usize] += normal * (push * w);
                alpha[v as usize] += w.abs();
            }
        }
        let (alpha_0, farthest) = (0..n)
            .into_par_iter()
            .filter(|&i| !fixed[i])
            .map(|i| (alpha[i], (target[i] - z[i]).norm()))
            .reduce(|| (0.0, 0.0), |a, b| (a.0.max(b.0), a.1.max(b.1)));
        // Eq. 53.
        let lambda = (eps * xi / (mu * alpha_0 * bound + farthest)).min(1.0);
        let moved = z
            .par_iter_mut()
            .zip(drift.par_iter_mut())
            .zip(changed.par_iter_mut())
            .enumerate()
            .map(|(i, ((zi, di), ci))| {
                if fixed[i] {
                    return 0.0;
                }
                let before = *zi;
                *zi += (force[i] + target[i] - *zi) * lambda;
                keep_out(i, zi);
                let step = (*zi - before).norm();
                *ci |= step > 0.0;
                *di += step;
                step
            })
            .reduce(|| 0.0, f64::max);
        stats.iterations += 1;
        stats.descent_ms += millis(t);
        if moved < STOP_FRACTION * eps * xi {
            break;
        }
    }

    // Pairs the descent may have brought together beyond the broad phase's margin.
    let t = Instant::now();
    let max_drift = drift.iter().copied().fold(0.0, f64::max);
    if 2.0 * max_drift + eps * xi > reach {
        let candidates = candidate_pairs(safe, z, mesh, eps * xi);
        pairs = primitive_pairs(mesh.triangles, &candidates);
    }
    stats.broad_phase_ms += millis(t);

    let t = Instant::now();
    stats.clamped = guarantee(safe, z, fixed, &pairs, params);
    stats.ccd_ms += millis(t);

    let t = Instant::now();
    stats.active_pairs = pairs
        .par_iter()
        .filter(|p| p.closest(z).separation.norm() < reach)
        .count();
    stats.descent_ms += millis(t);
    stats
}

/// The final clamp (see the module doc): returns the number of vertices it moved.
fn guarantee(
    safe: &[Vector3<f64>],
    z: &mut [Vector3<f64>],
    fixed: &[bool],
    pairs: &[Pair],
    params: &ContactParams,
) -> usize {
    let floor = params.eps * params.thickness;
    // Each pair's separation floor, from its distance at the safe positions; pairs already
    // touching there cannot be helped and are skipped.
    let floors: Vec<f64> = pairs
        .par_iter()
        .map(|p| floor.min(0.9 * p.closest(safe).separation.norm()))
        .collect();
    let mut moved = vec![false; z.len()];
    for pass in 0..=CLAMP_PASSES {
        let toi: Vec<Option<f64>> = pairs
            .par_iter()
            .zip(&floors)
            .map(|(p, &min)| {
                if min > 0.0 {
                    p.ccd(safe, z, min, &params.ccd)
                } else {
                    None
                }
            })
            .collect();
        if toi.iter().all(Option::is_none) {
            break;
        }
        let per_vertex = vertex_toi(pairs, &toi, z.len());
        for (i, zi) in z.iter_mut().enumerate() {
            let ti = per_vertex[i];
            if fixed[i] || ti >= 1.0 {
                continue;
            }
            let keep = if pass < CLAMP_PASSES { ti } else { 0.0 };
            *zi = safe[i] + (*zi - safe[i]) * keep;
            moved[i] = true;
        }
    }
    moved.iter().filter(|&&m| m).count()
}

#[cfg(test)]
mod tests {
    use super::*;

    type Scene = (Vec<Vector3<f64>>, Vec<Vector3<f64>>, Vec<[u32; 3]>);

    /// Two parallel triangles, the upper pushed through the lower by the "global step".
    fn crossing() -> Scene {
        let v = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
        let lower = [v(0., 0., 0.), v(1., 0., 0.), v(0., 1., 0.)];
        let safe: Vec<_> = lower
            .iter()
            .copied()
            .chain(lower.iter().map(|p| p + v(0.1, 0.1, 0.01)))
            .collect();
        let target: Vec<_> = lower
            .iter()
            .copied()
            .chain(lower.iter().map(|p| p + v(0.1, 0.1, -0.01)))
            .collect();
        (safe, target, vec![[0, 1, 2], [3, 4, 5]])
    }

    #[test]
    fn a_crossing_move_is_stopped_and_the_pair_kept_apart() {
        let (safe, target, triangles) = crossing();
        let params = ContactParams {
            thickness: 2e-3,
            d_hat: 4e-3,
            ..ContactParams::default()
        };
        let body = [0, 0];
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &body,
            self_contact: &[true],
        };
        let mut z = target.clone();
        let fixed = vec![false; 6];
        let stats = project(&safe, &mut z, &fixed, &mesh, &params, &|_, _| {});
        assert_eq!(stats.candidate_pairs, 1);
        assert!(stats.active_pairs > 0 && stats.iterations > 0);
        let lowest_upper = z[3..].iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
        let highest_lower = z[..3].iter().map(|p| p.z).fold(f64::NEG_INFINITY, f64::max);
        assert!(
            lowest_upper - highest_lower > params.eps * params.thickness,
            "gap {}",
            lowest_upper - highest_lower
        );
        // Without self-contact nothing happens.
        let mesh = ContactMesh {
            self_contact: &[false],
            ..mesh
        };
        let mut z = target.clone();
        let stats = project(&safe, &mut z, &fixed, &mesh, &params, &|_, _| {});
        assert_eq!(stats.candidate_pairs, 0);
        assert_eq!(z, target);
    }

    #[test]
    fn far_apart_bodies_are_left_alone() {
        let (safe, _, triangles) = crossing();
        let body = [0, 1];
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &body,
            self_contact: &[true, true],
        };
        let mut z = safe.clone();
        let params = ContactParams {
            thickness: 1e-3,
            d_hat: 2e-3,
            ..ContactParams::default()
        };
        project(&safe, &mut z, &[false; 6], &mesh, &params, &|_, _| {});
        assert_eq!(z, safe);
    }
}
