//! A plastic particle body's current reference bonds ([`RestBonds`]) as a dict of named numpy
//! arrays and back, checked: the form `Particles.rest_bonds` reads and sets, and
//! `peridyn.save_state` writes as entries `bonds_<name>_<body>`.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::particles::RestBonds;

use super::arrays::{entries_of, indices, reals_1d, to_numpy, to_numpy_1d, vec3s};

/// Per particle `p` its bonds `offsets[p]..offsets[p + 1]`, (N + 1,) int64.
const OFFSETS: &str = "offsets";
/// Per bond its neighbour, (B,) int64, increasing within each particle's bonds.
const NEIGHBOURS: &str = "neighbours";
/// Per bond its reference vector `X`, (B, 3) m.
const VECTORS: &str = "vectors";
/// Per bond the reference length its weight and springs were set at, (B,) m.
const BORN: &str = "born";
/// Per particle the accumulated plastic strain, (N,) dimensionless.
const PLASTIC_STRAIN: &str = "plastic_strain";
/// Per particle the volume its reference bonds span over its rest volume, (N,) dimensionless;
/// optional (dicts written before it lack it): 1 for every particle, as for the bonds of the
/// rest state.
pub const VOLUME: &str = "volume";

/// Every entry of the dict, in order.
pub const NAMES: [&str; 6] = [OFFSETS, NEIGHBOURS, VECTORS, BORN, PLASTIC_STRAIN, VOLUME];

/// `bonds` as a dict of every entry in [`NAMES`].
pub fn to_dict<'py>(py: Python<'py>, bonds: RestBonds) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    let ints = |v: &[u32]| to_numpy_1d(py, v.iter().map(|&o| o as i64).collect());
    dict.set_item(OFFSETS, ints(&bonds.offsets))?;
    dict.set_item(NEIGHBOURS, ints(&bonds.indices))?;
    dict.set_item(VECTORS, to_numpy(py, bonds.xi.into_iter())?)?;
    dict.set_item(BORN, to_numpy_1d(py, bonds.born))?;
    dict.set_item(PLASTIC_STRAIN, to_numpy_1d(py, bonds.plastic_strain))?;
    dict.set_item(VOLUME, to_numpy_1d(py, bonds.volume))?;
    Ok(dict)
}

/// The bonds a dict from [`to_dict`] holds (every entry but the optional [`VOLUME`], no
/// other; shapes and dtypes checked here, the bonds themselves by [`RestBonds::check`]
/// against the body).
pub fn from_dict(dict: &Bound<'_, PyDict>) -> PyResult<RestBonds> {
    entries_of(dict, &NAMES, &[VOLUME], "rest bonds")?;
    let item = |name: &str| dict.get_item(name).map(|v| v.expect("checked above"));
    let unsigned = |name: &str| -> PyResult<Vec<u32>> {
        indices(&item(name)?, name)?
            .into_iter()
            .enumerate()
            .map(|(k, v)| {
                u32::try_from(v).map_err(|_| {
                    PyValueError::new_err(format!("{name}[{k}] = {v} is not an index >= 0"))
                })
            })
            .collect()
    };
    let reals = |name: &str| reals_1d(&item(name)?, name);
    let offsets = unsigned(OFFSETS)?;
    let volume = match dict.get_item(VOLUME)? {
        Some(v) => reals_1d(&v, VOLUME)?,
        None => vec![1.0; offsets.len().saturating_sub(1)],
    };
    Ok(RestBonds {
        offsets,
        indices: unsigned(NEIGHBOURS)?,
        xi: vec3s(&item(VECTORS)?, VECTORS, None)?,
        born: reals(BORN)?,
        plastic_strain: reals(PLASTIC_STRAIN)?,
        volume,
    })
}
