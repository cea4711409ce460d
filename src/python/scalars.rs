//! Scalar arguments checked at the edge: a real number is a Python `int` or `float` or a numpy
//! scalar of a real or integer dtype (a 0-d array too); an integer is a Python `int` or a numpy
//! integer. Refused, with a `ValueError` naming the argument, the value and its type: `bool`
//! (True is not 1.0 here), complex numbers (their imaginary part would be dropped), strings
//! (even "1.5"), and integers that do not fit in 64 bits (never truncated).
//!
//! A string or a flag argument of any other type is a `TypeError` ([`Text`], [`Flag`]) whose
//! message names the argument and the type it takes.
//!
//! pyo3 names an argument only in an exception note, so [`Real`], [`Int`], [`Text`] and
//! [`Flag`] never fail to extract: they keep what was wrong, and `get(name)` raises it under
//! the argument's name.

use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyComplex, PyFloat, PyInt, PyString};

/// A real scalar argument: `get(name)` gives the value or a `ValueError` naming `name`.
#[derive(Debug, Clone)]
pub struct Real(Result<f64, String>);

/// An integer argument: `get(name)` gives the value or a `ValueError` naming `name`.
#[derive(Debug, Clone)]
pub struct Int(Result<i64, String>);

impl Real {
    /// A default value.
    pub const fn of(value: f64) -> Self {
        Self(Ok(value))
    }
    /// The value, or a `ValueError` saying why `name` is not a real number.
    pub fn get(&self, name: &str) -> PyResult<f64> {
        self.0
            .clone()
            .map_err(|why| PyValueError::new_err(format!("{name} must be a real number, {why}")))
    }
}

impl Int {
    /// A default value.
    pub const fn of(value: i64) -> Self {
        Self(Ok(value))
    }
    /// The value, or a `ValueError` saying why `name` is not a 64-bit integer.
    pub fn get(&self, name: &str) -> PyResult<i64> {
        self.0
            .clone()
            .map_err(|why| PyValueError::new_err(format!("{name} must be an integer, {why}")))
    }
}

/// A string argument (an option's name): `get(name)` gives it or a `TypeError` naming `name`.
#[derive(Debug, Clone)]
pub struct Text(Result<String, String>);

/// A flag argument (`True` or `False`; numpy's bool too): `get(name)` gives it or a
/// `TypeError` naming `name`. An integer is refused (1 is not True here).
#[derive(Debug, Clone)]
pub struct Flag(Result<bool, String>);

impl Text {
    /// A default value.
    pub fn of(value: &str) -> Self {
        Self(Ok(value.to_owned()))
    }
    /// The string, or a `TypeError` saying that `name` takes a str.
    pub fn get(&self, name: &str) -> PyResult<&str> {
        self.0
            .as_deref()
            .map_err(|why| PyTypeError::new_err(format!("{name} must be a str, {why}")))
    }
    /// The string of an argument that may be None, or a `TypeError` saying that `name` takes
    /// a str or None.
    pub fn get_optional<'a>(text: &'a Option<Self>, name: &str) -> PyResult<Option<&'a str>> {
        text.as_ref()
            .map(|t| {
                t.0.as_deref().map_err(|why| {
                    PyTypeError::new_err(format!("{name} must be a str or None, {why}"))
                })
            })
            .transpose()
    }
}

impl Flag {
    /// A default value.
    pub const fn of(value: bool) -> Self {
        Self(Ok(value))
    }
    /// The flag, or a `TypeError` saying that `name` takes a bool.
    pub fn get(&self, name: &str) -> PyResult<bool> {
        self.0.clone().map_err(|why| {
            PyTypeError::new_err(format!("{name} must be a bool (True or False), {why}"))
        })
    }
}

impl<'a, 'py> FromPyObject<'a, 'py> for Text {
    type Error = PyErr;
    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        kept(&obj).map(Self)
    }
}

impl<'a, 'py> FromPyObject<'a, 'py> for Flag {
    type Error = PyErr;
    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        kept(&obj).map(Self)
    }
}

/// `obj` as a `V`, or why not ([`described`]) for the keyword's own `TypeError` later.
fn kept<'py, V: for<'a> FromPyObject<'a, 'py>>(
    obj: &Bound<'py, PyAny>,
) -> PyResult<std::result::Result<V, String>> {
    Ok(match obj.extract::<V>() {
        Ok(value) => Ok(value),
        Err(_) => Err(described(obj)?),
    })
}

