//! Analytic colliders. After each global iteration every free vertex is projected out of
//! every collider so that its mid-surface keeps half the membrane thickness from the surface.

use nalgebra::Vector3;

use crate::error::{invalid, Result};
use crate::real::Real;

/// A static collider (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Collider {
    /// Half-space `{x : (x - point) . normal >= 0}` is free; `normal` is unit.
    Plane {
        point: Vector3<f64>,
        normal: Vector3<f64>,
    },
    /// Solid ball.
    Sphere { center: Vector3<f64>, radius: f64 },
}

impl Collider {
    /// A plane through `point` whose free side is the one `normal` points to.
    pub fn plane(point: [f64; 3], normal: [f64; 3]) -> Result<Self> {
        let (point, normal) = (Vector3::from(point), Vector3::from(normal));
        if !point.iter().all(|c| c.is_finite()) {
            return Err(invalid!(
                "plane point must be finite, got {:?}",
                point.as_slice()
            ));
        }
        let norm = normal.norm();
        if !(norm.is_finite() && norm > 1e-12) {
            return Err(invalid!(
                "plane normal must be a finite non-zero vector, got {:?}",
                normal.as_slice()
            ));
        }
        Ok(Self::Plane {
            point,
            normal: normal / norm,
        })
    }

    /// A sphere of `radius` (m, > 0) at `center`.
    pub fn sphere(center: [f64; 3], radius: f64) -> Result<Self> {
        let center = Vector3::from(center);
        if !center.iter().all(|c| c.is_finite()) {
            return Err(invalid!(
                "sphere center must be finite, got {:?}",
                center.as_slice()
            ));
        }
        if !(radius.is_finite() && radius > 0.0) {
            return Err(invalid!(
                "sphere radius must be a finite length > 0 m, got {radius}"
            ));
        }
        Ok(Self::Sphere { center, radius })
    }

    /// Signed distance from the surface (m), positive outside.
    pub fn signed_distance(&self, x: &Vector3<f64>) -> f64 {
        self.to_real::<f64>().signed_distance(x)
    }

    /// The collider in the simulation's precision.
    pub fn to_real<T: Real>(&self) -> ColliderModel<T> {
        match *self {
            Self::Plane { point, normal } => ColliderModel::Plane {
                offset: T::of(point.dot(&normal)),
                normal: normal.map(T::of),
            },
            Self::Sphere { center, radius } => ColliderModel::Sphere {
                center: center.map(T::of),
                radius: T::of(radius),
            },
        }
    }
}

/// [`Collider`] in the simulation's precision.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ColliderModel<T: Real> {
    Plane { normal: Vector3<T>, offset: T },
    Sphere { center: Vector3<T>, radius: T },
}

impl<T: Real> ColliderModel<T> {
    /// Signed distance from the surface (m), positive outside.
    #[inline]
    pub fn signed_distance(&self, x: &Vector3<T>) -> T {
        match *self {
            Self::Plane { normal, offset } => x.dot(&normal) - offset,
            Self::Sphere { center, radius } => (x - center).norm() - radius,
        }
    }

    /// Unit outward normal of the surface nearest `x`.
    #[inline]
    pub fn normal(&self, x: &Vector3<T>) -> Vector3<T> {
        match *self {
            Self::Plane { normal, .. } => normal,
            Self::Sphere { center, .. } => {
                let r = x - center;
                let d = r.norm();
                if d > T::zero() {
                    r / d
                } else {
                    Vector3::z()
                }
            }
        }
    }

    /// The closest point at distance >= `margin` from the surface: `x` itself when it is
    /// already that far out, else its projection onto the offset surface.
    #[inline]
    pub fn project(&self, x: Vector3<T>, margin: T) -> Vector3<T> {
        match *self {
            Self::Plane { normal, offset } => {
                let d = x.dot(&normal) - offset - margin;
                if d < T::zero() {
                    x - normal * d
                } else {
                    x
                }
            }
            Self::Sphere { center, radius } => {
                let r = x - center;
                let dist = r.norm();
                let reach = radius + margin;
                if dist >= reach {
                    x
                } else if dist > T::zero() {
                    center + r * (reach / dist)
                } else {
                    center + Vector3::z() * reach
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projection_lands_at_the_margin_and_leaves_free_points_alone() {
        let s = Collider::sphere([0.0, 0.0, 1.0], 0.5)
            .unwrap()
            .to_real::<f64>();
        let p = s.project(Vector3::new(0.1, 0.0, 1.0), 0.01);
        assert!((s.signed_distance(&p) - 0.01).abs() < 1e-14);
        let free = Vector3::new(2.0, 0.0, 0.0);
        assert_eq!(s.project(free, 0.01), free);
        let plane = Collider::plane([0.0, 0.0, -1.0], [0.0, 0.0, 2.0])
            .unwrap()
            .to_real::<f64>();
        let p = plane.project(Vector3::new(3.0, 4.0, -5.0), 0.002);
        assert!((p - Vector3::new(3.0, 4.0, -0.998)).norm() < 1e-15);
        assert!(Collider::sphere([0.0; 3], 0.0)
            .unwrap_err()
            .to_string()
            .contains("radius"));
        assert!(Collider::plane([0.0; 3], [0.0; 3])
            .unwrap_err()
            .to_string()
            .contains("normal"));
    }
}
