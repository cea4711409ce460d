//! The particles-against-membranes coupling of a step, between the two families: its pairs,
//! the families' inverse metrics, the projection during the iterations and at the end, and
//! the reactions it leaves for the convergence measures.

use std::time::Instant;

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::membrane::Membrane;
use crate::real::Real;
use crate::solve::families::Families;
use crate::solve::membranes::jacobi::jacobi_block;
use crate::solve::membranes::MembraneSystem;
use crate::solve::particles::ParticleSystem;
use crate::symmetric::SymmetricMatrix3;
use crate::timing::millis;

use super::pairs::PairList;
use super::projection::{pass, Metric, Scratch};
use super::{ITERATION_PASSES, MAX_PASSES, PASS_TOLERANCE};

/// The coupling of a body list with membranes and particle bodies.
pub(crate) struct ClothCoupling<T: Real> {
    /// Every membrane triangle in the membrane family's vertex numbering, and its half
    /// thickness (m, the mean of its vertices').
    triangles: Vec<[u32; 3]>,
    tau: Vec<f64>,
    /// Each particle's radius (m, its collider margin).
    radius: Vec<f64>,
    list: PairList,
    scratch: Scratch,
    particle_inverse: Vec<f64>,
    vertex_inverse: Vec<SymmetricMatrix3<f64>>,
    /// Each point's move by the last projection of the iterations (m): the reaction the
    /// coupling realised at the current iterate; empty before the first of a step.
    particle_reaction: Vec<Vector3<T>>,
    membrane_reaction: Vec<Vector3<T>>,
    /// The membranes' reaction with their contact's added (reused).
    merged: Vec<Vector3<T>>,
    /// Milliseconds of this step so far.
    pub millis: f64,
}

impl<T: Real> ClothCoupling<T> {
    /// The coupling of `membranes` (laid out as in `cloth`) with the particles of `particles`;
    /// None unless both families are present.
    pub fn of(membranes: &[&mut Membrane], families: &Families<T>) -> Option<Self> {
        let (cloth, particles) = (families.membranes.as_ref()?, families.particles.as_ref()?);
        let mut triangles = Vec::new();
        for (membrane, range) in membranes.iter().zip(&cloth.points.ranges) {
            let base = range.start as u32;
            triangles.extend(
                membrane
                    .mesh()
                    .triangles()
                    .iter()
                    .map(|t| t.map(|v| v + base)),
            );
        }
        let margin = &cloth.points.margin;
        let tau = triangles
            .iter()
            .map(|t| t.iter().map(|&v| margin[v as usize].to_f64()).sum::<f64>() / 3.0)
            .collect();
        Some(Self {
            triangles,
            tau,
            radius: particles.points.margin.iter().map(|m| m.to_f64()).collect(),
            list: PairList::default(),
            scratch: Scratch::default(),
            particle_inverse: vec![0.0; particles.points.margin.len()],
            vertex_inverse: vec![SymmetricMatrix3::zeros(); cloth.points.margin.len()],
            particle_reaction: Vec::new(),
            membrane_reaction: Vec::new(),
            merged: Vec::new(),
            millis: 0.0,
        })
    }

    /// Finds the step's pairs, once both families are loaded and predicted.
    pub fn start_step(&mut self, families: &Families<T>) {
        let started = Instant::now();
        self.particle_reaction.clear();
        self.membrane_reaction.clear();
        if let (Some(cloth), Some(particles)) = (&families.membranes, &families.particles) {
            self.list
                .find(&self.triangles, &self.tau, &cloth.points, &particles.points);
        }
        self.millis = millis(started);
    }

    /// Whether a projection ran in this step's iterations (before that, the iterate has not
    /// been through one, and its residual cannot decide convergence).
    pub fn ran(&self) -> bool {
        !self.particle_reaction.is_empty()
    }

