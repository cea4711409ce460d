//! The rigid coarse correction of the Jacobi global step: a two-level method whose coarse
//! space is the translation of each free particle body (beyond the 2017 paper, issue 38).
//!
//! **Why.** One Jacobi sweep on `(M + h^2 L) delta = r` ([`super::directions::jacobi`]) moves
//! a body's translation by only `m_i / D_i` of what its residual asks (`L` holds no stiffness
//! against a translation: an error `e` of the whole body leaves `r_i = -m_i e`, and the sweep
//! moves `m_i e / D_i`). At `h = 1/30` s a 25K-particle cube of E 2e5 Pa has `D_i / m_i` about
//! 5e4: after an impact the body hovers above the floor for hundreds of iterations. And a body
//! in free flight beside one in contact starts from the step's start positions (the family's
//! initial guess, [`crate::solve::sissm`], is chosen for all its bodies at once), a
//! translation error of `h v + h^2 g` that the sweep removes at the same `m_i / D_i` rate.
//!
//! **What.** After the sweep, each body that no collider or other body touched in the last
//! trial (`touched`, [`super::step`]) and that has no pins moves by the translation `t` (m)
//! that cancels the net force its residual leaves after the sweep, as a rigid body of its mass
//! `M` (kg) would: `M t = sum_i (r_i - m_i delta_i)`, `delta_i += t`. This is the Galerkin
//! coarse solve of eq. 12's linear system on the body's translations (`L` has no stiffness
//! against them, and the kernel's internal forces sum to zero over a body, so
//! `sum_i r_i = M (c* - c)` with `c`, `c*` the centres of mass of the iterate and of the
//! inertial targets), applied after the fine sweep. It leaves the fixed point alone: at the
//! solution every residual of a free body is zero, and so is the sum. Rotations are left to
//! the sweep: the deviatoric bond forces (eq. 10) are not central, so their torques need not
//! sum to zero over a body, and a rigid rotation fitted to them would spin it.
//!
//! **Contacts.** A body in contact is left to the fine iteration: the particles a collider,
//! the repulsion or a membrane (a coupling's reaction) holds carry its reaction in their residual, which no translation of the body
//! takes away (summing the reactions instead is wrong: measured in the Jacobi metric, `D_i` per
//! metre, a reaction is some 5e4 times what the body's mass asks for the same move). The
//! translation of a free body is shortened so that it carries no particle into a collider or
//! another body's particle (moved by that body's own translation) beyond where the sweep put
//! it: a body above the floor moves down until its lowest particle touches.
//!
//! The Chebyshev history `y_prev` moves with the body, so that the extrapolation acts on the
//! fine iteration's error and does not repeat the translation.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::collider::ColliderModel;
use crate::real::Real;
use crate::solve::points::Points;

use super::system::ParticleSystem;

/// Adds the translation of every free, unpinned body (module doc) to `sys.delta`, the fine
/// sweep's move from the residual `sys.current.residual`, and to the Chebyshev history. A
/// body with a particle that another family holds (`coupled`, a membrane's reaction on it,
/// [`crate::solve::coupling`]) is in contact too.
pub(crate) fn correct<T: Real>(
    sys: &mut ParticleSystem<T>,
    colliders: &[ColliderModel<T>],
    coupled: &[Vector3<T>],
) {
    let mut moves = std::mem::take(&mut sys.rigid);
    moves.clear();
    for range in sys.points.ranges.iter().cloned() {
        let (points, touched) = (&sys.points, &sys.touched);
        let held = range.clone().any(|i| {
            let coupled = coupled.get(i).is_some_and(|r| *r != Vector3::zeros());
            points.pinned[i] || touched[i] || coupled
        });
        moves.push(if held { None } else { translation(sys, range) });
    }
    let fractions: Vec<T> = (0..moves.len())
        .map(|b| moves[b].map_or(T::zero(), |_| T::of(reach(sys, b, &moves, colliders))))
        .collect();
    for (t, s) in moves.iter_mut().zip(fractions) {
        *t = t.filter(|_| s > T::zero()).map(|t| t * s);
    }
    let points = &mut sys.points;
    let history = points.y_prev.len() == points.y.len();
    for (range, t) in points.ranges.iter().zip(&moves) {
        if let Some(t) = t {
            sys.delta[range.clone()]
                .par_iter_mut()
                .for_each(|d| *d += t);
            if history {
                points.y_prev[range.clone()]
                    .par_iter_mut()
                    .for_each(|p| *p += t);
            }
        }
    }
    sys.rigid = moves;
}

/// The translation (m) of the body in `range` (module doc), summed in f64 in particle order
/// (the same for any thread count); `None` for a body without mass.
fn translation<T: Real>(
    sys: &ParticleSystem<T>,
    range: std::ops::Range<usize>,
) -> Option<Vector3<T>> {
    let (mass, r, delta) = (&sys.points.mass, &sys.current.residual, &sys.delta);
    let (mut total, mut force) = (0.0, Vector3::<f64>::zeros());
    for i in range {
        total += mass[i].to_f64();
        force += (r[i] - delta[i] * mass[i]).map(|c| c.to_f64());
    }
    (total > 0.0).then(|| (force / total).map(T::of))
}

/// The largest fraction (in `[0, 1]`) of body `b`'s translation that carries none of its
/// particles from where the sweep put them (`y + delta`) into a collider beyond its margin, or
/// into a particle of another body (moved by that body's translation) beyond the repulsion's
/// distance, or deeper than it already is: linear in the distance between the two ends.
fn reach<T: Real>(
    sys: &ParticleSystem<T>,
    b: usize,
    moves: &[Option<Vector3<T>>],
    colliders: &[ColliderModel<T>],
) -> f64 {
    let points = &sys.points;
    let t = moves[b].expect("a body with a translation");
    let body_of = |j: usize| points.ranges.partition_point(|r| r.end <= j);
    let fraction = |d0: f64, d1: f64| {
        if d1 >= d0.min(0.0) {
            1.0
        } else if d0 > 0.0 {
            d0 / (d0 - d1)
        } else {
            0.0
        }
    };
    points.ranges[b]
        .clone()
        .into_par_iter()
        .map(|i| {
            let from = points.y[i] + sys.delta[i];
            let to = from + t;
            let margin = points.margin[i];
            let walls = Points::colliders_of(&points.collides, i, colliders)
                .iter()
                .map(|c| {
                    let d0 = (c.signed_distance(&from) - margin).to_f64();
                    let d1 = (c.signed_distance(&to) - margin).to_f64();
                    fraction(d0, d1)
                })
                .fold(1.0, f64::min);
            let Some(repulsion) = &sys.repulsion else {
                return walls;
            };
            repulsion
                .partners(i)
                .iter()
                .map(|&j| (j as usize, body_of(j as usize)))
                .filter(|&(_, c)| c != b)
                .map(|(j, c)| {
                    let other = points.y[j] + sys.delta[j];
                    let moved = other + moves[c].unwrap_or_else(Vector3::zeros);
                    let reach = (margin + points.margin[j]).to_f64();
                    let d0 = (from - other).norm().to_f64() - reach;
                    let d1 = (to - moved).norm().to_f64() - reach;
                    fraction(d0, d1)
                })
                .fold(walls, f64::min)
        })
        .reduce(|| 1.0, f64::min)
}
