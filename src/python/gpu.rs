//! `peridyn.gpu_info()`: the adapter the GPU backend would use.

use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::errors::IntoPyResult;

/// The adapter the GPU backend would use, as a dict; raises RuntimeError naming what is
/// missing when there is none.
#[pyfunction]
pub fn gpu_info(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let info = py.detach(crate::gpu::gpu_info).py()?;
    let d = PyDict::new(py);
    d.set_item("name", info.name)?;
    d.set_item("backend", info.backend)?;
    d.set_item("device_type", info.device_type)?;
    d.set_item("driver", info.driver)?;
    d.set_item("f64", info.f64)?;
    let limits = PyDict::new(py);
    for (k, v) in info.limits {
        limits.set_item(k, v)?;
    }
    d.set_item("limits", limits)?;
    Ok(d)
}
