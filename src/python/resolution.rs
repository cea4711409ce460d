//! The warning (`peridyn.PrecisionWarning`) that a body's coordinates are too coarse in the
//! solver's precision for the motion gravity gives it in one step. Coordinates are measured
//! as the step measures them: a particle body's from its family's frame origin, near its
//! bodies (src/solve/frame.rs), and a membrane's, or a particle body's when membranes share
//! the step, from the world origin (docs/architecture.md, "Particle frame").

use nalgebra::Vector3;
use pyo3::prelude::*;

use crate::solve::frame::origin_near;

use super::body::PyBody;
use super::errors::PrecisionWarning;

/// The solver's precision: its name and machine epsilon.
pub(super) type Precision = (&'static str, f64);

/// The world point (m) the step measures the particle bodies among `bodies` from, as
/// `Families::load` chooses it: the world origin when a membrane is among them, else
/// [`origin_near`] every particle body's positions.
fn particle_origin(py: Python<'_>, bodies: &[&PyBody]) -> Vector3<f64> {
    if bodies.iter().any(|b| matches!(b, PyBody::Membrane(_))) {
        return Vector3::zeros();
    }
    let positions: Vec<Vector3<f64>> = bodies
        .iter()
        .flat_map(|b| b.particle_positions(py))
        .collect();
    origin_near(positions.iter())
}

/// Warns for each of `warned` (bodies among `bodies`, every body the next step advances)
/// whose coordinates, measured from where the step measures them ([`particle_origin`] for
/// particle bodies, the world origin for membranes), have a resolution `|x| epsilon` (m)
/// above `|g| dt^2` (m), the motion gravity `gravity` (m/s^2) gives a body at rest in one
/// step `dt` (s): the step would round it away.
pub(super) fn warn_resolution(
    py: Python<'_>,
    bodies: &[&PyBody],
    warned: &[&PyBody],
    (name, epsilon): Precision,
    dt: f64,
    gravity: &Vector3<f64>,
) -> PyResult<()> {
    let expected = gravity.norm() * dt * dt;
    if expected <= 0.0 {
        return Ok(());
    }
    let origin = particle_origin(py, bodies);
    for body in warned {
        let from = match body {
            PyBody::Membrane(_) => Vector3::zeros(),
            PyBody::Particles(_) => origin,
        };
        let coordinate = body.extent(py, &from)?;
        let resolution = coordinate * epsilon;
        if expected >= resolution {
            continue;
        }
        let (measured, remedy) = if from == Vector3::zeros() {
            ("the world origin", "move the scene near the origin")
        } else {
            (
                "the origin of the particle bodies' frame, near them",
                "the particle bodies span too much for this precision",
            )
        };
        let message = format!(
            "a body has coordinates up to {coordinate:e} m from {measured}, whose resolution \
             in precision '{name}' is {resolution:e} m, but the motion gravity gives it in one \
             step from rest, |g| dt^2 = {expected:e} m, is smaller: the step rounds it away and \
             the body will not fall as it should; {remedy}{}",
            if name == "f32" {
                " or use precision='f64'"
            } else {
                ""
            }
        );
        let category = py.get_type::<PrecisionWarning>();
        PyErr::warn(py, &category, &std::ffi::CString::new(message)?, 1)?;
    }
    Ok(())
}
