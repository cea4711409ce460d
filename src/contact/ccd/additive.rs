//! Additive CCD (Li et al. 2021, *Codimensional Incremental Potential Contact*, Algorithm 1),
//! as Algorithm 2 of Lu et al. 2023 uses it (line 6, with `s = 0.1`, `t_c = 0.95`).
//!
//! The primitives move linearly from `x` at `t = 0` to `x + p` at `t = 1`. After removing the
//! mean displacement (distances are translation invariant), no pair of points on the two
//! primitives approaches faster than `l_p = max_{first} |p_k| + max_{second} |p_k|` per unit
//! time. So from a configuration at distance `d` the gap `d - xi` cannot close before
//! `(d - xi) / l_p = (d^2 - xi^2) / ((d + xi) l_p)`: the algorithm advances by such safe steps
//! (the first scaled by `1 - s`, the later ones by `t_c`) until the gap has fallen to `s` times
//! its initial value (a collision: the time reached is a lower bound of the time of impact)
//! or the time passes 1 (no collision in the step); when the initial gap already exceeds `l_p`
//! the gap cannot close within the step and the search is skipped. The result is conservative by
//! construction: it never reports a time after the true time at which the distance reaches
//! `xi`.

use nalgebra::Vector3;

use crate::geometry::distance::{edge_edge_distance_squared, point_triangle_distance_squared};

/// Parameters of the additive CCD.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdditiveCcd {
    /// `s` in (0, 1): the search stops once the gap `d - xi` is below `s` times its initial
    /// value, and the first step covers `1 - s` of the initial safe step. Default 0.1 (the
    /// paper's choice).
    pub s: f64,
    /// `t_c` in (0, 1]: rescale of every later safe step (ipc-toolkit's conservative
    /// rescaling). Default 0.95 (the paper's choice).
    pub t_c: f64,
    /// Cap on the safe steps of one query; when reached, the time so far is returned as a
    /// (conservative) time of impact. Default 10 000.
    pub max_iterations: usize,
}

impl Default for AdditiveCcd {
    fn default() -> Self {
        Self {
            s: 0.1,
            t_c: 0.95,
            max_iterations: 10_000,
        }
    }
}

type Points = [Vector3<f64>; 4];

impl AdditiveCcd {
    /// Lower bound of the first time in `[0, 1]` at which the distance between the primitives
    /// falls to `min_distance` (m), or `None` if it stays above it over the whole step.
    /// `split` is the number of vertices of the first primitive (1: point-triangle, 2:
    /// edge-edge); `distance_squared` evaluates the primitive distance.
    fn query(
        &self,
        start: &Points,
        end: &Points,
        split: usize,
        min_distance: f64,
        distance_squared: impl Fn(&Points) -> f64,
    ) -> Option<f64> {
        let mut p: Points = [0, 1, 2, 3].map(|k| end[k] - start[k]);
        let mean = p.iter().sum::<Vector3<f64>>() / 4.0;
        p.iter_mut().for_each(|pk| *pk -= mean);
        let fastest = |range: &[Vector3<f64>]| range.iter().map(|v| v.norm()).fold(0.0, f64::max);
        let l_p = fastest(&p[..split]) + fastest(&p[split..]);
        let xi2 = min_distance * min_distance;
        let gap = |d2: f64| (d2 - xi2) / (d2.sqrt() + min_distance);
        let mut x = *start;
        let initial = gap(distance_squared(&x));
        if initial.is_nan() || initial <= 0.0 {
            return Some(0.0);
        }
        // The gap closes at most at `l_p` per unit time: if it exceeds `l_p` the distance stays
        // above `min_distance` over the whole step (covers `l_p == 0`), no search needed.
        if initial > l_p {
            return None;
        }
        let stop = self.s * initial;
        let mut t = 0.0;
        let mut step = (1.0 - self.s) * initial / l_p;
        for _ in 0..self.max_iterations {
            x.iter_mut().zip(&p).for_each(|(xk, pk)| *xk += pk * step);
            let now = gap(distance_squared(&x));
            // A NaN distance counts as a collision (conservative).
            if t > 0.0 && (now < stop || now.is_nan()) {
                return Some(t);
            }
            t += step;
            if t >= 1.0 {
                return None;
            }
            step = self.t_c * now / l_p;
        }
        Some(t)
    }
}

/// Additive CCD of point `x_0` against triangle `x_1 x_2 x_3`, moving linearly from `start`
/// to `end`: a lower bound of the time of impact in `[0, 1]` at separation `min_distance` (m),
/// or `None`.
pub fn point_triangle_ccd(
    start: &[Vector3<f64>; 4],
    end: &[Vector3<f64>; 4],
    min_distance: f64,
    params: &AdditiveCcd,
) -> Option<f64> {
    params.query(start, end, 1, min_distance, |x| {
        point_triangle_distance_squared(&x[0], &x[1], &x[2], &x[3])
    })
}

/// Additive CCD of edge `x_0 x_1` against edge `x_2 x_3`; see [`point_triangle_ccd`].
pub fn edge_edge_ccd(
    start: &[Vector3<f64>; 4],
    end: &[Vector3<f64>; 4],
    min_distance: f64,
    params: &AdditiveCcd,
) -> Option<f64> {
    params.query(start, end, 2, min_distance, |x| {
        edge_edge_distance_squared(&x[0], &x[1], &x[2], &x[3])
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> Vector3<f64> {
        Vector3::new(x, y, z)
    }

    #[test]
    fn point_through_triangle_is_caught_before_impact() {
        let tri = [v(-1., -1., 0.), v(1., -1., 0.), v(0., 1., 0.)];
        let start = [v(0., 0., 1.), tri[0], tri[1], tri[2]];
        let end = [v(0., 0., -1.), tri[0], tri[1], tri[2]];
        let params = AdditiveCcd::default();
        let toi = point_triangle_ccd(&start, &end, 0.0, &params).expect("collides");
        assert!(toi <= 0.5 && toi > 0.4, "{toi}");
        let thick = point_triangle_ccd(&start, &end, 0.2, &params).expect("collides");
        assert!(thick <= 0.4 && thick > 0.3, "{thick}");
        // Zero motion, and motion that stops short.
        assert_eq!(point_triangle_ccd(&start, &start, 0.0, &params), None);
        let short = [v(0., 0., 0.5), tri[0], tri[1], tri[2]];
        assert_eq!(point_triangle_ccd(&start, &short, 0.0, &params), None);
        // Touching at the start.
        assert_eq!(point_triangle_ccd(&end, &end, 1.5, &params), Some(0.0));
    }

    #[test]
    fn parallel_edges_approaching_are_caught() {
        let start = [v(0., 0., 1.), v(1., 0., 1.), v(0.5, 0., 0.), v(1.5, 0., 0.)];
        let end = [
            v(0., 0., -1.),
            v(1., 0., -1.),
            v(0.5, 0., 0.),
            v(1.5, 0., 0.),
        ];
        let params = AdditiveCcd::default();
        let toi = edge_edge_ccd(&start, &end, 0.0, &params).expect("collides");
        assert!(toi <= 0.5 && toi > 0.4, "{toi}");
        // Sliding along each other at constant distance: no collision.
        let slide = [v(3., 0., 1.), v(4., 0., 1.), v(0.5, 0., 0.), v(1.5, 0., 0.)];
        assert_eq!(edge_edge_ccd(&start, &slide, 0.5, &params), None);
    }
}
