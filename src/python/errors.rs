//! Core errors as Python exceptions, in one place.

use pyo3::exceptions::{PyRuntimeError, PyUserWarning, PyValueError};
use pyo3::PyErr;

use crate::error::Error;

pyo3::create_exception!(
    _core,
    DivergenceError,
    PyRuntimeError,
    "A time step produced non-finite positions; the bodies were left at their last good state."
);

pyo3::create_exception!(
    _core,
    PrecisionWarning,
    PyUserWarning,
    "The solver's floating-point precision cannot hold what the simulation asks of it: \
     coordinates so far from the origin that the motion of one step is below their resolution."
);

/// Maps a core error to its Python exception type.
pub fn to_py(err: Error) -> PyErr {
    match err {
        Error::InvalidInput(msg) => PyValueError::new_err(msg),
        e @ Error::Diverged { .. } => DivergenceError::new_err(e.to_string()),
        Error::Gpu(msg) => PyRuntimeError::new_err(msg),
    }
}

/// Runs `f`, turning a Rust panic (a bug: every input is validated before it reaches the
/// core) into a `RuntimeError` instead of letting it unwind into Python.
pub fn guard<T>(what: &str, f: impl FnOnce() -> crate::error::Result<T>) -> pyo3::PyResult<T> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(result) => result.map_err(to_py),
        Err(payload) => {
            let detail = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            Err(PyRuntimeError::new_err(format!(
                "internal error in {what} (please report it with the input that caused it): {detail}"
            )))
        }
    }
}

/// `?`-friendly conversion of core results.
pub trait IntoPyResult<T> {
    fn py(self) -> pyo3::PyResult<T>;
}

impl<T> IntoPyResult<T> for crate::error::Result<T> {
    fn py(self) -> pyo3::PyResult<T> {
        self.map_err(to_py)
    }
}
