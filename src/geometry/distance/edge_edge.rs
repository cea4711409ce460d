//! Edge-edge (segment-segment) distance.
//!
//! `d(A, B) = min_{s, t in [0, 1]} |(1 - s) a_0 + s a_1 - (1 - t) b_0 - t b_1|`, solved by
//! clamping the unconstrained line-line solution and re-projecting (Ericson, *Real-Time
//! Collision Detection*, 5.1.9). Parallel edges (`|a x b|^2` below a relative `1e-12`) take
//! `s = 0` and project; the distance is then exact and the weights are one valid choice among
//! the equally close ones. Zero-length edges reduce to point-segment or point-point queries.

use nalgebra::Vector3;

use super::{segment_parameter, Closest};

/// Closest points of segments `a0 a1` and `b0 b1`: weights `[1 - s, s, -(1 - t), -t]`.
pub fn edge_edge_closest(
    a0: &Vector3<f64>,
    a1: &Vector3<f64>,
    b0: &Vector3<f64>,
    b1: &Vector3<f64>,
) -> Closest {
    let (s, t) = parameters(a0, a1, b0, b1);
    Closest::of([1.0 - s, s, t - 1.0, -t], [a0, a1, b0, b1])
}

/// Squared distance between the segments (m^2).
pub fn edge_edge_distance_squared(
    a0: &Vector3<f64>,
    a1: &Vector3<f64>,
    b0: &Vector3<f64>,
    b1: &Vector3<f64>,
) -> f64 {
    edge_edge_closest(a0, a1, b0, b1).distance_squared()
}

/// Gradient of the squared distance with respect to `a0, a1, b0, b1`.
pub fn edge_edge_gradient(
    a0: &Vector3<f64>,
    a1: &Vector3<f64>,
    b0: &Vector3<f64>,
    b1: &Vector3<f64>,
) -> [Vector3<f64>; 4] {
    edge_edge_closest(a0, a1, b0, b1).gradient_squared()
}

/// `(s, t)` of the closest points.
fn parameters(
    a0: &Vector3<f64>,
    a1: &Vector3<f64>,
    b0: &Vector3<f64>,
    b1: &Vector3<f64>,
) -> (f64, f64) {
    let (d1, d2, r) = (a1 - a0, b1 - b0, a0 - b0);
    let (a, e, f) = (d1.norm_squared(), d2.norm_squared(), d2.dot(&r));
    let tiny = f64::MIN_POSITIVE;
    if a <= tiny && e <= tiny {
        return (0.0, 0.0);
    }
    if a <= tiny {
        return (0.0, (f / e).clamp(0.0, 1.0));
    }
    let c = d1.dot(&r);
    if e <= tiny {
        return ((-c / a).clamp(0.0, 1.0), 0.0);
    }
    let b = d1.dot(&d2);
    let denom = a * e - b * b;
    let s = if denom > 1e-12 * a * e {
        ((b * f - c * e) / denom).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let t = (b * s + f) / e;
    if t < 0.0 {
        (segment_parameter(b0, a0, a1), 0.0)
    } else if t > 1.0 {
        (segment_parameter(b1, a0, a1), 1.0)
    } else {
        (s, t)
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{finite_difference, random_points};
    use super::*;

    #[test]
    fn crossing_parallel_and_degenerate_edges() {
        let v = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
        let d2 = |a: [Vector3<f64>; 4]| edge_edge_distance_squared(&a[0], &a[1], &a[2], &a[3]);
        // Crossing at height 1.
        let cross = [v(-1., 0., 0.), v(1., 0., 0.), v(0., -1., 1.), v(0., 1., 1.)];
        assert!((d2(cross) - 1.0).abs() < 1e-15);
        // Parallel and overlapping, 0.5 apart; parallel and disjoint along the line.
        let par = [
            v(0., 0., 0.),
            v(1., 0., 0.),
            v(0.5, 0.5, 0.),
            v(2., 0.5, 0.),
        ];
        assert!((d2(par) - 0.25).abs() < 1e-15);
        let apart = [v(0., 0., 0.), v(1., 0., 0.), v(3., 0., 0.), v(2., 0., 0.)];
        assert!((d2(apart) - 1.0).abs() < 1e-15);
        // Collinear overlapping: distance zero.
        let collinear = [v(0., 0., 0.), v(2., 0., 0.), v(1., 0., 0.), v(3., 0., 0.)];
        assert!(d2(collinear) < 1e-30);
        // Zero-length edges.
        let point = [v(0., 0., 0.), v(0., 0., 0.), v(-1., 1., 0.), v(1., 1., 0.)];
        assert!((d2(point) - 1.0).abs() < 1e-15);
        let points = [v(0., 0., 0.), v(0., 0., 0.), v(0., 3., 4.), v(0., 3., 4.)];
        assert!((d2(points) - 25.0).abs() < 1e-12);
    }

    #[test]
    fn gradient_matches_finite_differences() {
        for x in random_points(200, 11) {
            let f = |y: &[Vector3<f64>; 4]| edge_edge_distance_squared(&y[0], &y[1], &y[2], &y[3]);
            let g = edge_edge_gradient(&x[0], &x[1], &x[2], &x[3]);
            finite_difference(&x, f, &g);
        }
    }
}
