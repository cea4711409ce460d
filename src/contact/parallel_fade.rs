//! The fade of nearly parallel edge-edge pairs: IPC's edge-edge mollifier (Li et al. 2020,
//! section 4.3), not in Lu et al. 2023.
//!
//! **Why.** Where two edges turn through parallel, their closest points jump from one end of
//! the overlap to the other (for exactly parallel, overlapping edges every point of the
//! overlap is closest), and so does the barrier's push of eq. 49 on their four vertices: the
//! total push on each edge is continuous, its split between the edge's two vertices is not.
//! Eq. 47 then has no smooth minimum there, and the local step's moves jump back and forth by
//! about the jump. Stacked cloth layers are full of such pairs (an edge of one layer lying
//! along the edge below it): once layers touch, every step runs to its iteration cap, the
//! convergence measure frozen at about the jump (a micrometre or so). The pair's barrier
//! term is therefore scaled by its fade `m`, which falls to 0
//! as the edges become parallel; there the point-triangle pairs of the same two triangles
//! (each edge's vertices against the other edge's triangles) carry the contact.
//!
//! **The fade.** With `theta` the angle between the edges and `theta_0` the fade angle,
//! `r = sin^2 theta / sin^2 theta_0` and `m = r (2 - r)` for `r < 1`, else 1: `m(0) = 0`, and
//! `m = 1`, `dm/dr = 0` at `r = 1` (C1). IPC compares `|e_a x e_b|^2` with
//! `1e-3 |e_a^rest|^2 |e_b^rest|^2`, the same with `sin^2 theta_0 = 1e-3` where the edges keep
//! their rest lengths; here the current lengths divide, so the fade depends on the angle
//! alone and needs no rest shape.
//!
//! **Held through a local step.** The local step takes each pair's fade at its safe
//! positions and keeps it through the descent (lagged, as IPC lags the normal force of
//! friction): every local step minimises eq. 47 with fixed fades, so its descent direction
//! stays the gradient of what it minimises. The fade's own gradient, `mu B(x) dm/dc grad c`
//! with `c = |e_a x e_b|^2`, is left out: it is a torque turning the two edges towards
//! parallel, and for the paper's cloth (edges `L` of 8.5 mm, at the 3 mm gap of the closest
//! layers of the three-layer run) its stiffness, `mu B d^2c/dx^2 dm/dc` up to
//! `4 mu B / (sin^2 theta_0 L^2)`, is some 300 times the proximal term's (`mu` = 1): it would
//! pull the edges of stacked layers into line. The price of holding: a pair that turns out of
//! parallel within a local step (an 8.5 mm edge turned by 1.8 degrees moves its end by
//! 0.27 mm, two descent moves of `eps xi`) keeps its small fade until the next local step;
//! the CCD and the final clamp still keep it `eps xi` apart.

use nalgebra::Vector3;

/// IPC's fade limit, `sin^2 theta_0 = 1e-3` (Li et al. 2020): `theta_0` = 1.8 degrees.
pub const IPC_SIN2_LIMIT: f64 = 1e-3;

/// The default fade angle `theta_0` (radians): IPC's, [`IPC_SIN2_LIMIT`].
pub fn default_parallel_angle() -> f64 {
    IPC_SIN2_LIMIT.sqrt().asin()
}

/// `sin^2 theta_0` for a fade angle `theta_0` (radians).
pub fn sin2_limit(angle: f64) -> f64 {
    angle.sin().powi(2)
}

