//! The first iterate of a step (Algorithm 1, line 2): the lowest-energy of a few candidate
//! starts, each kept out of the colliders, and its energy.

use rayon::prelude::*;

use crate::collider::ColliderModel;
use crate::membrane::Preconditioner;
use crate::parallel::chunked_sum;
use crate::real::Real;

use super::collider_passes::push_iterate_out_of_colliders;
use super::family::Family;
use super::points::Points;

/// A candidate first iterate of a step, for free points (pinned ones take `y*`, their
/// prescribed position).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Start {
    /// The inertial prediction `y* = y_t + h v_t + h^2 g`: exact in free flight.
    Prediction,
    /// The step's start `y_t`: exact at rest.
    Previous,
    /// The coast `y_t + h v_t` (`y*` without gravity's kick): exact for a rigid body moving
    /// along a frictionless collider that carries its weight.
    Coast,
}

/// Places `start` into the iterate `y`, kept out of the colliders.
fn place<T: Real>(points: &mut Points<T>, start: Start, h: T, colliders: &[ColliderModel<T>]) {
    let (y_start, y_star, velocity) = (&points.y_start, &points.y_star, &points.velocity);
    let pinned = &points.pinned;
    points.y.par_iter_mut().enumerate().for_each(|(i, y)| {
        *y = match start {
            _ if pinned[i] => y_star[i],
            Start::Prediction => y_star[i],
            Start::Previous => y_start[i],
            Start::Coast => y_start[i] + velocity[i] * h,
        };
    });
    push_iterate_out_of_colliders(points, colliders);
}

/// The coast's two inertial terms (J), over free points: the kinetic energy
/// `sum_i m_i |v_i|^2 / 2`, and the coast's inertial energy `sum_i m_i |y_t + h v_t - y*_i|^2
/// / (2 h^2) = sum_i m_i h^2 |g|^2 / 2` (gravity's share), a lower bound of its total energy.
fn coast_terms<T: Real>(points: &mut Points<T>, h: T) -> (f64, f64) {
    let inv_2h2 = 0.5 / (h.to_f64() * h.to_f64());
    let Points {
        y_start,
        y_star,
        velocity,
        pinned,
        mass,
        energy_chunks,
        ..
    } = points;
    let kinetic = chunked_sum(y_start.len(), energy_chunks, |i| {
        let free = if pinned[i] { 0.0 } else { 1.0 };
        free * 0.5 * mass[i].to_f64() * velocity[i].norm_squared().to_f64()
    });
    let share = chunked_sum(y_start.len(), energy_chunks, |i| {
        let free = if pinned[i] { 0.0 } else { 1.0 };
        let kick = y_star[i] - y_start[i] - velocity[i] * h;
        free * mass[i].to_f64() * kick.norm_squared().to_f64() * inv_2h2
    });
    (kinetic, share)
}

/// Starts the iteration from whichever candidate ([`Start`]) has the lowest variational
/// energy, and returns that energy; the responses are left evaluated at the chosen start
/// (ties keep the earlier candidate: `y*`, then `y_t`, then the coast).
///
/// `y*` is exact in free flight, but for a stiff body it can hold a large elastic energy
/// (a pinned sheet's first row of bonds stretched by `h^2 g`); starting there, a step that runs
/// out of iterations releases that energy as spurious motion. From `y_t` an unfinished step
/// moves too little instead, which dissipates. `E(y*)` is the elastic energy `U(y*)`, and
/// `E(y_t) >= m |y_t - y*|^2 / (2 h^2)`, so `y_t` is evaluated only when `U(y*)` exceeds that
/// inertial term: most dynamic steps cost one kernel pass here, not two.
///
/// A body resting on a collider while it moves along it (a cube sliding on a frictionless
/// floor) is neither: `y*` sinks it by `h^2 g` into the collider, whose push compresses its
/// contact layer by that much (87 % of the spacing for 1.25 cm particles at h = 1/30 s), an
/// impact to undo at every step, and `y_t` is `h v_t` behind. Where the family
/// [`Family::coasts`], a collider moved a point of `y*`, the body moves faster than a step of
/// gravity adds (the kinetic energy exceeds the coast's inertial term `M h^2 |g|^2 / 2`) and no
/// candidate so far is below that term, the coast `y_t + h v_t` is evaluated too: the exact
/// solution of a rigid slide on a frictionless collider. A body at rest or in free flight
/// never pays for it.
pub(crate) fn initial_guess<T: Real>(
    family: &mut dyn Family<T>,
    h: T,
    mode: Preconditioner,
    colliders: &[ColliderModel<T>],
) -> f64 {
    push_iterate_out_of_colliders(family.points_mut(), colliders);
    let pushed = family.coasts() && {
        let points = family.points();
        points.y.par_iter().zip(&points.y_star).any(|(y, s)| y != s)
    };
    family.evaluate_energy(mode);
    let mut best = (Start::Prediction, family.total_energy(h));
    let mut last = Start::Prediction;
    let mut weigh = |family: &mut dyn Family<T>, start: Start, best: &mut (Start, f64)| {
        place(family.points_mut(), start, h, colliders);
        family.evaluate(mode);
        last = start;
        let energy = family.total_energy(h);
        if energy < best.1 {
            *best = (start, energy);
        }
    };
    if best.1 > family.inertial_energy_at_start(h) {
        weigh(family, Start::Previous, &mut best);
    }
    if pushed {
        let (kinetic, share) = coast_terms(family.points_mut(), h);
        if kinetic > share && best.1 > share {
            weigh(family, Start::Coast, &mut best);
        }
    }
    if best.0 != last {
        place(family.points_mut(), best.0, h, colliders);
        family.evaluate(mode);
    }
    best.1
}
