//! How one descent iteration moves a vertex: the proximal term's pull, eq. 53's compliance
//! bound, the damping of moves that reverse, the settling of short ones, and the way out of
//! the colliders.

use nalgebra::Vector3;

use crate::symmetric::SymmetricMatrix3;

/// Keeps vertex `i` out of the colliders after a move from `from` (outside them) to `z_i`:
/// `push_out(i, from, z_i, metric)` keeps `z_i` on the side of each collider the move came
/// from, moves it back to their surfaces by the shortest move in the metric whose inverse is
/// `metric` (symmetric positive definite; `None`: the identity, a normal projection), and then
/// onto them wherever the surface's curvature left it inside.
pub type PushOut<'a> =
    dyn Fn(usize, &Vector3<f64>, &mut Vector3<f64>, Option<&SymmetricMatrix3<f64>>) + Sync + 'a;

/// The proximal term's pull on vertex `i`, `W_i (y_i^k - z_i)` (m) for `to_target =
/// y_i^k - z_i` (`weights`: see [`super::resolve_contacts`]).
#[inline]
pub(super) fn proximal_pull(
    weights: Option<&[SymmetricMatrix3<f64>]>,
    i: usize,
    to_target: &Vector3<f64>,
) -> Vector3<f64> {
    weights.map_or(*to_target, |w| w[i].mul_vector(to_target))
}

/// A bound of `|W^-1|` (the largest absolute row sum of the inverse, dimensionless; 0 where
/// `W` is not invertible, as the vertex then stays).
pub(super) fn compliance_bound(w: &SymmetricMatrix3<f64>) -> f64 {
    w.try_inverse().map_or(0.0, |c| {
        let [c00, c11, c22] = c.diagonal.map(f64::abs);
        let [c01, c02, c12] = c.upper.map(f64::abs);
        (c00 + c01 + c02).max(c01 + c11 + c12).max(c02 + c12 + c22)
    })
}

/// A vertex's descent move, as [`settle_or_move`] decides it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Move {
    /// Shorter than the settled length: not taken (the vertex stays); the move's length (m),
    /// which the stopping test still counts.
    Settled(f64),
    /// Taken: where the vertex goes (m), and the move's length (m).
    Taken { end: Vector3<f64>, length: f64 },
}

/// Decides a vertex's descent move from `before` (m), where `take(damp)` is where a move at
/// damping `damp` ends ([`damped_move`]). A move at least `settled` (m) long that points
/// against `last`, the vertex's last move taken, overshot: its damping `damp` is halved for the
/// rest of the local step and the move taken again at it (see the module doc; the moves as
/// taken are compared, so a proposal into a collider that holds the vertex points against a
/// slide along it). A move shorter than `settled` is not taken and changes neither `damp` nor
/// `last` (it reverses nothing); a move taken becomes `last`.
pub(super) fn settle_or_move(
    before: &Vector3<f64>,
    take: impl Fn(f64) -> Vector3<f64>,
    settled: f64,
    last: &mut Vector3<f64>,
    damp: &mut f64,
) -> Move {
    let mut end = take(*damp);
    if (end - before).norm() >= settled && (end - before).dot(last) < 0.0 {
        *damp *= 0.5;
        end = take(*damp);
    }
    let length = (end - before).norm();
    if length < settled {
        return Move::Settled(length);
    }
    *last = end - before;
    Move::Taken { end, length }
}

/// Where vertex `i` goes from `before` on a descent move of `damp` times `proposed` (m):
/// out of the colliders in the proposal's metric (`metric`, the inverse of `W_i + K_i`; `None`:
/// the identity), then cut to `damp` times `longest` (m; `None`: no cut) and taken out of the
/// colliders again, by a normal projection, where the cut point is inside.
///
/// A normal projection after a move in `(W_i + K_i)^-1` would stop where that move points
/// straight into the collider, with the part `(W_i + K_i) n` of the descent direction along the
/// surface unbalanced. The cut comes after the projection: a proposal mostly into the collider
/// would otherwise be cut to a crawl along it (and the metric's slide along a surface can be
/// long where the barrier is stiff and nearly normal to it). The cut point lies on the chord
/// from `before` to the projected end, which cuts into a curved collider (by about `f (1 - f)
/// L^2 / 2R` at the fraction `f` of a chord of length `L` on a ball of radius `R`): hence the
/// second projection.
pub(super) fn damped_move(
    i: usize,
    before: &Vector3<f64>,
    proposed: &Vector3<f64>,
    metric: Option<&SymmetricMatrix3<f64>>,
    longest: Option<f64>,
    damp: f64,
    push_out: &PushOut,
) -> Vector3<f64> {
    let mut at = before + proposed * damp;
    push_out(i, before, &mut at, metric);
    if let Some(longest) = longest {
        let (slide, limit) = (at - before, longest * damp);
        let length = slide.norm();
        if length > limit {
            at = before + slide * (limit / length);
            push_out(i, before, &mut at, None);
        }
    }
    at
}
