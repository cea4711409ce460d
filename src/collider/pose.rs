//! Rigid poses of colliders: `x_world = R x_body + t`, and where a collider's material points
//! were at the start of a step given its poses at the start and at the end.

use nalgebra::{Matrix3, Vector3};

use crate::error::{invalid, Result};

/// A rigid transform `x -> rotation * x + translation`: `rotation` orthonormal with det +1,
/// `translation` in m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    pub rotation: Matrix3<f64>,
    pub translation: Vector3<f64>,
}

impl Pose {
    pub const IDENTITY: Self = Self {
        rotation: Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
        translation: Vector3::new(0.0, 0.0, 0.0),
    };

    /// A pose from a rotation matrix given by rows and a translation (m); both checked.
    pub fn new(rotation: [[f64; 3]; 3], translation: [f64; 3]) -> Result<Self> {
        let translation = Vector3::from(translation);
        if let Some(k) = translation.iter().position(|c| !c.is_finite()) {
            return Err(invalid!(
                "translation[{k}] must be finite, got {:?}",
                translation.as_slice()
            ));
        }
        Ok(Self {
            rotation: rotation_matrix("rotation", rotation)?,
            translation,
        })
    }

    /// The pose moved on by the translation `shift` (m).
    pub fn shifted(&self, shift: &Vector3<f64>) -> Self {
        Self {
            rotation: self.rotation,
            translation: self.translation + shift,
        }
    }

    /// The rigid map taking a material point's position under this (end) pose to its position
    /// under `start`: `x -> R_0 R_1^T (x - t_1) + t_0`.
    pub fn back_to(&self, start: &Pose) -> Self {
        let rotation = start.rotation * self.rotation.transpose();
        Self {
            rotation,
            translation: start.translation - rotation * self.translation,
        }
    }
}

/// How far from the identity `R^T R` of an accepted rotation may be, entry by entry: the
/// round-off of rotations computed by a caller (e.g. composed turns), while a matrix that is
/// not a rotation stays rejected.
pub(crate) const ORTHONORMAL_TOLERANCE: f64 = 1e-9;

/// Checks a rotation matrix given by rows: finite, orthonormal (`|R^T R - I| <`
/// [`ORTHONORMAL_TOLERANCE`] entry by entry) and det +1. The error names `name` and the offending entry or property.
pub fn rotation_matrix(name: &str, rows: [[f64; 3]; 3]) -> Result<Matrix3<f64>> {
    for (r, row) in rows.iter().enumerate() {
        if let Some(c) = row.iter().position(|v| !v.is_finite()) {
            return Err(invalid!(
                "{name}[{r}][{c}] must be finite, got {}; {name} must be a rotation matrix (orthonormal, det +1)",
                row[c]
            ));
        }
    }
    let m = Matrix3::from_row_slice(&rows.concat());
    let deviation = (m.transpose() * m - Matrix3::identity()).abs().max();
    if deviation >= ORTHONORMAL_TOLERANCE {
        return Err(invalid!(
            "{name} must be a rotation matrix (orthonormal, det +1), but R^T R differs from I by {deviation:e}: {rows:?}"
        ));
    }
    if m.determinant() <= 0.0 {
        return Err(invalid!(
            "{name} must be a rotation matrix (orthonormal, det +1), got det {} (a reflection): {rows:?}",
            m.determinant()
        ));
    }
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The back map sends a material point's end position to its start position, for a pose
    /// turned by 90 degrees about z and moved.
    #[test]
    fn back_map_follows_a_material_point() {
        let start = Pose::new(
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            [1.0, 0.0, 0.0],
        )
        .unwrap();
        let end = Pose::new(
            [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
            [0.0, 0.0, 2.0],
        )
        .unwrap();
        let apply = |p: &Pose, x: &Vector3<f64>| p.rotation * x + p.translation;
        let body = Vector3::new(0.3, -0.2, 0.5);
        let back = end.back_to(&start);
        assert!((apply(&back, &apply(&end, &body)) - apply(&start, &body)).norm() < 1e-15);
    }

    #[test]
    fn bad_rotations_are_named() {
        let msg = |rows| rotation_matrix("rotation", rows).unwrap_err().to_string();
        assert!(
            msg([[1.0, 0.0, 0.0], [0.0, f64::NAN, 0.0], [0.0, 0.0, 1.0]])
                .contains("rotation[1][1]")
        );
        assert!(msg([[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).contains("orthonormal"));
        assert!(msg([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]).contains("det"));
        assert!(Pose::new(
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            [0.0, f64::INFINITY, 0.0]
        )
        .unwrap_err()
        .to_string()
        .contains("translation[1]"));
    }
}
