//! The Python edge: pyo3 wrappers, numpy conversion, argument validation and error bridging.
//! Nothing outside this module (and `lib.rs`) imports pyo3 or numpy.

mod arrays;
mod body;
mod collider;
mod contact;
mod elastic;
mod errors;
mod fluid;
mod gpu;
mod granular;
mod material;
mod material_state;
mod membrane;
mod options;
mod owner;
mod particle_body;
mod particles;
mod pins;
mod plasticity;
mod resolution;
mod rest_bonds;
mod scalars;
mod solver;
mod solver_state;
mod step_stats;
mod thin;

use pyo3::prelude::*;

/// Adds every class, function and exception of `peridyn._core` to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add(
        "DivergenceError",
        m.py().get_type::<errors::DivergenceError>(),
    )?;
    m.add(
        "PrecisionWarning",
        m.py().get_type::<errors::PrecisionWarning>(),
    )?;
    m.add_class::<material::PyStretchA3>()?;
    m.add_class::<material::PyNeoHookean>()?;
    m.add_class::<membrane::PyMembrane>()?;
    m.add_class::<elastic::PyElastic>()?;
    m.add_class::<particle_body::PyParticles>()?;
    m.add_class::<plasticity::PyDruckerPrager>()?;
    m.add_class::<fluid::PyViscoelasticFluid>()?;
    m.add_class::<granular::PyGranular>()?;
    m.add_class::<collider::PyCollider>()?;
    m.add_class::<collider::PyPlane>()?;
    m.add_class::<collider::PySphere>()?;
    m.add_class::<collider::PyBox>()?;
    m.add_class::<collider::PyCapsule>()?;
    m.add_class::<collider::PyMeshCollider>()?;
    m.add_class::<solver::PySolver>()?;
    m.add_class::<step_stats::PyStepStats>()?;
    m.add_class::<contact::PyContact>()?;
    m.add_submodule(&contact::module(m.py())?)?;
    m.add_function(wrap_pyfunction!(gpu::gpu_info, m)?)?;
    m.add_function(wrap_pyfunction!(particles::sample_volume, m)?)?;
    m.add_function(wrap_pyfunction!(particles::sample_surface, m)?)?;
    Ok(())
}
