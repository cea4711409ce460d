//! Python wrapper of [`Membrane`]. The membrane lives behind an `Arc<Mutex>` shared with the
//! solvers it was added to, so Python sees the solver's results and the solver sees Python's
//! edits (positions, velocities, pins) at its next step.

use std::sync::{Arc, Mutex, MutexGuard};

use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::membrane::{Membrane, MembraneParams};
use crate::mesh::TriangleMesh;

use super::arrays::{to_numpy, to_numpy_1d, triangles, vec3s};
use super::errors::{guard, IntoPyResult};
use super::material;
use super::owner::Owner;
use super::pins;
use super::scalars::{Flag, Int, Real};

/// A thin hyperelastic membrane (triangle mesh) simulated by projective peridynamics.
#[pyclass(module = "peridyn._core", name = "Membrane")]
pub struct PyMembrane {
    pub inner: Arc<Mutex<Membrane>>,
    /// The solver stepping it ([`Owner`]).
    pub owner: Owner,
}

impl PyMembrane {
    pub fn lock(&self) -> MutexGuard<'_, Membrane> {
        synced_or_not(&self.inner)
    }

    /// Locks the membrane with its positions and velocities current: read back from the
    /// device a GPU step left them on, if any.
    pub fn state(&self) -> PyResult<MutexGuard<'_, Membrane>> {
        synced(&self.inner)
    }
}

fn synced_or_not(inner: &Mutex<Membrane>) -> MutexGuard<'_, Membrane> {
    inner
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// See [`PyMembrane::state`].
fn synced(inner: &Mutex<Membrane>) -> PyResult<MutexGuard<'_, Membrane>> {
    let mut m = synced_or_not(inner);
    m.sync().py()?;
    Ok(m)
}

