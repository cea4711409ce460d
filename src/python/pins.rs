//! The pin methods `Membrane` and `Particles` share (`pin`, `unpin`, `pinned`, `pin_targets`):
//! argument conversion and checks written once, over the [`PinnedPoints`] both cores offer.
//! What pinning means stays with each body (a particle body also pins its ghost layers).

use std::collections::BTreeMap;
use std::ops::DerefMut;

use nalgebra::Vector3;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::error::Result;
use crate::membrane::Membrane;
use crate::particles::Particles;

use super::arrays::{indices, to_numpy, to_numpy_1d, vec3s};
use super::errors::IntoPyResult;

/// A body whose points can be held at targets (m).
pub trait PinnedPoints {
    /// What a point is called in messages ("vertex", "particle").
    const POINT: &'static str;
    /// Its plural.
    const POINTS: &'static str;
    /// What the body is called in messages.
    const BODY: &'static str;
    fn num_points(&self) -> usize;
    fn pin_points(&mut self, indices: &[i64], targets: Option<&[Vector3<f64>]>) -> Result<()>;
    fn unpin_points(&mut self, indices: Option<&[i64]>) -> Result<()>;
    fn pin_map(&self) -> &BTreeMap<u32, Vector3<f64>>;
    fn move_pin_targets(&mut self, targets: &[Vector3<f64>]) -> Result<()>;
}

impl PinnedPoints for Membrane {
    const POINT: &'static str = "vertex";
    const POINTS: &'static str = "vertices";
    const BODY: &'static str = "membrane";
    fn num_points(&self) -> usize {
        self.num_vertices()
    }
    fn pin_points(&mut self, indices: &[i64], targets: Option<&[Vector3<f64>]>) -> Result<()> {
        self.pin(indices, targets)
    }
    fn unpin_points(&mut self, indices: Option<&[i64]>) -> Result<()> {
        self.unpin(indices)
    }
    fn pin_map(&self) -> &BTreeMap<u32, Vector3<f64>> {
        self.pins()
    }
    fn move_pin_targets(&mut self, targets: &[Vector3<f64>]) -> Result<()> {
        self.set_pin_targets(targets)
    }
}

impl PinnedPoints for Particles {
    const POINT: &'static str = "particle";
    const POINTS: &'static str = "particles";
    const BODY: &'static str = "body";
    fn num_points(&self) -> usize {
        self.num_particles()
    }
    fn pin_points(&mut self, indices: &[i64], targets: Option<&[Vector3<f64>]>) -> Result<()> {
        self.pin(indices, targets)
    }
    fn unpin_points(&mut self, indices: Option<&[i64]>) -> Result<()> {
        self.unpin(indices)
    }
    fn pin_map(&self) -> &BTreeMap<u32, Vector3<f64>> {
        self.pins()
    }
    fn move_pin_targets(&mut self, targets: &[Vector3<f64>]) -> Result<()> {
        self.set_pin_targets(targets)
    }
}

/// Refuses an index outside `[0, n)`, naming its entry and its true value (the cores keep
/// point indices in 32 bits: 2**32 must not become point 0).
fn in_range<B: PinnedPoints>(indices: &[i64], n: usize) -> PyResult<()> {
    match indices
        .iter()
        .position(|&i| usize::try_from(i).map_or(true, |i| i >= n))
    {
        None => Ok(()),
        Some(k) => Err(PyValueError::new_err(format!(
            "indices[{k}] = {} is not a {} index: the {} has {n} {}, [0, {n})",
            indices[k],
            B::POINT,
            B::BODY,
            B::POINTS
        ))),
    }
}

/// `pin(indices, targets=None)`: the arguments are converted before `lock` is called (a
/// membrane's lock may read its state back from the GPU).
pub fn pin<B: PinnedPoints, G: DerefMut<Target = B>>(
    lock: impl FnOnce() -> PyResult<G>,
    indices: &Bound<'_, PyAny>,
    targets: Option<&Bound<'_, PyAny>>,
) -> PyResult<()> {
    let idx = self::indices(indices, "indices")?;
    let targets = targets
        .map(|t| vec3s(t, "targets", Some(idx.len())))
        .transpose()?;
    let mut body = lock()?;
    in_range::<B>(&idx, body.num_points())?;
    body.pin_points(&idx, targets.as_deref()).py()
}

/// `unpin(indices=None)`: all pins when `indices` is None.
pub fn unpin<B: PinnedPoints>(body: &mut B, indices: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
    let idx = indices.map(|i| self::indices(i, "indices")).transpose()?;
    if let Some(idx) = &idx {
        in_range::<B>(idx, body.num_points())?;
    }
    body.unpin_points(idx.as_deref()).py()
}

/// Sorted indices of the pinned points (int64).
pub fn pinned<'py, B: PinnedPoints>(py: Python<'py>, body: &B) -> Bound<'py, PyAny> {
    to_numpy_1d(py, body.pin_map().keys().map(|&i| i64::from(i)).collect())
}

/// (P, 3) targets of the pinned points (m), in the order of `pinned`.
pub fn pin_targets<'py, B: PinnedPoints>(py: Python<'py>, body: &B) -> PyResult<Bound<'py, PyAny>> {
    let targets: Vec<_> = body.pin_map().values().copied().collect();
    to_numpy(py, targets.into_iter())
}

/// Sets `pin_targets` ((P, 3) m, in the order of `pinned`).
pub fn set_pin_targets<B: PinnedPoints>(body: &mut B, value: &Bound<'_, PyAny>) -> PyResult<()> {
    let n = body.pin_map().len();
    body.move_pin_targets(&vec3s(value, "pin_targets", Some(n))?)
        .py()
}
