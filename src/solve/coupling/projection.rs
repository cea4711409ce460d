//! The projection of the particle-triangle constraints (see the module [`super`] for the
//! equations): one Jacobi pass over every pair at once, with mass splitting, in `f64`,
//! deterministic for any thread count (each pair, particle and vertex is computed alone and
//! sums run in a fixed order).

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::real::Real;
use crate::symmetric::SymmetricMatrix3;

use super::pairs::PairList;
use super::prism::over_triangle;

/// A pair's state in one pass: its direction `g_p = s n`, weights and violation `C` (m;
/// negative when violated), then its impulse `J` (kg m).
#[derive(Clone, Copy, Default)]
pub(super) struct PairState {
    direction: Vector3<f64>,
    weights: [f64; 3],
    violation: f64,
    active: bool,
    impulse: Vector3<f64>,
}

/// What a pass reads: the triangles, the gap of each pair's two primitives and the inverse
/// metrics (1/kg; zero for a pinned point).
pub(super) struct Metric<'a> {
    pub triangles: &'a [[u32; 3]],
    /// Half thickness of each triangle (m).
    pub tau: &'a [f64],
    /// Radius of each particle (m).
    pub radius: &'a [f64],
    pub particle_inverse: &'a [f64],
    pub vertex_inverse: &'a [SymmetricMatrix3<f64>],
}

/// The pass's scratch, reused.
#[derive(Default)]
pub(super) struct Scratch {
    states: Vec<PairState>,
    particle_count: Vec<u32>,
    vertex_count: Vec<u32>,
}

/// One Jacobi pass of every pair of `list` on the positions `particles` and `vertices` (m),
/// adding each point's move to `particle_moved` and `vertex_moved` (m). Returns the largest
/// violation before the pass as a fraction of its pair's gap (0 when none is violated).
#[allow(clippy::too_many_arguments)]
pub(super) fn pass<T: Real>(
    list: &mut PairList,
    metric: &Metric<'_>,
    scratch: &mut Scratch,
    particles: &mut [Vector3<T>],
    vertices: &mut [Vector3<T>],
    particle_moved: &mut [Vector3<T>],
    vertex_moved: &mut [Vector3<T>],
) -> f64 {
    let to_f64 = |v: &Vector3<T>| v.map(|c| c.to_f64());
    scratch
        .states
        .resize(list.pairs.len(), PairState::default());
    // The pairs' geometry and violations; a pair takes its side when first over its triangle.
    let worst = {
        let (p, v) = (&*particles, &*vertices);
        list.pairs
            .par_iter_mut()
            .zip(scratch.states.par_iter_mut())
            .map(|(pair, state)| {
                let [a, b, c] =
                    metric.triangles[pair.triangle as usize].map(|k| to_f64(&v[k as usize]));
                let x = to_f64(&p[pair.particle as usize]);
                *state = PairState::default();
                let Some(over) = over_triangle(&x, &a, &b, &c) else {
                    return 0.0;
                };
                if pair.side == 0 {
                    pair.side = over.side();
                }
                let side = f64::from(pair.side);
                let gap =
                    metric.radius[pair.particle as usize] + metric.tau[pair.triangle as usize];
                state.direction = over.normal * side;
                state.weights = over.weights;
                state.violation = over.height * side - gap;
                state.active = state.violation < 0.0;
                if state.active {
                    -state.violation / gap
                } else {
                    0.0
                }
            })
            .reduce(|| 0.0, f64::max)
    };
    if worst == 0.0 {
        return 0.0;
    }
    // How many violated pairs each point is in.
    let states = &scratch.states;
    let starts = &list.particle_start;
    scratch.particle_count.resize(particles.len(), 0);
    scratch
        .particle_count
        .par_iter_mut()
        .enumerate()
        .for_each(|(i, n)| {
            let row = starts[i] as usize..starts[i + 1] as usize;
            *n = states[row].iter().filter(|s| s.active).count() as u32;
        });
    let (vstart, ventries) = (&list.vertex_start, &list.vertex_entries);
    scratch.vertex_count.resize(vertices.len(), 0);
    scratch
        .vertex_count
        .par_iter_mut()
        .enumerate()
        .for_each(|(v, n)| {
            let row = &ventries[vstart[v] as usize..vstart[v + 1] as usize];
            *n = row.iter().filter(|&&k| states[k as usize].active).count() as u32;
        });
    // Impulses.
    let (pcount, vcount) = (&scratch.particle_count, &scratch.vertex_count);
    let pairs = &list.pairs;
    scratch
        .states
        .par_iter_mut()
        .enumerate()
        .for_each(|(k, state)| {
            if !state.active {
                return;
            }
            let pair = pairs[k];
            let g = state.direction;
            let i = pair.particle as usize;
            let mut compliance = f64::from(pcount[i]) * metric.particle_inverse[i];
            for (corner, &vertex) in metric.triangles[pair.triangle as usize].iter().enumerate() {
                let w = state.weights[corner];
                let v = vertex as usize;
                compliance +=
                    f64::from(vcount[v]) * w * w * g.dot(&metric.vertex_inverse[v].mul_vector(&g));
            }
            if compliance > 0.0 {
                state.impulse = g * (-state.violation / compliance);
            }
        });
    // Moves: `D_p^-1 sum J` for a particle, `-D_v^-1 sum w_v J` for a vertex.
    let states = &scratch.states;
    particles
        .par_iter_mut()
        .zip(particle_moved.par_iter_mut())
        .enumerate()
        .for_each(|(i, (x, moved))| {
            let row = starts[i] as usize..starts[i + 1] as usize;
            if row.is_empty() {
                return;
            }
            let sum = states[row]
                .iter()
                .fold(Vector3::zeros(), |s, st| s + st.impulse);
            let dx = (sum * metric.particle_inverse[i]).map(T::of);
            *x += dx;
            *moved += dx;
        });
    let triangles = metric.triangles;
    vertices
        .par_iter_mut()
        .zip(vertex_moved.par_iter_mut())
        .enumerate()
        .for_each(|(v, (x, moved))| {
            let row = &ventries[vstart[v] as usize..vstart[v + 1] as usize];
            if row.is_empty() {
                return;
            }
            let sum = row.iter().fold(Vector3::zeros(), |s, &k| {
                let (state, pair) = (&states[k as usize], &pairs[k as usize]);
                let t = &triangles[pair.triangle as usize];
                let corner = t.iter().position(|&u| u as usize == v).unwrap_or(0);
                s - state.impulse * state.weights[corner]
            });
            let dx = metric.vertex_inverse[v].mul_vector(&sum).map(T::of);
            *x += dx;
            *moved += dx;
        });
    worst
}
