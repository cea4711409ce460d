//! A solver's internal state ([`SolverState`]) as a dict of named numpy arrays, the form
//! `peridyn.save_state` writes as `internal_<name>` entries, and back, checked.

use numpy::PyReadonlyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::contact::{SavedRestGap, SavedRestGaps};
use crate::solve::SolverState;

use super::arrays::{exact_entries, flags, integer_rows, real_array, to_numpy, to_numpy_1d, vec3s};
use super::errors::to_py;

/// Per membrane vertex, the warm start of the next contact local step, (N, 3) m.
const WARM_START: &str = "contact_warm_start";
/// Whether the rest gaps were seeded, 0-d bool.
const SEEDED: &str = "contact_rest_gaps_seeded";
/// The reach the gaps are scaled by, 0-d m.
const REACH: &str = "contact_rest_gap_reach";
/// Per gap, the pair's vertices, (G, 4) int64.
const VERTICES: &str = "contact_rest_gap_vertices";
/// Per gap, whether the pair is edge-edge (else point-triangle), (G,) bool.
const EDGE_EDGE: &str = "contact_rest_gap_edge_edge";
/// Per gap, the distance at which its barrier starts, (G,) m.
const DISTANCES: &str = "contact_rest_gap_distances";

/// Every entry of the dict, in order.
const NAMES: [&str; 6] = [WARM_START, SEEDED, REACH, VERTICES, EDGE_EDGE, DISTANCES];

/// `state` as a dict of every entry in [`NAMES`] (empty arrays and `seeded` false where there
/// is nothing yet).
pub fn to_dict<'py>(py: Python<'py>, state: SolverState) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    dict.set_item(
        WARM_START,
        to_numpy(py, state.contact_warm_start.into_iter())?,
    )?;
    let np = py.import("numpy")?;
    let seeded = state.contact_rest_gaps.is_some();
    let saved = state.contact_rest_gaps.unwrap_or_default();
    dict.set_item(SEEDED, np.call_method1("array", (seeded,))?)?;
    dict.set_item(REACH, np.call_method1("array", (saved.reach,))?)?;
    let flat: Vec<i64> = saved
        .gaps
        .iter()
        .flat_map(|g| g.vertices.map(i64::from))
        .collect();
    let vertices = to_numpy_1d(py, flat).call_method1("reshape", ((saved.gaps.len(), 4),))?;
    dict.set_item(VERTICES, vertices)?;
    let edge_edge: Vec<bool> = saved.gaps.iter().map(|g| g.edge_edge).collect();
    dict.set_item(EDGE_EDGE, to_numpy_1d(py, edge_edge))?;
    let distances: Vec<f64> = saved.gaps.iter().map(|g| g.distance).collect();
    dict.set_item(DISTANCES, to_numpy_1d(py, distances))?;
    Ok(dict)
}

/// The state a dict from [`to_dict`] holds, checked for a solver whose membranes have
/// `vertices` vertices in all. An empty dict is the default state (nothing carried over: the
/// next contact step seeds afresh); otherwise every entry must be there, and no other.
pub fn from_dict(dict: &Bound<'_, PyDict>, vertices: usize) -> PyResult<SolverState> {
    if dict.is_empty() {
        return Ok(SolverState::default());
    }
    exact_entries(dict, &NAMES, "the internal state (or none)")?;
    let item = |name: &str| dict.get_item(name).map(|v| v.expect("checked above"));
    let warm = vec3s(&item(WARM_START)?, WARM_START, None)?;
    let seeded = flag(&item(SEEDED)?, SEEDED)?;
    let reach = scalar(&item(REACH)?, REACH)?;
    let pairs = integer_rows::<4>(&item(VERTICES)?, VERTICES)?;
    let edge_edge = flags(&item(EDGE_EDGE)?, EDGE_EDGE)?;
    let distances: PyReadonlyArray1<f64> = real_array(&item(DISTANCES)?, DISTANCES)?
        .call_method1("reshape", (-1,))?
        .extract()?;
    let distances = distances.as_slice()?;
    let g = pairs.len();
    if edge_edge.len() != g || distances.len() != g {
        return Err(PyValueError::new_err(format!(
            "{VERTICES}, {EDGE_EDGE} and {DISTANCES} must describe the same gaps: they hold {g}, \
             {} and {}",
            edge_edge.len(),
            distances.len()
        )));
    }
    if !seeded && g > 0 {
        return Err(PyValueError::new_err(format!(
            "{SEEDED} is false but the state holds {g} rest gaps"
        )));
    }
    let mut gaps = Vec::with_capacity(g);
    for (k, ((v, &edge_edge), &distance)) in pairs.iter().zip(&edge_edge).zip(distances).enumerate()
    {
        let mut vertices_of_pair = [0u32; 4];
        for (slot, &index) in vertices_of_pair.iter_mut().zip(v) {
            if index < 0 || index as usize >= vertices {
                return Err(PyValueError::new_err(format!(
                    "{VERTICES}[{k}] names vertex {index}, but the membranes have {vertices}"
                )));
            }
            *slot = index as u32;
        }
        gaps.push(SavedRestGap {
            edge_edge,
            vertices: vertices_of_pair,
            distance,
        });
    }
    let state = SolverState {
        contact_warm_start: warm,
        contact_rest_gaps: seeded.then_some(SavedRestGaps { reach, gaps }),
    };
    state.validate().map_err(to_py)?;
    state.check_against(vertices).map_err(to_py)?;
    Ok(state)
}

/// A 0-d real array (or a number) as a float.
fn scalar(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<f64> {
    let arr = real_array(obj, name)?;
    let size: usize = arr.getattr("size")?.extract()?;
    // `real_array` makes at least one dimension: the input's own must be 0.
    let ndim: usize = obj
        .py()
        .import("numpy")?
        .call_method1("ndim", (obj,))?
        .extract()?;
    if size != 1 || ndim != 0 {
        return Err(PyValueError::new_err(format!(
            "{name} must be a single number"
        )));
    }
    arr.call_method0("item")?.extract()
}

/// A single boolean (0-d bool array or `bool`).
fn flag(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<bool> {
    let ndim: usize = obj
        .py()
        .import("numpy")?
        .call_method1("ndim", (obj,))?
        .extract()?;
    match flags(obj, name)?.as_slice() {
        [value] if ndim == 0 => Ok(*value),
        _ => Err(PyValueError::new_err(format!(
            "{name} must be a single boolean"
        ))),
    }
}