/// The fade `m` of an edge-edge pair with edge vectors `a` and `b` (m) for the fade limit
/// `sin2_limit = sin^2 theta_0` (dimensionless, in `[0, 1)`): 0 for parallel edges, 1 from the
/// angle `theta_0` on (see the module doc). Where the ratio `r` is not below 1 because it is
/// not finite (a zero-length edge, `sin2_limit = 0`, a NaN position), the fade is 1: without a
/// direction there is no jump to fade.
pub fn edge_edge_fade(a: &Vector3<f64>, b: &Vector3<f64>, sin2_limit: f64) -> f64 {
    let r = a.cross(b).norm_squared() / (sin2_limit * a.norm_squared() * b.norm_squared());
    if r < 1.0 {
        r * (2.0 - r)
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::Rng;

    /// Edge `b` at angle `theta` to `a = (la, 0, 0)` in the plane `z = 0`, of length `lb`.
    fn edges(theta: f64, la: f64, lb: f64) -> (Vector3<f64>, Vector3<f64>) {
        (
            Vector3::new(la, 0.0, 0.0),
            Vector3::new(lb * theta.cos(), lb * theta.sin(), 0.0),
        )
    }

    #[test]
    fn parallel_edges_fade_out_and_edges_beyond_the_angle_count_fully() {
        let limit = sin2_limit(0.03);
        for theta in [0.0, std::f64::consts::PI] {
            let (a, b) = edges(theta, 1.0, 2.0);
            assert!(edge_edge_fade(&a, &b, limit).abs() < 1e-12, "{theta}");
        }
        for theta in [0.0301, 0.5, 1.5, 3.0] {
            let (a, b) = edges(theta, 1.0, 2.0);
            assert_eq!(edge_edge_fade(&a, &b, limit), 1.0, "{theta}");
        }
        // In between it rises with the angle.
        let fades: Vec<f64> = (1..30)
            .map(|k| {
                let (a, b) = edges(0.001 * f64::from(k), 1.0, 2.0);
                edge_edge_fade(&a, &b, limit)
            })
            .collect();
        assert!(fades
            .windows(2)
            .all(|w| 0.0 < w[0] && w[0] < w[1] && w[1] < 1.0));
    }

    /// `m` as a function of `r = sin^2 theta / sin^2 theta_0` matches `r (2 - r)`, and its value
    /// and slope meet 1 and 0 at `r = 1` from below (C1): central differences of the fade in
    /// `r` on the left, and the jump across the breakpoint of order `h^2`.
    #[test]
    fn the_fade_is_c1_where_it_reaches_one() {
        let limit = 1e-3;
        let at = |r: f64| {
            let theta = (r * limit).sqrt().asin();
            let (a, b) = edges(theta, 0.3, 0.7);
            edge_edge_fade(&a, &b, limit)
        };
        for r in [0.1, 0.5, 0.9] {
            assert!((at(r) - r * (2.0 - r)).abs() < 1e-12, "{r}");
        }
        let h = 1e-5;
        let slope_below = (at(1.0 - h) - at(1.0 - 3.0 * h)) / (2.0 * h);
        assert!(slope_below.abs() < 1e-4, "slope {slope_below}");
        assert!((at(1.0 + h) - at(1.0 - h)).abs() < 1e-9);
    }

    /// Only the angle counts: scaling either edge, turning both together, or reversing one
    /// keeps the fade.
    #[test]
    fn the_fade_depends_on_the_angle_alone() {
        let mut rng = Rng::new(5);
        let limit = sin2_limit(0.05);
        for _ in 0..200 {
            let (a, b) = edges(0.06 * rng.uniform().abs(), 1.0, 1.0);
            let m = edge_edge_fade(&a, &b, limit);
            let turn = nalgebra::Rotation3::new(rng.vector() * 3.0);
            let (sa, sb) = (1e-3 + rng.uniform().abs(), 1e-3 + rng.uniform().abs());
            let moved = edge_edge_fade(&(turn * a * sa), &(turn * b * -sb), limit);
            assert!((moved - m).abs() < 1e-9, "{moved} vs {m}");
        }
    }

    #[test]
    fn a_point_like_edge_no_fade_angle_or_a_nan_counts_fully() {
        let (a, b) = edges(0.0, 1.0, 1.0);
        assert_eq!(edge_edge_fade(&a, &b, 0.0), 1.0);
        assert_eq!(edge_edge_fade(&Vector3::zeros(), &b, 1e-3), 1.0);
        assert_eq!(edge_edge_fade(&a, &Vector3::zeros(), 1e-3), 1.0);
        assert_eq!(edge_edge_fade(&(a * f64::NAN), &b, 1e-3), 1.0);
    }

    #[test]
    fn the_default_angle_is_ipcs() {
        assert!((sin2_limit(default_parallel_angle()) - IPC_SIN2_LIMIT).abs() < 1e-15);
    }
}
