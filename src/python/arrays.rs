//! numpy in and out. Inputs of any real or integer dtype (and nested sequences) are converted
//! by numpy itself; shapes are checked here with messages that name the argument.

use nalgebra::Vector3;
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// `numpy.ascontiguousarray(obj, dtype)`.
fn as_contiguous<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    dtype: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let np = obj.py().import("numpy")?;
    np.call_method1("ascontiguousarray", (obj, dtype))
        .map_err(|e| PyValueError::new_err(format!("{name} must be a numeric array: {e}")))
}

/// An (n, 3) real array (n checked when given) as vectors.
pub fn vec3s(
    obj: &Bound<'_, PyAny>,
    name: &str,
    rows: Option<usize>,
) -> PyResult<Vec<Vector3<f64>>> {
    let arr = as_contiguous(obj, name, "float64")?;
    let shape: Vec<usize> = arr.getattr("shape")?.extract()?;
    let ok = shape.len() == 2 && shape[1] == 3 && rows.is_none_or(|n| shape[0] == n);
    if !ok {
        let want = rows.map_or("(N, 3)".to_string(), |n| format!("({n}, 3)"));
        return Err(PyValueError::new_err(format!(
            "{name} must have shape {want}, got {shape:?}"
        )));
    }
    let arr: PyReadonlyArray2<f64> = arr.extract()?;
    let view = arr.as_array();
    Ok(view
        .outer_iter()
        .map(|r| Vector3::new(r[0], r[1], r[2]))
        .collect())
}

/// A 3-vector parameter (tuple, list or array), finite.
pub fn vec3(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<[f64; 3]> {
    let arr = as_contiguous(obj, name, "float64")?;
    let shape: Vec<usize> = arr.getattr("shape")?.extract()?;
    if shape != [3] {
        return Err(PyValueError::new_err(format!(
            "{name} must have 3 components, got shape {shape:?}"
        )));
    }
    let arr: PyReadonlyArray1<f64> = arr.extract()?;
    let s = arr.as_slice()?;
    Ok([s[0], s[1], s[2]])
}

/// Checks that an array holds integers (any width or signedness) and returns it as int64.
fn integers<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Bound<'py, PyAny>> {
    let np = obj.py().import("numpy")?;
    let arr = np.call_method1("asarray", (obj,))?;
    let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
    let size: usize = arr.getattr("size")?.extract()?;
    if !(kind == "i" || kind == "u" || size == 0) {
        return Err(PyValueError::new_err(format!(
            "{name} must hold integers, got dtype {}",
            arr.getattr("dtype")?.str()?
        )));
    }
    np.call_method1("ascontiguousarray", (arr, "int64"))
}

/// An (m, 3) integer array.
pub fn triangles(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<[i64; 3]>> {
    let arr = integers(obj, name)?;
    let shape: Vec<usize> = arr.getattr("shape")?.extract()?;
    if !(shape.len() == 2 && shape[1] == 3) {
        return Err(PyValueError::new_err(format!(
            "{name} must have shape (M, 3), got {shape:?}"
        )));
    }
    let arr: PyReadonlyArray2<i64> = arr.extract()?;
    Ok(arr
        .as_array()
        .outer_iter()
        .map(|r| [r[0], r[1], r[2]])
        .collect())
}

/// A 1-D integer array (a scalar counts as one index).
pub fn indices(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<i64>> {
    let arr = integers(obj, name)?;
    let arr = obj
        .py()
        .import("numpy")?
        .call_method1("atleast_1d", (arr,))?;
    let shape: Vec<usize> = arr.getattr("shape")?.extract()?;
    if shape.len() != 1 {
        return Err(PyValueError::new_err(format!(
            "{name} must be one-dimensional, got shape {shape:?}"
        )));
    }
    let arr: PyReadonlyArray1<i64> = arr.extract()?;
    Ok(arr.as_slice()?.to_vec())
}

/// Vectors as a new (n, 3) float64 array.
pub fn to_numpy<'py>(
    py: Python<'py>,
    values: impl ExactSizeIterator<Item = Vector3<f64>>,
) -> PyResult<Bound<'py, PyAny>> {
    let n = values.len();
    let mut flat = Vec::with_capacity(3 * n);
    for v in values {
        flat.extend_from_slice(v.as_slice());
    }
    Ok(PyArray1::from_vec(py, flat).reshape([n, 3])?.into_any())
}

/// Scalars as a new 1-D array.
pub fn to_numpy_1d<'py, T: numpy::Element>(py: Python<'py>, values: Vec<T>) -> Bound<'py, PyAny> {
    PyArray1::from_vec(py, values).into_any()
}
