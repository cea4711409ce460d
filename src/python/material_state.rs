//! A particle body's material state ([`MaterialState`]) as a flat dict of named numpy arrays
//! and back, checked: the form `Particles.material_state` reads and sets, and
//! `peridyn.save_state` writes as entries `material_<name>_<body>`. An optional part is an
//! empty array when absent.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::particles::{DensitySolver, Elastic, MaterialState, ViscoelasticFluid};

use super::arrays::{entries_of, flags, reals_1d, to_numpy, to_numpy_1d, vec3s};
use super::rest_bonds;

/// `[0, mu, lam]` (Pa) for `Elastic(mu=, lam=)`, `[1, E, nu]` (Pa, 1) for `from_young`.
const ELASTIC: &str = "elastic";
/// The fluid's parameters in the order of [`fluid_numbers`], or empty.
const FLUID: &str = "fluid";
/// The horizon (m) as one number, or empty for the default.
const HORIZON: &str = "horizon";
/// The reference positions, (N, 3) m.
const REFERENCE: &str = "reference";
/// Per particle whether it is a fluid particle, (N,) bool, or empty.
const FLUID_MASK: &str = "fluid_mask";
/// A sand body's saturations, (N,), or empty.
const WETTED: &str = "wetted";
/// A mixed body's bonds: the entries of `Particles.rest_bonds` with this prefix (all empty
/// for a body of one material).
const REGION: &str = "region_";

/// The entry names, the region bonds' included.
fn names() -> Vec<String> {
    let mut names: Vec<String> = [ELASTIC, FLUID, HORIZON, REFERENCE, FLUID_MASK, WETTED]
        .map(String::from)
        .to_vec();
    names.extend(rest_bonds::NAMES.iter().map(|n| format!("{REGION}{n}")));
    names
}

/// A fluid's parameters as numbers: viscosity (Pa s), density iterations, density tolerance,
/// relaxation, redistribution, redistribution iterations, shear modulus (Pa), yield stress
/// (Pa; 0 for the default), adhesion (0 or 1), density solver (0 Jacobi, 1 conjugate
/// gradients; absent in states written before it, which were Jacobi), bulk modulus (Pa; 0 for
/// the default; absent in states written before it), surface tension (N/m; absent in states
/// written before it, which had none), plastic viscosity (Pa s; absent in states written
/// before it, which were rate-independent).
fn fluid_numbers(f: &ViscoelasticFluid) -> Vec<f64> {
    let ViscoelasticFluid {
        viscosity,
        density_iterations,
        density_tolerance,
        relaxation,
        redistribution,
        redistribution_iterations,
        shear_modulus,
        yield_stress,
        adhesion,
        density_solver,
        bulk_modulus,
        surface_tension,
        plastic_viscosity,
    } = *f;
    vec![
        viscosity,
        density_iterations as f64,
        density_tolerance,
        relaxation,
        redistribution,
        redistribution_iterations as f64,
        shear_modulus,
        yield_stress.unwrap_or(0.0),
        f64::from(u8::from(adhesion)),
        f64::from(u8::from(
            density_solver == DensitySolver::ConjugateGradients,
        )),
        bulk_modulus.unwrap_or(0.0),
        surface_tension,
        plastic_viscosity,
    ]
}

/// The fluid [`fluid_numbers`] wrote (its parameters checked by the core).
fn fluid_from(v: &[f64]) -> PyResult<ViscoelasticFluid> {
    let count = |x: f64, name: &str| -> PyResult<usize> {
        if x >= 0.0 && x.fract() == 0.0 && x <= u32::MAX as f64 {
            Ok(x as usize)
        } else {
            Err(PyValueError::new_err(format!(
                "{FLUID}: {name} must be a whole number >= 0, got {x}"
            )))
        }
    };
    let (v, plastic_viscosity) = match v {
        [head @ .., eta] if v.len() == 13 => (head, *eta),
        _ => (v, 0.0),
    };
    let (v, surface_tension) = match v {
        [head @ .., sigma] if v.len() == 12 => (head, *sigma),
        _ => (v, 0.0),
    };
    let (v, bulk_modulus) = match v {
        [head @ .., bulk] if v.len() == 11 => (head, *bulk),
        _ => (v, 0.0),
    };
    let (v, solver) = match v {
        [head @ .., solver] if v.len() == 10 => (head, *solver),
        _ => (v, 0.0),
    };
    let &[viscosity, iterations, density_tolerance, relaxation, redistribution, passes, shear_modulus, yield_stress, adhesion] =
        v
    else {
        return Err(PyValueError::new_err(format!(
            "{FLUID} must hold 13 numbers (12 before the plastic viscosity, 11 before the surface tension, 10 before the bulk modulus, 9 before the density solver) or none, got {}",
            v.len()
        )));
    };
    let density_solver = match solver {
        0.0 => DensitySolver::Jacobi,
        1.0 => DensitySolver::ConjugateGradients,
        _ => {
            return Err(PyValueError::new_err(format!(
                "{FLUID}: the density solver must be 0 or 1, got {solver}"
            )))
        }
    };
    if adhesion != 0.0 && adhesion != 1.0 {
        return Err(PyValueError::new_err(format!(
            "{FLUID}: adhesion must be 0 or 1, got {adhesion}"
        )));
    }
    Ok(ViscoelasticFluid {
        viscosity,
        density_iterations: count(iterations, "density_iterations")?,
        density_tolerance,
        relaxation,
        redistribution,
        redistribution_iterations: count(passes, "redistribution_iterations")?,
        shear_modulus,
        yield_stress: (yield_stress != 0.0).then_some(yield_stress),
        adhesion: adhesion == 1.0,
        density_solver,
        bulk_modulus: (bulk_modulus != 0.0).then_some(bulk_modulus),
        surface_tension,
        plastic_viscosity,
    })
}

