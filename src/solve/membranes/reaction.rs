//! The contact reaction a local step realised at a vertex, for the convergence measure
//! ([`super::jacobi::free_residual`]).

use nalgebra::{Matrix3, Vector3};

/// The part of a local step's move `moved` (m) that the contacts at the vertex can have
/// produced: the non-negative combination `sum_j a_j u_j` (`a_j >= 0`) of the unit
/// `directions` closest to `moved` (the barrier's push and the outward normals of the
/// colliders the vertex touches). Contacts push and never pull, so a move against a direction
/// is no reaction of it; what is left, `moved - sum_j a_j u_j`, stays in the measure.
///
/// This is non-negative least squares. Its solution is the plain least-squares fit on the set
/// of its positive coefficients, so the fit on every subset of linearly independent
/// directions whose coefficients all come out non-negative is tried, and the closest kept (a
/// vertex has a handful of directions: one for the push, one per collider it touches).
pub(crate) fn realised_reaction(moved: &Vector3<f64>, directions: &[Vector3<f64>]) -> Vector3<f64> {
    if let [u] = directions {
        return u * u.dot(moved).max(0.0);
    }
    let mut best = Vector3::zeros();
    let mut best_miss = moved.norm_squared();
    for subset in 1..(1u64 << directions.len()) {
        // At most three directions can be independent in space.
        if subset.count_ones() > 3 {
            continue;
        }
        let mut chosen = [Vector3::zeros(); 3];
        let mut count = 0;
        for (j, u) in directions.iter().enumerate() {
            if subset >> j & 1 == 1 {
                chosen[count] = *u;
                count += 1;
            }
        }
        // The normal equations of the fit, padded with the identity beyond `count` (whose
        // coefficients then come out zero).
        let gram = Matrix3::from_fn(|a, b| match (a < count, b < count) {
            (true, true) => chosen[a].dot(&chosen[b]),
            _ => f64::from(u8::from(a == b)),
        });
        let projections =
            Vector3::from_fn(|a, _| if a < count { chosen[a].dot(moved) } else { 0.0 });
        let Some(coefficients) = gram.cholesky().map(|c| c.solve(&projections)) else {
            continue;
        };
        if coefficients.iter().any(|&a| a < 0.0) {
            continue;
        }
        let fit = Matrix3::from_columns(&chosen) * coefficients;
        let miss = (moved - fit).norm_squared();
        if miss < best_miss {
            best = fit;
            best_miss = miss;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::Rng;

    fn unit(rng: &mut Rng) -> Vector3<f64> {
        loop {
            let v = rng.vector();
            if v.norm() > 0.1 {
                return v.normalize();
            }
        }
    }

    /// One direction: a move along it is all reaction, a move against it none, and an oblique
    /// move its projection.
    #[test]
    fn one_direction_keeps_the_projection_on_its_side() {
        let u = Vector3::new(0.0, 0.6, 0.8);
        let along = u * 2e-5;
        assert_eq!(realised_reaction(&along, &[u]), along);
        assert_eq!(realised_reaction(&-along, &[u]), Vector3::zeros());
        let oblique = Vector3::new(3e-5, 0.0, 1e-5);
        assert!((realised_reaction(&oblique, &[u]) - u * 8e-6).norm() < 1e-20);
    }

    /// A vertex pressed by the barrier against a collider: its move is a positive mix of the
    /// push and the collider's normal, and all of it is reaction; a tangential slide on top of
    /// it is not.
    #[test]
    fn a_push_against_a_collider_is_all_reaction_and_a_slide_is_not() {
        let push = Vector3::new(0.0, 0.8, -0.6);
        let normal = Vector3::new(0.0, 0.0, 1.0);
        let moved = push * 3e-5 + normal * 5e-5;
        assert!((realised_reaction(&moved, &[push, normal]) - moved).norm() < 1e-18);
        let slide = Vector3::new(4e-5, 0.0, 0.0);
        assert!((realised_reaction(&(moved + slide), &[push, normal]) - moved).norm() < 1e-18);
    }

    /// On random moves and one to four random directions (parallel and opposite ones among
    /// them), the result satisfies the optimality conditions of non-negative least squares:
    /// it is in the cone of the directions, the rest `moved - fit` points against or across
    /// every direction (`u . rest <= 0`), and is orthogonal to the fit.
    #[test]
    fn the_fit_is_the_non_negative_least_squares_solution() {
        let mut rng = Rng::new(7);
        for case in 0..2000 {
            let count = 1 + case % 4;
            let mut directions: Vec<Vector3<f64>> = (0..count).map(|_| unit(&mut rng)).collect();
            if case % 5 == 0 && count > 1 {
                directions[1] = -directions[0];
            }
            if case % 7 == 0 && count > 2 {
                directions[2] = directions[0];
            }
            let moved = unit(&mut rng) * 10f64.powf(-4.5 + 1.5 * rng.uniform());
            let fit = realised_reaction(&moved, &directions);
            let rest = moved - fit;
            let scale = moved.norm();
            for u in &directions {
                assert!(
                    u.dot(&rest) <= 1e-9 * scale,
                    "case {case}: rest along a direction"
                );
            }
            assert!(
                fit.dot(&rest).abs() <= 1e-9 * scale * scale,
                "case {case}: not orthogonal"
            );
            assert!(
                in_cone(&fit, &directions, 1e-9 * scale),
                "case {case}: fit {fit:?} outside the cone of {directions:?}"
            );
        }
    }

    /// Whether `v` is a non-negative combination of `directions` (to `tol`): by Caratheodory
    /// it is one of at most three of them if of any, so each such subset is solved for its
    /// coefficients (by SVD) and checked.
    fn in_cone(v: &Vector3<f64>, directions: &[Vector3<f64>], tol: f64) -> bool {
        (1..(1u32 << directions.len())).any(|subset| {
            let chosen: Vec<Vector3<f64>> = (0..directions.len())
                .filter(|j| subset >> j & 1 == 1)
                .map(|j| directions[j])
                .collect();
            if chosen.len() > 3 {
                return false;
            }
            let basis = nalgebra::Matrix3xX::from_columns(&chosen);
            let Ok(a) = basis.clone().svd(true, true).solve(v, 1e-12) else {
                return false;
            };
            a.iter().all(|&x| x >= 0.0) && (basis * a - v).norm() <= tol
        })
    }
}
