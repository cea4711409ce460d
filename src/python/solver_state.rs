//! A solver's internal state ([`SolverState`]) as a dict of named numpy arrays, the form
//! `peridyn.save_state` writes as `internal_<name>` entries, and back, checked.

use numpy::PyReadonlyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::contact::{SavedRestGap, SavedRestGaps};
use crate::solve::{SavedGrainContact, SolverState};

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

/// Per grain contact with friction, its two particles `(i, j)`, (P, 2) int64.
const GRAIN_PAIRS: &str = "grain_contact_pairs";
/// Per grain contact, its friction multiplier `lambda_ij`, (P, 3) m.
const GRAIN_MULTIPLIERS: &str = "grain_contact_multipliers";

/// Every entry of the dict, in order.
const NAMES: [&str; 8] = [
    WARM_START,
    SEEDED,
    REACH,
    VERTICES,
    EDGE_EDGE,
    DISTANCES,
    GRAIN_PAIRS,
    GRAIN_MULTIPLIERS,
];
/// The entries of a dict saved before the grains' contact friction was (state files of
/// format version 2 and before): that friction starts from 0.
const CONTACT_NAMES: [&str; 6] = [WARM_START, SEEDED, REACH, VERTICES, EDGE_EDGE, DISTANCES];

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
    let contacts = &state.grain_contacts;
    let flat: Vec<i64> = contacts
        .iter()
        .flat_map(|c| c.particles.map(i64::from))
        .collect();
    let pairs = to_numpy_1d(py, flat).call_method1("reshape", ((contacts.len(), 2),))?;
    dict.set_item(GRAIN_PAIRS, pairs)?;
    dict.set_item(
        GRAIN_MULTIPLIERS,
        to_numpy(py, contacts.iter().map(|c| c.multiplier))?,
    )?;
    Ok(dict)
}

/// The state a dict from [`to_dict`] holds, checked for a solver whose membranes have
/// `vertices` vertices in all and whose particle bodies have `particles` particles. An empty
/// dict is the default state (nothing carried over: the next contact step seeds afresh);
/// otherwise every entry must be there, and no other, but for the grain contacts' two, which
/// a dict saved before them lacks (their friction then starts from 0).
pub fn from_dict(
    dict: &Bound<'_, PyDict>,
    vertices: usize,
    particles: usize,
) -> PyResult<SolverState> {
    if dict.is_empty() {
        return Ok(SolverState::default());
    }
    let has_grains = dict.contains(GRAIN_PAIRS)? || dict.contains(GRAIN_MULTIPLIERS)?;
    let names: &[&str] = if has_grains { &NAMES } else { &CONTACT_NAMES };
    exact_entries(dict, names, "the internal state (or none)")?;
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
    let grain_contacts = if has_grains {
        grain_contacts(&item(GRAIN_PAIRS)?, &item(GRAIN_MULTIPLIERS)?)?
    } else {
        Vec::new()
    };
    let state = SolverState {
        contact_warm_start: warm,
        contact_rest_gaps: seeded.then_some(SavedRestGaps { reach, gaps }),
        grain_contacts,
    };
    state.validate().map_err(to_py)?;
    state.check_against(vertices, particles).map_err(to_py)?;
    Ok(state)
}

/// The grain contacts of the entries `pairs` and `multipliers` (one row each per contact).
fn grain_contacts(
    pairs: &Bound<'_, PyAny>,
    multipliers: &Bound<'_, PyAny>,
) -> PyResult<Vec<SavedGrainContact>> {
    let pairs = integer_rows::<2>(pairs, GRAIN_PAIRS)?;
    let multipliers = vec3s(multipliers, GRAIN_MULTIPLIERS, None)?;
    if multipliers.len() != pairs.len() {
        return Err(PyValueError::new_err(format!(
            "{GRAIN_PAIRS} and {GRAIN_MULTIPLIERS} must describe the same contacts: they hold \
             {} and {}",
            pairs.len(),
            multipliers.len()
        )));
    }
    let mut contacts = Vec::with_capacity(pairs.len());
    for (k, (pair, &multiplier)) in pairs.iter().zip(&multipliers).enumerate() {
        let mut particles = [0u32; 2];
        for (slot, &index) in particles.iter_mut().zip(pair) {
            *slot = u32::try_from(index).map_err(|_| {
                PyValueError::new_err(format!(
                    "{GRAIN_PAIRS}[{k}] names particle {index}, not a particle index"
                ))
            })?;
        }
        contacts.push(SavedGrainContact {
            particles,
            multiplier,
        });
    }
    Ok(contacts)
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
