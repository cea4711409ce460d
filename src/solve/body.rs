//! The seam between the solver and the kinds of body it steps.
//!
//! A step advances a list of bodies of any kind ([`BodyMut`]). What the solver reads and
//! writes of every body, whatever its kind, is its points' state ([`Body`]): positions,
//! velocities and pins, copied into the family's [`Points`](super::points::Points). What a
//! kind computes (rest data, its per-element kernel and preconditioner, its global move and
//! an end-of-step hook) is its family ([`super::family::Family`]), built from the bodies of
//! that kind. A new kind adds a variant here and a family; the membrane code needs no edit.

use std::collections::BTreeMap;

use nalgebra::Vector3;

use crate::error::Result;
use crate::membrane::Membrane;
use crate::particles::Particles;

/// What the solver reads and writes of a body of any kind: its points' state, in f64 and SI
/// units.
pub trait Body {
    /// A process-unique identity, so that a solver can tell whether its cached rest data
    /// still match.
    fn id(&self) -> u64;
    /// Number of points (a membrane's vertices, a particle body's particles).
    fn num_points(&self) -> usize;
    /// Positions (m).
    fn positions(&self) -> &[Vector3<f64>];
    /// Velocities (m/s).
    fn velocities(&self) -> &[Vector3<f64>];
    /// Pinned points and their targets (m).
    fn pins(&self) -> &BTreeMap<u32, Vector3<f64>>;
    /// Positions and velocities to write a finished step back into (the host copy becomes
    /// the newest).
    fn state_mut(&mut self) -> (&mut [Vector3<f64>], &mut [Vector3<f64>]);
    /// Brings the host copy of the state up to date (a GPU step may have left a newer one on
    /// its device).
    fn sync(&mut self) -> Result<()>;
}

/// One body of the list a step advances, by kind.
pub enum BodyMut<'a> {
    Membrane(&'a mut Membrane),
    Particles(&'a mut Particles),
}

impl<'a> From<&'a mut Particles> for BodyMut<'a> {
    fn from(particles: &'a mut Particles) -> Self {
        Self::Particles(particles)
    }
}

impl<'a> From<&'a mut Membrane> for BodyMut<'a> {
    fn from(membrane: &'a mut Membrane) -> Self {
        Self::Membrane(membrane)
    }
}

impl BodyMut<'_> {
    /// The body's points' state, whatever its kind.
    pub fn body(&self) -> &dyn Body {
        match self {
            Self::Membrane(m) => &**m,
            Self::Particles(p) => &**p,
        }
    }

    /// See [`Self::body`].
    pub fn body_mut(&mut self) -> &mut dyn Body {
        match self {
            Self::Membrane(m) => &mut **m,
            Self::Particles(p) => &mut **p,
        }
    }
}

/// A step's bodies sorted into their families, each with its bodies' indices in the list
/// the step was given (to name a body in an error).
pub(crate) struct ByKind<'l> {
    pub membranes: Vec<&'l mut Membrane>,
    pub membrane_indices: Vec<usize>,
    pub particles: Vec<&'l mut Particles>,
    pub particle_indices: Vec<usize>,
}

impl<'l> ByKind<'l> {
    pub fn sort(bodies: &'l mut [BodyMut<'_>]) -> Self {
        let mut sorted = Self {
            membranes: Vec::new(),
            membrane_indices: Vec::new(),
            particles: Vec::new(),
            particle_indices: Vec::new(),
        };
        for (i, body) in bodies.iter_mut().enumerate() {
            match body {
                BodyMut::Membrane(m) => {
                    sorted.membranes.push(&mut **m);
                    sorted.membrane_indices.push(i);
                }
                BodyMut::Particles(p) => {
                    sorted.particles.push(&mut **p);
                    sorted.particle_indices.push(i);
                }
            }
        }
        sorted
    }

    /// Brings every body's host state up to date (see [`Body::sync`]).
    pub fn sync(&mut self) -> Result<()> {
        self.membranes.iter_mut().try_for_each(|m| m.sync())
    }

    /// Each present family's body indices in the step's list, in the order of
    /// [`Families::each`](super::families::Families::each) (membranes, then particles; a
    /// family is present exactly when it has bodies).
    pub fn list_indices(&self) -> Vec<&[usize]> {
        [&self.membrane_indices[..], &self.particle_indices[..]]
            .into_iter()
            .filter(|l| !l.is_empty())
            .collect()
    }
}

impl Body for Membrane {
    fn id(&self) -> u64 {
        Membrane::id(self)
    }
    fn num_points(&self) -> usize {
        self.num_vertices()
    }
    fn positions(&self) -> &[Vector3<f64>] {
        Membrane::positions(self)
    }
    fn velocities(&self) -> &[Vector3<f64>] {
        Membrane::velocities(self)
    }
    fn pins(&self) -> &BTreeMap<u32, Vector3<f64>> {
        Membrane::pins(self)
    }
    fn state_mut(&mut self) -> (&mut [Vector3<f64>], &mut [Vector3<f64>]) {
        Membrane::state_mut(self)
    }
    fn sync(&mut self) -> Result<()> {
        Membrane::sync(self)
    }
}

impl Body for Particles {
    fn id(&self) -> u64 {
        Particles::id(self)
    }
    fn num_points(&self) -> usize {
        self.num_particles()
    }
    fn positions(&self) -> &[Vector3<f64>] {
        Particles::positions(self)
    }
    fn velocities(&self) -> &[Vector3<f64>] {
        Particles::velocities(self)
    }
    fn pins(&self) -> &BTreeMap<u32, Vector3<f64>> {
        Particles::pins(self)
    }
    fn state_mut(&mut self) -> (&mut [Vector3<f64>], &mut [Vector3<f64>]) {
        Particles::state_mut(self)
    }
    /// Particles are stepped on the host only: their state is always current.
    fn sync(&mut self) -> Result<()> {
        Ok(())
    }
}
