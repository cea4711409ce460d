//! The particle family's working set: every particle body's rest data and state concatenated
//! into one particle range, the kernel's evaluations and the global step's buffers, all
//! allocated once so that the iteration allocates nothing.

use std::time::Instant;

use nalgebra::Vector3;

use crate::error::Result;
use crate::particles::{ParticleRest, Particles};
use crate::real::Real;
use crate::solve::points::Points;
use crate::solve::{ParticleTimings, Timings};
use crate::timing::millis;

use super::direct::DirectSolver;
use super::evaluation::Evaluation;
use super::plastic::PlasticBodies;
use super::repulsion::Repulsion;

/// The particle family's working set.
pub(crate) struct ParticleSystem<T: Real> {
    pub points: Points<T>,
    pub rest: ParticleRest<T>,
    /// The evaluation at the current iterate, and a line search's trial.
    pub current: Evaluation<T>,
    pub trial: Evaluation<T>,
    /// The global step's move and a Jacobi sweep's scratch (m).
    pub delta: Vec<Vector3<T>>,
    pub scratch: Vec<Vector3<T>>,
    /// The factored global matrix, once the direct solver was asked for; the particles it
    /// holds this step (pins and collider contacts, [`super::step`]), and a failure of its
    /// factorisation, reported at the end of the step.
    pub direct: Option<DirectSolver>,
    pub held: Vec<bool>,
    /// The particles a collider moved in the last trial ([`super::step`]).
    pub touched: Vec<bool>,
    pub failure: Option<crate::error::Error>,
    /// The minimum distance between bodies (none for a single body).
    pub repulsion: Option<Repulsion<T>>,
    /// Partial sums of the merit (reused).
    pub chunks: Vec<f64>,
    /// Every body's bonds when some body is plastic ([`super::plastic`]).
    pub plastic: Option<PlasticBodies>,
    /// The step's phases so far ([`crate::solve::StepStats::particles`]).
    pub timings: ParticleTimings,
}

impl<T: Real> ParticleSystem<T> {
    /// The working set of `bodies`, their rest data computed here (state is loaded by
    /// [`Points::load`]).
    pub fn build(bodies: &[&mut Particles]) -> Result<Self> {
        let shared: Vec<&Particles> = bodies.iter().map(|b| &**b).collect();
        let rest = ParticleRest::<T>::of_bodies(&shared)?;
        let (n, bonds) = (rest.len(), rest.indices.len());
        let mut points = Points::new(bodies, rest.mass.clone(), rest.margin.clone());
        points.collides.clone_from(&rest.collides);
        let repulsion = Repulsion::of(&points);
        Ok(Self {
            points,
            rest,
            current: Evaluation::new(n, bonds),
            trial: Evaluation::new(n, bonds),
            delta: vec![Vector3::zeros(); n],
            scratch: vec![Vector3::zeros(); n],
            repulsion,
            direct: None,
            held: vec![false; n],
            touched: vec![false; n],
            failure: None,
            chunks: Vec::new(),
            plastic: PlasticBodies::of(bodies),
            timings: ParticleTimings::default(),
        })
    }

    /// The kernel at the current iterate `y`, unless the current evaluation is there already
    /// (a line search's accepted trial).
    pub fn evaluate(&mut self) {
        if self.current.is_at(&self.points.y) {
            return;
        }
        let started = Instant::now();
        self.current.at.copy_from_slice(&self.points.y);
        self.current.run(&self.rest);
        self.timings.kernel += millis(started);
        self.timings.evaluations += 1;
    }

    /// The plastic end of a step ([`super::plastic`]): the rest data rebuilt from the returned
    /// bonds; the evaluations start afresh, and so does the direct solver's pattern when a
    /// neighbourhood changed. Nothing when no body is plastic, or no particle yielded and no
    /// neighbourhood changed.
    pub(crate) fn plastic_end_step(&mut self, timings: &mut Timings) -> Result<()> {
        let Some(plastic) = self.plastic.as_mut() else {
            return Ok(());
        };
        let Some((rest, changed)) = plastic.end_step(&self.points.y, timings)? else {
            return Ok(());
        };
        self.rest = rest;
        if changed {
            let (n, bonds) = (self.rest.len(), self.rest.indices.len());
            self.current = Evaluation::new(n, bonds);
            self.trial = Evaluation::new(n, bonds);
            self.direct = None;
        } else {
            self.current.valid = false;
            self.trial.valid = false;
        }
        Ok(())
    }

    /// The Jacobi diagonal `D_i = m_i + h^2 L_ii` (kg) of particle `i`.
    #[inline(always)]
    pub fn diagonal(&self, i: usize, h2: T) -> T {
        self.rest.mass[i] + h2 * self.rest.stiffness[i]
    }
}
