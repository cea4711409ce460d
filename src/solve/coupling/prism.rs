//! Whether a point is over a triangle (its projection on the triangle's plane inside the
//! triangle, within [`PRISM_SLACK`]), and its height above the plane there.

use nalgebra::Vector3;

use super::PRISM_SLACK;

/// A point over a triangle: the plane's unit normal, the clamped barycentric weights of the
/// point's projection (summing to 1) and the point's height above the plane along the normal
/// (m).
#[derive(Clone, Copy, Debug)]
pub(super) struct Over {
    pub normal: Vector3<f64>,
    pub weights: [f64; 3],
    pub height: f64,
}

impl Over {
    /// The side of the plane the point is on (+1 on the plane).
    pub fn side(&self) -> i8 {
        if self.height >= 0.0 {
            1
        } else {
            -1
        }
    }
}

/// `x` over the triangle `a b c` (its projection on the plane within [`PRISM_SLACK`] of the
/// triangle, in barycentric coordinates), or None (also for a degenerate triangle).
pub(super) fn over_triangle(
    x: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
) -> Option<Over> {
    let (e1, e2, q) = (b - a, c - a, x - a);
    let n = e1.cross(&e2);
    let area2 = n.norm_squared();
    let scale = e1.norm_squared().max(e2.norm_squared());
    if area2.is_nan() || area2 <= 1e-24 * scale * scale {
        return None;
    }
    let beta = q.cross(&e2).dot(&n) / area2;
    let gamma = e1.cross(&q).dot(&n) / area2;
    let alpha = 1.0 - beta - gamma;
    if alpha.min(beta).min(gamma) < -PRISM_SLACK {
        return None;
    }
    let clamped = [alpha, beta, gamma].map(|w| w.max(0.0));
    let sum: f64 = clamped.iter().sum();
    let normal = n / area2.sqrt();
    Some(Over {
        normal,
        weights: clamped.map(|w| w / sum),
        height: normal.dot(&q),
    })
}
