//! numpy in and out. Inputs of any real or integer dtype (and nested sequences of numbers) are
//! converted by numpy itself; everything else is refused with a `ValueError` naming the argument
//! and the dtype, before numpy could convert it with a loss: complex (imaginary parts dropped),
//! bool, strings (numpy parses "1.5"), objects; integers that do not fit in 64 bits are refused
//! with their value, never wrapped. Shapes are checked here with messages that name the argument.

use nalgebra::Vector3;
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// `obj` as a float64 contiguous array, refusing every dtype that is not real or integer.
pub fn real_array<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Bound<'py, PyAny>> {
    let np = obj.py().import("numpy")?;
    let arr = np
        .call_method1("asarray", (obj,))
        .map_err(|e| PyValueError::new_err(format!("{name} must be a numeric array: {e}")))?;
    let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
    if !matches!(kind.as_str(), "f" | "i" | "u") {
        let dtype = arr.getattr("dtype")?.str()?.to_string();
        let why = match kind.as_str() {
            "c" => " (complex: the imaginary parts would be lost)",
            "b" => " (bool)",
            "U" | "S" => " (strings are not parsed as numbers)",
            "O" => " (objects: mixed types, None, or integers beyond 64 bits)",
            _ => "",
        };
        return Err(PyValueError::new_err(format!(
            "{name} must hold real numbers, got dtype {dtype}{why}"
        )));
    }
    np.call_method1("ascontiguousarray", (arr, "float64"))
}

/// An (n, 3) real array (n checked when given) as vectors.
pub fn vec3s(
    obj: &Bound<'_, PyAny>,
    name: &str,
    rows: Option<usize>,
) -> PyResult<Vec<Vector3<f64>>> {
    let arr = real_array(obj, name)?;
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
    let arr = real_array(obj, name)?;
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

/// Checks that an array holds integers (any width or signedness) that fit in int64 and
/// returns it as int64; the message of one that does not fit names it and its position.
fn integers<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Bound<'py, PyAny>> {
    let np = obj.py().import("numpy")?;
    let arr = np
        .call_method1("asarray", (obj,))
        .map_err(|e| PyValueError::new_err(format!("{name} must be an integer array: {e}")))?;
    let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
    let size: usize = arr.getattr("size")?.extract()?;
    let flat = || arr.call_method1("reshape", (-1,));
    if kind == "O" {
        // Python ints beyond 64 bits make an object array: name the first that does not fit.
        for (k, item) in flat()?.try_iter()?.enumerate() {
            if let Err(why) = super::scalars::int(&item?)? {
                return Err(PyValueError::new_err(format!(
                    "{name} must hold 64-bit integers: entry {k} {why}"
                )));
            }
        }
    } else if kind == "u" && size > 0 {
        let max: u64 = arr.call_method0("max")?.extract()?;
        if max > i64::MAX as u64 {
            let k: usize = arr.call_method0("argmax")?.extract()?;
            return Err(PyValueError::new_err(format!(
                "{name} must hold 64-bit signed integers: entry {k} is {max}, which does not fit"
            )));
        }
    }
    if !(kind == "i" || kind == "u" || kind == "O" || size == 0) {
        return Err(PyValueError::new_err(format!(
            "{name} must hold integers, got dtype {}",
            arr.getattr("dtype")?.str()?
        )));
    }
    np.call_method1("ascontiguousarray", (arr, "int64"))
}