impl<'a, 'py> FromPyObject<'a, 'py> for Real {
    type Error = PyErr;
    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        Ok(Self(real(&obj)?))
    }
}

impl<'a, 'py> FromPyObject<'a, 'py> for Int {
    type Error = PyErr;
    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        Ok(Self(int(&obj)?))
    }
}

/// `repr(obj)` and its type's name, for messages (the name alone if its `repr` raises).
fn described(obj: &Bound<'_, PyAny>) -> PyResult<String> {
    let ty = obj.get_type().name()?;
    Ok(match obj.repr() {
        Ok(repr) => format!("got {ty} {repr}"),
        Err(_) => format!("got a {ty}"),
    })
}

/// The numpy dtype kind of a numpy scalar or array (None for anything else).
fn dtype_kind(obj: &Bound<'_, PyAny>) -> PyResult<Option<(String, String, usize)>> {
    let Ok(dtype) = obj.getattr("dtype") else {
        return Ok(None);
    };
    let Ok(kind) = dtype.getattr("kind") else {
        return Ok(None);
    };
    let ndim: usize = obj.getattr("ndim").and_then(|n| n.extract()).unwrap_or(0);
    Ok(Some((kind.extract()?, dtype.str()?.to_string(), ndim)))
}

/// Why `obj` is not a real number (Err of the inner result), or its value.
pub fn real(obj: &Bound<'_, PyAny>) -> PyResult<Result<f64, String>> {
    if obj.is_instance_of::<PyBool>() {
        return Ok(Err(format!("got bool {}", obj.repr()?)));
    }
    if let Ok(f) = obj.cast::<PyFloat>() {
        return Ok(Ok(f.value()));
    }
    if obj.is_instance_of::<PyInt>() {
        return Ok(obj.extract::<f64>().map_err(|_| {
            format!(
                "got int {} (beyond the range of float64)",
                obj.repr().map(|r| r.to_string()).unwrap_or_default()
            )
        }));
    }
    if obj.is_instance_of::<PyComplex>() && dtype_kind(obj)?.is_none() {
        return Ok(Err(format!(
            "{} (its imaginary part would be lost)",
            described(obj)?
        )));
    }
    if obj.is_instance_of::<PyString>() {
        return Ok(Err(format!("{} (strings are not parsed)", described(obj)?)));
    }
    if let Some((kind, dtype, ndim)) = dtype_kind(obj)? {
        if ndim != 0 {
            return Ok(Err(format!(
                "got an array of dtype {dtype} with {ndim} dimension(s), not a scalar"
            )));
        }
        return Ok(match kind.as_str() {
            "f" | "i" | "u" => obj.extract::<f64>().map_err(|e| e.to_string()),
            "c" => Err(format!(
                "got dtype {dtype} {} (its imaginary part would be lost)",
                obj.repr()?
            )),
            _ => Err(format!("got dtype {dtype} {}", obj.repr()?)),
        });
    }
    // Anything else that Python itself takes as a real number (fractions.Fraction,
    // decimal.Decimal, objects with __float__).
    Ok(obj
        .extract::<f64>()
        .map_err(|_| described(obj).unwrap_or_else(|e| e.to_string())))
}

/// Why `obj` is not a 64-bit integer (Err of the inner result), or its value.
pub fn int(obj: &Bound<'_, PyAny>) -> PyResult<Result<i64, String>> {
    if obj.is_instance_of::<PyBool>() {
        return Ok(Err(format!("got bool {}", obj.repr()?)));
    }
    if obj.is_instance_of::<PyInt>() {
        return Ok(obj.extract::<i64>().map_err(|_| {
            format!(
                "got {} which does not fit in a 64-bit integer",
                obj.repr().map(|r| r.to_string()).unwrap_or_default()
            )
        }));
    }
    if let Some((kind, dtype, ndim)) = dtype_kind(obj)? {
        if ndim == 0 && (kind == "i" || kind == "u") {
            let value = obj.call_method0("__int__")?;
            return int(&value);
        }
        return Ok(Err(format!("got dtype {dtype} {}", obj.repr()?)));
    }
    Ok(Err(described(obj)?))
}