    /// The reactions the global moves measure their residual with, per family in the order
    /// of [`Families::each`]: the membranes' (their contact's `contact` added) and the
    /// particles'; empty before the first projection of a step.
    pub fn reactions<'a>(&'a mut self, contact: &'a [Vector3<T>]) -> [&'a [Vector3<T>]; 2] {
        if !self.ran() {
            return [contact, &[]];
        }
        let membranes: &[Vector3<T>] = if contact.is_empty() {
            &self.membrane_reaction
        } else {
            self.merged.clear();
            let coupling = &self.membrane_reaction;
            self.merged
                .extend(contact.iter().zip(coupling).map(|(a, b)| a + b));
            &self.merged
        };
        [membranes, &self.particle_reaction]
    }

    /// The projection after a global iteration, on both families' `y_next`; returns the
    /// largest move it made (m).
    pub fn iterate(&mut self, families: &mut Families<T>, h: T) -> f64 {
        self.project(families, h, Iterate::Next);
        let largest = |moves: &[Vector3<T>]| {
            moves
                .par_iter()
                .map(|m| m.norm_squared().to_f64())
                .reduce(|| 0.0, f64::max)
                .sqrt()
        };
        largest(&self.particle_reaction).max(largest(&self.membrane_reaction))
    }

    /// The projection once more on the positions the velocities are taken from (`y`), after
    /// the fluids' density projection (the reactions' buffers take its moves: they are spent).
    pub fn finish(&mut self, families: &mut Families<T>, h: T) {
        self.project(families, h, Iterate::Current);
    }

    /// The passes of one projection on the iterate `which` of both families, each point's
    /// move into the reactions.
    fn project(&mut self, families: &mut Families<T>, h: T, which: Iterate) {
        let (Some(cloth), Some(particles)) = (&mut families.membranes, &mut families.particles)
        else {
            return;
        };
        let started = Instant::now();
        match which {
            Iterate::Next => self.metrics(cloth, particles, h),
            Iterate::Current => self.masses(cloth, particles),
        }
        let zero = Vector3::zeros();
        self.particle_reaction.clear();
        self.particle_reaction
            .resize(particles.points.y.len(), zero);
        self.membrane_reaction.clear();
        self.membrane_reaction.resize(cloth.points.y.len(), zero);
        let metric = Metric {
            triangles: &self.triangles,
            tau: &self.tau,
            radius: &self.radius,
            particle_inverse: &self.particle_inverse,
            vertex_inverse: &self.vertex_inverse,
        };
        let (p, c, passes) = match which {
            Iterate::Next => (
                &mut particles.points.y_next,
                &mut cloth.points.y_next,
                ITERATION_PASSES,
            ),
            Iterate::Current => (&mut particles.points.y, &mut cloth.points.y, MAX_PASSES),
        };
        for _ in 0..passes {
            let worst = pass(
                &mut self.list,
                &metric,
                &mut self.scratch,
                p,
                c,
                &mut self.particle_reaction,
                &mut self.membrane_reaction,
            );
            if worst <= PASS_TOLERANCE {
                break;
            }
        }
        if let Iterate::Next = which {
            // The direct solver holds these particles from its next move on: they take the
            // Jacobi move, whose metric the projection is in (see the module [`super`]).
            let held = &mut particles.held;
            for (h, r) in held.iter_mut().zip(&self.particle_reaction) {
                *h |= *r != Vector3::zeros();
            }
        }
        self.millis += millis(started);
    }

    /// The inverse masses (1/kg) of the particles and of the vertices in some pair, the
    /// metric of the projection at the end of the step (see the module [`super`]); zero for
    /// pinned points.
    fn masses(&mut self, cloth: &MembraneSystem<T>, particles: &ParticleSystem<T>) {
        self.fill_inverses(
            cloth,
            particles,
            |i| 1.0 / particles.rest.mass[i].to_f64(),
            |v| SymmetricMatrix3::zeros().plus_identity(1.0 / cloth.rest.vertices[v].mass.to_f64()),
        );
    }

    /// The inverse Jacobi blocks (1/kg) of the particles and of the vertices in some pair at
    /// the last evaluation; zero for pinned points.
    fn metrics(&mut self, cloth: &MembraneSystem<T>, particles: &ParticleSystem<T>, h: T) {
        let h2 = h * h;
        self.fill_inverses(
            cloth,
            particles,
            |i| 1.0 / particles.diagonal(i, h2).to_f64(),
            |v| {
                let mass = cloth.rest.vertices[v].mass;
                jacobi_block(cloth, v, h2)
                    .inverse_or(T::one() / mass)
                    .map(|x| x.to_f64())
            },
        );
    }

    /// `particle_inverse[i]` and `vertex_inverse[v]` from the given maps for the free points
    /// in some pair, zero for the pinned ones and those in no pair.
    fn fill_inverses(
        &mut self,
        cloth: &MembraneSystem<T>,
        particles: &ParticleSystem<T>,
        particle: impl Fn(usize) -> f64 + Sync,
        vertex: impl Fn(usize) -> SymmetricMatrix3<f64> + Sync,
    ) {
        let (starts, pinned) = (&self.list.particle_start, &particles.points.pinned);
        self.particle_inverse
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, inverse)| {
                let free = !pinned[i] && starts[i] != starts[i + 1];
                *inverse = if free { particle(i) } else { 0.0 };
            });
        let (starts, pinned) = (&self.list.vertex_start, &cloth.points.pinned);
        self.vertex_inverse
            .par_iter_mut()
            .enumerate()
            .for_each(|(v, inverse)| {
                let free = !pinned[v] && starts[v] != starts[v + 1];
                *inverse = if free {
                    vertex(v)
                } else {
                    SymmetricMatrix3::zeros()
                };
            });
    }
}

/// Which iterate a projection acts on.
#[derive(Clone, Copy)]
enum Iterate {
    /// `y_next`, after a global iteration.
    Next,
    /// `y`, after the iterations.
    Current,
}
