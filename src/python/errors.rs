//! Core errors as Python exceptions, in one place.

use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::PyErr;

use crate::error::Error;

pyo3::create_exception!(
    _core,
    DivergenceError,
    PyRuntimeError,
    "A time step produced non-finite positions; the bodies were left at their last good state."
);

/// Maps a core error to its Python exception type.
pub fn to_py(err: Error) -> PyErr {
    match err {
        Error::InvalidInput(msg) => PyValueError::new_err(msg),
        e @ Error::Diverged { .. } => DivergenceError::new_err(e.to_string()),
        Error::Gpu(msg) => PyRuntimeError::new_err(msg),
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
