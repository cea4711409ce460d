//! The state every body kind shares: positions, velocities and pins of its points, in f64 and
//! SI units, with the checks that name a bad entry (a membrane's vertex, a particle).

use std::collections::BTreeMap;

use nalgebra::Vector3;

use crate::error::{invalid, Result};

/// Positions (m), velocities (m/s) and pins (point index -> target, m) of a body's points.
#[derive(Debug, Clone)]
pub struct PointState {
    pub positions: Vec<Vector3<f64>>,
    pub velocities: Vec<Vector3<f64>>,
    pub pins: BTreeMap<u32, Vector3<f64>>,
}

impl PointState {
    /// Points at `positions` (m), at rest, nothing pinned.
    pub fn at_rest(positions: Vec<Vector3<f64>>) -> Self {
        let velocities = vec![Vector3::zeros(); positions.len()];
        Self {
            positions,
            velocities,
            pins: BTreeMap::new(),
        }
    }

    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Checks a replacement for `name` (positions or velocities): one finite vector per point;
    /// an error names the first bad `noun` ("vertex", "particle").
    pub fn check_field(&self, name: &str, noun: &str, values: &[Vector3<f64>]) -> Result<()> {
        if values.len() != self.len() {
            return Err(invalid!(
                "{name} must have shape ({}, 3), got ({}, 3)",
                self.len(),
                values.len()
            ));
        }
        if let Some(i) = values.iter().position(|v| !v.iter().all(|c| c.is_finite())) {
            return Err(invalid!(
                "{name} of {noun} {i} is not finite: {:?}",
                values[i].as_slice()
            ));
        }
        Ok(())
    }

    /// Checks a pin request: indices in range, one finite target per index when given.
    pub fn check_pins(
        &self,
        noun: &str,
        indices: &[i64],
        targets: Option<&[Vector3<f64>]>,
    ) -> Result<()> {
        let n = self.len();
        if let Some(t) = targets {
            if t.len() != indices.len() {
                return Err(invalid!(
                    "pin targets must have shape ({}, 3), got ({}, 3)",
                    indices.len(),
                    t.len()
                ));
            }
            if let Some(k) = t.iter().position(|v| !v.iter().all(|c| c.is_finite())) {
                return Err(invalid!(
                    "pin target {k} ({noun} {}) is not finite: {:?}",
                    indices[k],
                    t[k].as_slice()
                ));
            }
        }
        for (k, &i) in indices.iter().enumerate() {
            if i < 0 || i as usize >= n {
                return Err(invalid!(
                    "pin index {i} (entry {k}) is out of range [0, {n})"
                ));
            }
        }
        Ok(())
    }

    /// Pins points checked by [`Self::check_pins`] at `targets` (default: where they are).
    pub fn insert_pins(&mut self, indices: &[i64], targets: Option<&[Vector3<f64>]>) {
        for (k, &i) in indices.iter().enumerate() {
            let target = targets.map_or(self.positions[i as usize], |t| t[k]);
            self.pins.insert(i as u32, target);
        }
    }

    /// Releases the given points (all when `None`); an index that is not pinned is an error.
    pub fn unpin(&mut self, noun: &str, indices: Option<&[i64]>) -> Result<()> {
        match indices {
            None => self.pins.clear(),
            Some(list) => {
                let mut points = Vec::with_capacity(list.len());
                for (k, &i) in list.iter().enumerate() {
                    match u32::try_from(i) {
                        Ok(p) if self.pins.contains_key(&p) => points.push(p),
                        _ => return Err(invalid!("{noun} {i} (entry {k}) is not pinned")),
                    }
                }
                for p in points {
                    self.pins.remove(&p);
                }
            }
        }
        Ok(())
    }

    /// Moves the pinned points' targets (m, in ascending point order).
    pub fn set_pin_targets(&mut self, targets: &[Vector3<f64>]) -> Result<()> {
        if targets.len() != self.pins.len() {
            return Err(invalid!(
                "pin_targets must have shape ({}, 3), got ({}, 3)",
                self.pins.len(),
                targets.len()
            ));
        }
        if let Some(k) = targets
            .iter()
            .position(|v| !v.iter().all(|c| c.is_finite()))
        {
            return Err(invalid!(
                "pin target {k} is not finite: {:?}",
                targets[k].as_slice()
            ));
        }
        for (slot, t) in self.pins.values_mut().zip(targets) {
            *slot = *t;
        }
        Ok(())
    }
}