#[pymethods]
impl PyMembrane {
    #[new]
    #[pyo3(signature = (vertices, triangles, *, thickness, density, material,
                        bending = Real::of(0.0),
                        hourglass = Real::of(MembraneParams::DEFAULT_HOURGLASS),
                        neighbors = Int::of(1), self_contact = Flag::of(true),
                        friction = Real::of(0.0)))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        vertices: &Bound<'_, PyAny>,
        triangles: &Bound<'_, PyAny>,
        thickness: Real,
        density: Real,
        material: &Bound<'_, PyAny>,
        bending: Real,
        hourglass: Real,
        neighbors: Int,
        self_contact: Flag,
        friction: Real,
    ) -> PyResult<Self> {
        let friction = friction.get("friction")?;
        let self_contact = self_contact.get("self_contact")?;
        let thickness = thickness.get("thickness")?;
        let density = density.get("density")?;
        let bending = bending.get("bending")?;
        let hourglass = hourglass.get("hourglass")?;
        let neighbors = neighbors.get("neighbors")?;
        let v: Vec<[f64; 3]> = vec3s(vertices, "vertices", None)?
            .iter()
            .map(|p| [p.x, p.y, p.z])
            .collect();
        let t = self::triangles(triangles, "triangles")?;
        let material = material::extract(material)?;
        if neighbors < 1 {
            return Err(pyo3::exceptions::PyValueError::new_err(format!(
                "neighbors must be >= 1 (the k of the k-ring), got {neighbors}"
            )));
        }
        let params = MembraneParams {
            thickness,
            density,
            material,
            bending,
            hourglass,
            neighbors: neighbors as usize,
        };
        let membrane = py.detach(|| {
            guard("Membrane()", || {
                params.validate()?;
                let mut membrane = Membrane::new(TriangleMesh::new(v, t)?, params)?;
                membrane.set_self_contact(self_contact);
                membrane.set_friction(friction)?;
                Ok(membrane)
            })
        })?;
        Ok(Self {
            inner: Arc::new(Mutex::new(membrane)),
            owner: Owner::default(),
        })
    }

    /// Whether a solver with contact keeps this membrane's triangles apart from each other.
    #[getter]
    fn self_contact(&self) -> bool {
        self.lock().self_contact()
    }
    #[setter]
    fn set_self_contact(&self, on: Flag) -> PyResult<()> {
        self.lock().set_self_contact(on.get("self_contact")?);
        Ok(())
    }
    /// Coulomb friction coefficient against membranes (>= 0; a pair takes the geometric mean
    /// of its two bodies' coefficients).
    #[getter]
    fn friction(&self) -> f64 {
        self.lock().friction()
    }
    #[setter]
    fn set_friction(&self, mu: Real) -> PyResult<()> {
        let mu = mu.get("friction")?;
        self.lock().set_friction(mu).py()
    }
    #[getter]
    fn num_vertices(&self) -> usize {
        self.lock().num_vertices()
    }
    #[getter]
    fn num_triangles(&self) -> usize {
        self.lock().mesh().triangles().len()
    }
    /// (N, 3) current positions (m); settable.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_numpy(py, self.state()?.positions().iter().copied())
    }
    #[setter]
    fn set_positions(&self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let mut m = self.lock();
        let n = m.num_vertices();
        m.set_positions(vec3s(value, "positions", Some(n))?).py()
    }
    /// (N, 3) velocities (m/s); settable.
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_numpy(py, self.state()?.velocities().iter().copied())
    }
    #[setter]
    fn set_velocities(&self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let mut m = self.lock();
        let n = m.num_vertices();
        m.set_velocities(vec3s(value, "velocities", Some(n))?).py()
    }
    /// (N, 3) rest positions (m).
    #[getter]
    fn rest_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_numpy(py, self.lock().mesh().vertices().iter().copied())
    }
    /// (M, 3) triangles (int64).
    #[getter]
    fn triangles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let flat: Vec<i64> = self
            .lock()
            .mesh()
            .triangles()
            .iter()
            .flat_map(|t| t.map(i64::from))
            .collect();
        let n = flat.len() / 3;
        to_numpy_1d(py, flat).call_method1("reshape", ((n, 3),))
    }
    /// (N,) lumped vertex masses (kg).
    #[getter]
    fn masses<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        to_numpy_1d(py, self.lock().masses())
    }
    /// (N,) lumped vertex volumes (m^3).
    #[getter]
    fn volumes<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        to_numpy_1d(py, self.lock().volumes())
    }
    #[getter]
    fn thickness(&self) -> f64 {
        self.lock().params().thickness
    }
    #[getter]
    fn density(&self) -> f64 {
        self.lock().params().density
    }
    #[getter]
    fn material(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        material::to_py(py, self.lock().params().material)
    }
    #[getter]
    fn bending(&self) -> f64 {
        self.lock().params().bending
    }
    #[getter]
    fn hourglass(&self) -> f64 {
        self.lock().params().hourglass
    }
    #[getter]
    fn neighbors(&self) -> usize {
        self.lock().params().neighbors
    }
    /// CSR (offsets, indices) of every vertex's neighbours (int64).
    fn neighborhood<'py>(&self, py: Python<'py>) -> (Bound<'py, PyAny>, Bound<'py, PyAny>) {
        let m = self.lock();
        let nb = m.neighborhood();
        (
            to_numpy_1d(py, nb.offsets.iter().map(|&o| o as i64).collect()),
            to_numpy_1d(py, nb.indices.iter().map(|&o| o as i64).collect()),
        )
    }
    /// Fixes vertices at `targets` ((len(indices), 3) m; default: where they are now).
    #[pyo3(signature = (indices, targets = None))]
    fn pin(&self, indices: &Bound<'_, PyAny>, targets: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        pins::pin(|| self.state(), indices, targets)
    }
    /// Releases the given pinned vertices (all when None).
    #[pyo3(signature = (indices = None))]
    fn unpin(&self, indices: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        pins::unpin(&mut *self.lock(), indices)
    }
    /// Sorted indices of the pinned vertices (int64).
    #[getter]
    fn pinned<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        pins::pinned(py, &*self.lock())
    }
    /// (P, 3) targets of the pinned vertices (m), in the order of `pinned`; settable.
    #[getter]
    fn pin_targets<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        pins::pin_targets(py, &*self.lock())
    }
    #[setter]
    fn set_pin_targets(&self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        pins::set_pin_targets(&mut *self.lock(), value)
    }
    /// Stretching + bending + hourglass energy (J) at the current positions.
    fn elastic_energy(&self, py: Python<'_>) -> PyResult<f64> {
        let inner = self.inner.clone();
        py.detach(move || Ok(synced(&inner)?.energy_terms().py()?.total()))
    }
    /// {'stretch': J, 'bending': J, 'hourglass': J} at the current positions.
    fn energy_terms<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let inner = self.inner.clone();
        let e = py.detach(move || synced(&inner)?.energy_terms().py())?;
        let d = PyDict::new(py);
        d.set_item("stretch", e.stretch)?;
        d.set_item("bending", e.bending)?;
        d.set_item("hourglass", e.hourglass)?;
        Ok(d)
    }
    /// (N, 3) internal forces (N): minus the gradient of `elastic_energy`.
    fn internal_forces<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let inner = self.inner.clone();
        let f = py.detach(move || synced(&inner)?.internal_forces().py())?;
        to_numpy(py, f.into_iter())
    }
    /// (N, 3) principal stretches per vertex (two in-plane, descending, then the normal one).
    fn stretches<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let s = self.state()?.stretches().py()?;
        to_numpy(py, s.into_iter().map(nalgebra::Vector3::from))
    }
    /// Kinetic energy (J).
    fn kinetic_energy(&self) -> PyResult<f64> {
        Ok(self.state()?.kinetic_energy())
    }
    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let m = self.lock();
        let p = m.params();
        let mat = material::to_py(py, p.material)?
            .bind(py)
            .repr()?
            .to_string();
        Ok(format!(
            "Membrane(vertices={}, triangles={}, thickness={}, density={}, material={mat}, bending={}, hourglass={}, neighbors={}, pinned={})",
            m.num_vertices(),
            m.mesh().triangles().len(),
            p.thickness,
            p.density,
            p.bending,
            p.hourglass,
            p.neighbors,
            m.pins().len()
        ))
    }
}
