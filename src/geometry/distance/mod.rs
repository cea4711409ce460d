//! Distances between the primitives of two triangles (Lu et al. 2023, eq. 48): a triangle pair
//! reduces to 6 point-triangle and 9 edge-edge queries.
//!
//! Every query returns a [`Closest`]: the closest points as weights `c_k` on the four vertices
//! `x_k` of the pair, so that the separation vector is `d = sum_k c_k x_k` (from the second
//! primitive to the first) and the squared distance is `|d|^2`. Because the closest points
//! minimise the distance, the envelope theorem gives the gradient without differentiating the
//! weights: `d|d|^2/dx_k = 2 c_k d` and `d|d|/dx_k = c_k d / |d|`.

mod edge_edge;
mod point_triangle;

pub use edge_edge::{edge_edge_closest, edge_edge_distance_squared, edge_edge_gradient};
pub use point_triangle::{
    point_triangle_closest, point_triangle_distance_squared, point_triangle_gradient,
};

use nalgebra::Vector3;

/// Closest points between two primitives with four vertices `x_0..x_3` (point-triangle:
/// `p, t0, t1, t2`; edge-edge: `a0, a1, b0, b1`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Closest {
    /// `c_k`: the separation is `d = sum_k c_k x_k`; the weights of each primitive are its
    /// barycentric coordinates (first primitive positive, second negative, each summing to 1).
    pub weights: [f64; 4],
    /// `d` (m), pointing from the second primitive's closest point to the first's.
    pub separation: Vector3<f64>,
}

impl Closest {
    fn of(weights: [f64; 4], x: [&Vector3<f64>; 4]) -> Self {
        let separation = x
            .iter()
            .zip(weights)
            .fold(Vector3::zeros(), |acc, (xk, ck)| acc + *xk * ck);
        Self {
            weights,
            separation,
        }
    }

    /// `|d|^2` (m^2).
    pub fn distance_squared(&self) -> f64 {
        self.separation.norm_squared()
    }

    /// `d|d|^2/dx_k = 2 c_k d` (m), vertex by vertex.
    pub fn gradient_squared(&self) -> [Vector3<f64>; 4] {
        self.weights.map(|c| self.separation * (2.0 * c))
    }
}

/// Closest point of segment `a b` to `p` as the weight `s` of `b` (`(1 - s) a + s b`);
/// a degenerate segment gives `s = 0`.
fn segment_parameter(p: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    let e = b - a;
    let len2 = e.norm_squared();
    if len2 <= f64::MIN_POSITIVE {
        return 0.0;
    }
    ((p - a).dot(&e) / len2).clamp(0.0, 1.0)
}

#[cfg(test)]
pub(crate) mod tests {
    use nalgebra::Vector3;

    pub use crate::test_rng::Rng;

    /// `n` random sets of four points in the unit cube.
    pub fn random_points(n: usize, seed: u64) -> Vec<[Vector3<f64>; 4]> {
        let mut rng = Rng::new(seed);
        (0..n).map(|_| [(); 4].map(|_| rng.vector())).collect()
    }

    /// Asserts `grad` matches central differences of `f` at `x` (relative 1e-5).
    pub fn finite_difference(
        x: &[Vector3<f64>; 4],
        f: impl Fn(&[Vector3<f64>; 4]) -> f64,
        grad: &[Vector3<f64>; 4],
    ) {
        let h = 1e-7;
        for k in 0..4 {
            for c in 0..3 {
                let (mut plus, mut minus) = (*x, *x);
                plus[k][c] += h;
                minus[k][c] -= h;
                let fd = (f(&plus) - f(&minus)) / (2.0 * h);
                assert!(
                    (fd - grad[k][c]).abs() < 1e-5 * (1.0 + fd.abs()),
                    "vertex {k} coordinate {c}: analytic {} vs FD {fd}",
                    grad[k][c]
                );
            }
        }
    }
}
