//! The particle-triangle pairs of one step: candidates by the membrane contact's broad phase
//! (a uniform grid of the triangles' boxes, [`BroadPhase`]), each with the side of its
//! triangle the particle starts on.
//!
//! Every triangle's box covers its vertices at the start of the step and at their predicted
//! positions `y*`, padded by its half thickness and the reach `s` (m), the largest predicted
//! move `|y* - y_t|` of any point of the two families; each colliding particle asks for the
//! triangles whose boxes meet its own (start and prediction), padded by its radius and `s`.
//! A pair is therefore found whenever the particle and the triangle come within their gap
//! while no point moves more than `s` beyond its prediction.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::contact::{BroadPhase, ContactMesh};
use crate::geometry::vertex_index::index_by_vertex;
use crate::real::Real;
use crate::solve::points::Points;

use super::prism::over_triangle;

/// One particle-triangle pair of a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Pair {
    pub particle: u32,
    pub triangle: u32,
    /// The side of the triangle's plane the particle keeps (+-1), 0 until the particle is
    /// first over the triangle.
    pub side: i8,
}

/// The pairs of a step, by particle (increasing), and by membrane vertex.
#[derive(Default)]
pub(super) struct PairList {
    pub pairs: Vec<Pair>,
    /// `pairs[particle_start[i]..particle_start[i + 1]]` are particle `i`'s pairs.
    pub particle_start: Vec<u32>,
    /// `vertex_entries[vertex_start[v]..vertex_start[v + 1]]`: the pairs whose triangle holds
    /// vertex `v`, increasing.
    pub vertex_start: Vec<u32>,
    pub vertex_entries: Vec<u32>,
    broad: BroadPhase,
    start: Vec<Vector3<f64>>,
    end: Vec<Vector3<f64>>,
    padding: Vec<f64>,
    rows: Vec<Vec<u32>>,
}

impl PairList {
    /// The pairs of the step that starts at the loaded and predicted `cloth` and `particles`
    /// (`y_t`, `y*`), for the triangles `triangles` (vertex indices into `cloth`) of half
    /// thicknesses `tau` (m).
    pub fn find<T: Real>(
        &mut self,
        triangles: &[[u32; 3]],
        tau: &[f64],
        cloth: &Points<T>,
        particles: &Points<T>,
    ) {
        let to_f64 = |v: &Vector3<T>| v.map(|c| c.to_f64());
        let reach = |points: &Points<T>| {
            (0..points.y_start.len())
                .into_par_iter()
                .map(|i| to_f64(&(points.y_star[i] - points.y_start[i])).norm())
                .reduce(|| 0.0, f64::max)
        };
        let s = reach(cloth).max(reach(particles));
        self.start.clear();
        self.start.extend(cloth.y_start.iter().map(to_f64));
        self.end.clear();
        self.end.extend(cloth.y_star.iter().map(to_f64));
        self.padding.clear();
        self.padding.extend(tau.iter().map(|t| t + s));
        // One body without self-contact: the grid is built, no triangle pair is reported.
        let body = vec![0; triangles.len()];
        let mesh = ContactMesh {
            triangles,
            body: &body,
            self_contact: &[false],
        };
        self.broad
            .candidate_pairs(&self.start, &self.end, &mesh, &self.padding);
        let broad = &self.broad;
        let n = particles.y_start.len();
        self.rows.resize_with(n, Vec::new);
        self.rows.par_iter_mut().enumerate().for_each(|(i, row)| {
            row.clear();
            if !particles.collides[i] {
                return;
            }
            let (a, b) = (to_f64(&particles.y_start[i]), to_f64(&particles.y_star[i]));
            let pad = Vector3::repeat(particles.margin[i].to_f64() + s);
            broad.overlapping(a.inf(&b) - pad, a.sup(&b) + pad, row);
        });
        self.pairs.clear();
        self.particle_start.clear();
        self.particle_start.push(0);
        for (i, row) in self.rows.iter().enumerate() {
            self.pairs.extend(row.iter().map(|&t| Pair {
                particle: i as u32,
                triangle: t,
                side: 0,
            }));
            self.particle_start.push(self.pairs.len() as u32);
        }
        let start = &self.start;
        self.pairs.par_iter_mut().for_each(|pair| {
            let [a, b, c] = triangles[pair.triangle as usize].map(|v| &start[v as usize]);
            let x = to_f64(&particles.y_start[pair.particle as usize]);
            if let Some(over) = over_triangle(&x, a, b, c) {
                pair.side = over.side();
            }
        });
        index_by_vertex(
            self.pairs.iter().map(|p| triangles[p.triangle as usize]),
            cloth.y_start.len(),
            &mut self.vertex_start,
            &mut self.vertex_entries,
        );
    }
}
