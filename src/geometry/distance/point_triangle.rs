//! Point-triangle distance.
//!
//! `d(p, T) = min_{w in simplex} |p - (w_0 t_0 + w_1 t_1 + w_2 t_2)|`: the closest point is
//! found by Voronoi regions (Ericson, *Real-Time Collision Detection*, 5.1.5), which handles
//! the vertex, edge and face regions without a case table. A degenerate (zero-area) triangle
//! falls back to the nearest of its three edges.

use nalgebra::Vector3;

use super::{segment_parameter, Closest};

/// Closest points of `p` and triangle `t0 t1 t2`: weights `[1, -w_0, -w_1, -w_2]` with `w`
/// the barycentric coordinates of the closest point on the triangle.
pub fn point_triangle_closest(
    p: &Vector3<f64>,
    t0: &Vector3<f64>,
    t1: &Vector3<f64>,
    t2: &Vector3<f64>,
) -> Closest {
    let w = triangle_weights(p, t0, t1, t2);
    Closest::of([1.0, -w[0], -w[1], -w[2]], [p, t0, t1, t2])
}

/// `|p - closest point of T|^2` (m^2).
pub fn point_triangle_distance_squared(
    p: &Vector3<f64>,
    t0: &Vector3<f64>,
    t1: &Vector3<f64>,
    t2: &Vector3<f64>,
) -> f64 {
    point_triangle_closest(p, t0, t1, t2).distance_squared()
}

/// Gradient of the squared distance with respect to `p, t0, t1, t2`: `2 d`, `-2 w_k d`.
pub fn point_triangle_gradient(
    p: &Vector3<f64>,
    t0: &Vector3<f64>,
    t1: &Vector3<f64>,
    t2: &Vector3<f64>,
) -> [Vector3<f64>; 4] {
    point_triangle_closest(p, t0, t1, t2).gradient_squared()
}

/// Barycentric coordinates of the point of triangle `a b c` closest to `p`.
fn triangle_weights(
    p: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
) -> [f64; 3] {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let scale = ab.norm_squared().max(ac.norm_squared());
    if ab.cross(&ac).norm_squared() <= 1e-24 * scale * scale {
        return degenerate_weights(p, a, b, c);
    }
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return [1.0 - v, v, 0.0];
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    [1.0 - v - w, v, w]
}

/// A zero-area triangle is the union of its edges: the nearest edge's closest point.
fn degenerate_weights(
    p: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
) -> [f64; 3] {
    let on_edge = |u: &Vector3<f64>, v: &Vector3<f64>| {
        let s = segment_parameter(p, u, v);
        (s, (p - (u * (1.0 - s) + v * s)).norm_squared())
    };
    let (s_ab, d_ab) = on_edge(a, b);
    let (s_bc, d_bc) = on_edge(b, c);
    let (s_ca, d_ca) = on_edge(c, a);
    if d_ab <= d_bc && d_ab <= d_ca {
        [1.0 - s_ab, s_ab, 0.0]
    } else if d_bc <= d_ca {
        [0.0, 1.0 - s_bc, s_bc]
    } else {
        [s_ca, 0.0, 1.0 - s_ca]
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{finite_difference, random_points};
    use super::*;

    #[test]
    fn regions_give_the_expected_distances() {
        let (a, b, c) = (
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, 1.0, 0.0),
        );
        let d2 = |p: Vector3<f64>| point_triangle_distance_squared(&p, &a, &b, &c);
        assert!((d2(Vector3::new(0.2, 0.2, 0.5)) - 0.25).abs() < 1e-15);
        assert!((d2(Vector3::new(-1.0, -1.0, 0.0)) - 2.0).abs() < 1e-15);
        assert!((d2(Vector3::new(0.5, -2.0, 0.0)) - 4.0).abs() < 1e-15);
        assert!((d2(Vector3::new(1.0, 1.0, 0.0)) - 0.5).abs() < 1e-15);
        // Degenerate triangle (collinear vertices): distance to the segment.
        let flat = point_triangle_distance_squared(
            &Vector3::new(0.5, 1.0, 0.0),
            &a,
            &b,
            &Vector3::new(2.0, 0.0, 0.0),
        );
        assert!((flat - 1.0).abs() < 1e-15);
    }

    #[test]
    fn gradient_matches_finite_differences() {
        for x in random_points(200, 7) {
            let f =
                |y: &[Vector3<f64>; 4]| point_triangle_distance_squared(&y[0], &y[1], &y[2], &y[3]);
            let g = point_triangle_gradient(&x[0], &x[1], &x[2], &x[3]);
            finite_difference(&x, f, &g);
        }
    }
}