/// `state` as a dict of every entry (see the module's doc).
pub fn to_dict<'py>(py: Python<'py>, state: MaterialState) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    let elastic = match state.elastic {
        Elastic::Paper { mu, lam } => vec![0.0, mu, lam],
        Elastic::Young { e, nu } => vec![1.0, e, nu],
    };
    dict.set_item(ELASTIC, to_numpy_1d(py, elastic))?;
    let fluid = state.fluid.as_ref().map_or_else(Vec::new, fluid_numbers);
    dict.set_item(FLUID, to_numpy_1d(py, fluid))?;
    dict.set_item(
        HORIZON,
        to_numpy_1d(py, state.horizon.into_iter().collect()),
    )?;
    dict.set_item(REFERENCE, to_numpy(py, state.reference.into_iter())?)?;
    dict.set_item(
        FLUID_MASK,
        to_numpy_1d(py, state.fluid_mask.unwrap_or_default()),
    )?;
    dict.set_item(WETTED, to_numpy_1d(py, state.wetted.unwrap_or_default()))?;
    let bonds = state.region_bonds.unwrap_or(crate::particles::RestBonds {
        offsets: Vec::new(),
        indices: Vec::new(),
        xi: Vec::new(),
        born: Vec::new(),
        plastic_strain: Vec::new(),
        volume: Vec::new(),
    });
    for (name, value) in rest_bonds::to_dict(py, bonds)?.iter() {
        dict.set_item(format!("{REGION}{}", name.extract::<String>()?), value)?;
    }
    Ok(dict)
}

/// The state a dict from [`to_dict`] holds (every entry, the region bonds' volume ratios
/// optional as in [`rest_bonds::from_dict`], no other; shapes and dtypes checked
/// here, the state itself by the core against the body).
pub fn from_dict(dict: &Bound<'_, PyDict>) -> PyResult<MaterialState> {
    let names = names();
    let refs: Vec<&str> = names.iter().map(String::as_str).collect();
    let optional = format!("{REGION}{}", rest_bonds::VOLUME);
    entries_of(dict, &refs, &[optional.as_str()], "material state")?;
    let item = |name: &str| dict.get_item(name).map(|v| v.expect("checked above"));
    let reals = |name: &str| reals_1d(&item(name)?, name);
    let elastic = match reals(ELASTIC)?.as_slice() {
        &[0.0, mu, lam] => Elastic::Paper { mu, lam },
        &[1.0, e, nu] => Elastic::Young { e, nu },
        other => {
            return Err(PyValueError::new_err(format!(
                "{ELASTIC} must be [0, mu, lam] or [1, E, nu], got {other:?}"
            )))
        }
    };
    let fluid = match reals(FLUID)?.as_slice() {
        [] => None,
        v => Some(fluid_from(v)?),
    };
    let horizon = match reals(HORIZON)?.as_slice() {
        [] => None,
        &[h] => Some(h),
        other => {
            return Err(PyValueError::new_err(format!(
                "{HORIZON} must hold one number or none, got {}",
                other.len()
            )))
        }
    };
    let mask = flags(&item(FLUID_MASK)?, FLUID_MASK)?;
    let wetted = reals(WETTED)?;
    let region = PyDict::new(dict.py());
    for name in rest_bonds::NAMES {
        if let Some(value) = dict.get_item(format!("{REGION}{name}"))? {
            region.set_item(name, value)?;
        }
    }
    let bonds = rest_bonds::from_dict(&region)?;
    Ok(MaterialState {
        elastic,
        fluid,
        horizon,
        reference: vec3s(&item(REFERENCE)?, REFERENCE, None)?,
        fluid_mask: (!mask.is_empty()).then_some(mask),
        region_bonds: (!bonds.offsets.is_empty()).then_some(bonds),
        wetted: (!wetted.is_empty()).then_some(wetted),
    })
}