/// An (m, 3) integer array.
pub fn triangles(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<[i64; 3]>> {
    integer_rows::<3>(obj, name)
}

/// An (m, K) integer array, by rows.
pub fn integer_rows<const K: usize>(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<[i64; K]>> {
    let arr = integers(obj, name)?;
    let shape: Vec<usize> = arr.getattr("shape")?.extract()?;
    if !(shape.len() == 2 && shape[1] == K) {
        return Err(PyValueError::new_err(format!(
            "{name} must have shape (M, {K}), got {shape:?}"
        )));
    }
    let arr: PyReadonlyArray2<i64> = arr.extract()?;
    Ok(arr
        .as_array()
        .outer_iter()
        .map(|r| std::array::from_fn(|k| r[k]))
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

/// How far (entry by entry, `|R^T R - I|`) a rotation matrix given by the user may be from
/// orthonormal: rotations rounded to float32 (about 1e-7) or printed with 7 digits pass and are
/// re-orthonormalised; anything further is left to the core, which refuses it.
pub const ROTATION_TOLERANCE: f64 = 1e-6;

/// A (3, 3) rotation matrix by rows: one orthonormal within [`ROTATION_TOLERANCE`] but not
/// within the core's 1e-9 is replaced by the nearest orthonormal matrix (the orthogonal factor of its polar decomposition); the
/// core checks the result (finite, orthonormal, det +1) and names what is wrong.
pub fn rotation_rows(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<[[f64; 3]; 3]> {
    let m = vec3s(obj, name, Some(3))?;
    let rows = [0, 1, 2].map(|k| [m[k].x, m[k].y, m[k].z]);
    let r = nalgebra::Matrix3::from_row_slice(&rows.concat());
    if !r.iter().all(|c| c.is_finite()) {
        return Ok(rows);
    }
    let deviation = (r.transpose() * r - nalgebra::Matrix3::identity())
        .abs()
        .max();
    // Within the core's own tolerance (1e-9) the matrix is kept bit for bit: a pose read back
    // and set again (a restored simulation) must not change.
    if !(1e-9..ROTATION_TOLERANCE).contains(&deviation) || r.determinant() <= 0.0 {
        return Ok(rows);
    }
    let svd = r.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Ok(rows);
    };
    let q = u * v_t;
    Ok([0, 1, 2].map(|i| [q[(i, 0)], q[(i, 1)], q[(i, 2)]]))
}

/// Checks that `dict` holds exactly the string keys `names` (no other, none missing), naming
/// what is unknown and what is missing; `what` says whose entries they are in the message.
pub fn exact_entries(dict: &Bound<'_, PyDict>, names: &[&str], what: &str) -> PyResult<()> {
    entries_of(dict, names, &[], what)
}

/// [`exact_entries`] where the keys `optional` (among `names`) may be missing: entries added
/// after dicts without them were written.
pub fn entries_of(
    dict: &Bound<'_, PyDict>,
    names: &[&str],
    optional: &[&str],
    what: &str,
) -> PyResult<()> {
    let mut keys = Vec::with_capacity(dict.len());
    for key in dict.keys() {
        keys.push(key.extract::<String>().map_err(|_| {
            PyValueError::new_err(format!("{what} entry names must be strings, got {key}"))
        })?);
    }
    let unknown: Vec<&String> = keys
        .iter()
        .filter(|k| !names.contains(&k.as_str()))
        .collect();
    let missing: Vec<&&str> = names
        .iter()
        .filter(|n| !optional.contains(n) && !keys.iter().any(|k| k == *n))
        .collect();
    if unknown.is_empty() && missing.is_empty() {
        return Ok(());
    }
    Err(PyValueError::new_err(format!(
        "{what} must hold exactly the entries {names:?}: unknown {unknown:?}, missing {missing:?}"
    )))
}

/// A bool array (of any shape) as a flat vector; other dtypes are refused.
pub fn flags(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<bool>> {
    let arr = obj.py().import("numpy")?.call_method1("asarray", (obj,))?;
    let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
    let size: usize = arr.getattr("size")?.extract()?;
    if kind != "b" && size > 0 {
        return Err(PyValueError::new_err(format!(
            "{name} must hold booleans, got dtype {}",
            arr.getattr("dtype")?.str()?
        )));
    }
    let flat: PyReadonlyArray1<bool> = arr
        .call_method1("astype", ("bool",))?
        .call_method1("reshape", (-1,))?
        .extract()?;
    Ok(flat.as_slice()?.to_vec())
}

/// A one-dimensional real array as floats; other shapes are refused, naming `name`.
pub fn reals_1d(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<f64>> {
    let arr = real_array(obj, name)?;
    let ndim: usize = arr.getattr("ndim")?.extract()?;
    if ndim != 1 {
        return Err(PyValueError::new_err(format!(
            "{name} must be one-dimensional, got {ndim} dimensions"
        )));
    }
    arr.extract()
}
