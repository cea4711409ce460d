//! The Python side of the body seam: a body of any kind that `Solver.add` takes, and the lock
//! a step holds on each body's core while it advances them.

use std::sync::{Arc, Mutex, MutexGuard};

use nalgebra::Vector3;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

use crate::membrane::Membrane;
use crate::particles::Particles;
use crate::solve::BodyMut;

use super::membrane::PyMembrane;
use super::owner::{Owner, SolverMark};
use super::particle_body::PyParticles;

/// A `ValueError` naming the first of a solver's `bodies` that another solver has taken over
/// since ([`Owner`]): the solver of `mark` steps only the bodies it holds.
pub fn check_held(py: Python<'_>, bodies: &[PyBody], mark: &Arc<SolverMark>) -> PyResult<()> {
    match bodies
        .iter()
        .position(|b| !b.with_owner(py, |owner| owner.held_by(mark)))
    {
        None => Ok(()),
        Some(index) => Err(PyValueError::new_err(format!(
            "body {index} ({}) was added to another Solver since: a body is stepped by the \
             solver it was last added to, which keeps its own record of it between steps (its \
             working set, contact warm start and friction); step that solver, or add the body \
             to this one again to take it back",
            bodies[index].describe(py)
        ))),
    }
}

/// A body a solver steps, by kind.
pub enum PyBody {
    Membrane(Py<PyMembrane>),
    Particles(Py<PyParticles>),
}

/// The core of a [`PyBody`], shared with its Python object.
pub enum SharedBody {
    Membrane(Arc<Mutex<Membrane>>),
    Particles(Arc<Mutex<Particles>>),
}

/// A [`SharedBody`] locked for a step.
pub enum LockedBody<'a> {
    Membrane(MutexGuard<'a, Membrane>),
    Particles(MutexGuard<'a, Particles>),
}

impl PyBody {
    /// The body `object` is, or a `TypeError` naming what it is instead.
    pub fn extract(object: &Bound<'_, PyAny>) -> PyResult<Self> {
        if let Ok(membrane) = object.cast::<PyMembrane>() {
            return Ok(Self::Membrane(membrane.clone().unbind()));
        }
        if let Ok(particles) = object.cast::<PyParticles>() {
            return Ok(Self::Particles(particles.clone().unbind()));
        }
        Err(PyTypeError::new_err(format!(
            "Solver.add takes a body (peridyn.Membrane or peridyn.Particles), got {}",
            object.get_type().name()?
        )))
    }

    /// Runs `f` on the body's [`Owner`].
    pub fn with_owner<R>(&self, py: Python<'_>, f: impl FnOnce(&Owner) -> R) -> R {
        match self {
            Self::Membrane(m) => f(&m.borrow(py).owner),
            Self::Particles(p) => f(&p.borrow(py).owner),
        }
    }

    /// What the body is, for messages: its class and size ("Particles of 27 particles").
    pub fn describe(&self, py: Python<'_>) -> String {
        match self {
            Self::Membrane(m) => {
                format!(
                    "Membrane of {} vertices",
                    m.borrow(py).lock().num_vertices()
                )
            }
            Self::Particles(p) => {
                format!(
                    "Particles of {} particles",
                    p.borrow(py).lock().num_particles()
                )
            }
        }
    }

    pub fn shared(&self, py: Python<'_>) -> SharedBody {
        match self {
            Self::Membrane(m) => SharedBody::Membrane(m.borrow(py).inner.clone()),
            Self::Particles(p) => SharedBody::Particles(p.borrow(py).inner.clone()),
        }
    }

    /// The largest coordinate magnitude (m) of the body's positions now, measured from
    /// `origin` (m, world; read back from the device after a GPU step).
    pub fn extent(&self, py: Python<'_>, origin: &Vector3<f64>) -> PyResult<f64> {
        let largest =
            |x: &[Vector3<f64>]| x.iter().map(|p| (p - origin).amax()).fold(0.0, f64::max);
        match self {
            Self::Membrane(m) => Ok(largest(m.borrow(py).state()?.positions())),
            Self::Particles(p) => Ok(largest(p.borrow(py).lock().positions())),
        }
    }

    /// The positions (m, world) of a particle body; none for a membrane.
    pub fn particle_positions(&self, py: Python<'_>) -> Vec<Vector3<f64>> {
        match self {
            Self::Membrane(_) => Vec::new(),
            Self::Particles(p) => p.borrow(py).lock().positions().to_vec(),
        }
    }

    pub fn object(&self, py: Python<'_>) -> Py<PyAny> {
        match self {
            Self::Membrane(m) => m.clone_ref(py).into_any(),
            Self::Particles(p) => p.clone_ref(py).into_any(),
        }
    }
}

impl SharedBody {
    /// Whether both share one core (the same body added twice).
    pub fn same(&self, other: &Self) -> bool {
        match (self, other) {
            (Self::Membrane(a), Self::Membrane(b)) => Arc::ptr_eq(a, b),
            (Self::Particles(a), Self::Particles(b)) => Arc::ptr_eq(a, b),
            _ => false,
        }
    }

    /// Locks the core (a lock poisoned by a panic elsewhere still gives the body: every
    /// step leaves it in a consistent state).
    pub fn lock(&self) -> LockedBody<'_> {
        match self {
            Self::Membrane(m) => LockedBody::Membrane(m.lock().unwrap_or_else(|p| p.into_inner())),
            Self::Particles(p) => {
                LockedBody::Particles(p.lock().unwrap_or_else(|p| p.into_inner()))
            }
        }
    }
}

impl LockedBody<'_> {
    pub fn body_mut(&mut self) -> BodyMut<'_> {
        match self {
            Self::Membrane(m) => BodyMut::Membrane(m),
            Self::Particles(p) => BodyMut::Particles(p),
        }
    }
}
