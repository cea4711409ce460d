//! The descent of the contact local step, Algorithm 2 of Lu et al. 2023: CCD and clamps
//! (lines 4-18), the barrier's push (lines 19-23, eq. 49), the step (eq. 53 or the curvature
//! rule) and the stopping test, then the guarantee pass and the sums at the final positions.

use std::time::Instant;

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::timing::millis;

use super::super::barrier_push::{barrier_energy, VertexSums};
use super::super::broad_phase::ContactMesh;
use super::super::parallel_fade::sin2_limit;
use super::super::primitive_pairs::Pair;
use super::friction::{friction_moves, Friction};
use super::guarantee::{guarantee, vertex_toi};
use super::live_pairs::FIRST_ALLOWANCE;
use super::moves::{compliance_bound, damped_move, proximal_pull, settle_or_move, Move, PushOut};
use super::params::{ContactParams, DescentStep, ProximalWeights, SETTLED_SHARE};
use super::refill;
use super::stats::ContactStats;
use super::workspace::Workspace;
use crate::geometry::distance::Closest;
use crate::symmetric::SymmetricMatrix3;

/// Forgets every pair's time of impact and nearness, and marks every vertex moved, so that the
/// next CCD queries all `pairs` (a count) afresh.
pub(super) fn restart_ccd(
    pairs: usize,
    toi: &mut Vec<Option<f64>>,
    near: &mut Vec<bool>,
    changed: &mut [bool],
) {
    refill(toi, pairs, None);
    refill(near, pairs, true);
    changed.iter_mut().for_each(|c| *c = true);
}

/// Runs the local step: `positions` holds `y^k` on entry and `z` on return; `safe` is
/// `z^{k-1}`, free of intersections; `fixed` vertices are never moved; `weights` gives the
/// metric of eq. 47's proximal term ([`ProximalWeights`]; `None`: the identity, see
/// [`super::ProximalMetric`]), kept in `work` ([`Workspace::weights`]). `tol` is the solver's
/// tolerance (m; 0: none), which bounds the stopping distance
/// ([`ContactParams::stop_distance`]). `push_out`
/// ([`PushOut`]) takes a vertex out of the colliders after every descent move, in the move's
/// metric, so the barrier cannot push a membrane into a collider. (The final clamp moves a
/// vertex back towards its safe position along a straight line, which can cut into a curved
/// collider by the sagitta of that chord, `L^2 / 8R` for a chord of length `L` on a ball of
/// radius `R`.) `work` holds the buffers between calls.
#[allow(clippy::too_many_arguments)]
pub fn resolve_contacts(
    safe: &[Vector3<f64>],
    positions: &mut [Vector3<f64>],
    fixed: &[bool],
    weights: Option<&ProximalWeights>,
    mesh: &ContactMesh,
    params: &ContactParams,
    tol: f64,
    push_out: &PushOut,
    work: &mut Workspace,
) -> ContactStats {
    let mut stats = ContactStats::default();
    let barrier = params.barrier();
    let (xi, eps, mu) = (params.thickness, params.eps, params.weight);
    let reach = barrier.reach();
    let n = positions.len();

    let t = Instant::now();
    work.target.clear();
    work.target.extend_from_slice(positions);
    let first = FIRST_ALLOWANCE * eps * xi;
    work.live.start(
        safe,
        &work.target,
        first,
        mesh,
        reach,
        sin2_limit(params.parallel_angle),
        &mut stats,
    );
    // The rest gaps: seeded from the pairs at the step's start (the safe positions of its
    // first local step) once the solver has armed them, and the scales taken again whenever
    // the gaps or the reach changed.
    if work.live.gaps.pending() {
        let live = &mut work.live;
        live.gaps.seed(&live.pairs, &live.start, mesh, reach);
    }
    work.live.gaps.set_reach(reach);
    if work.live.gaps.take_changed() {
        work.live.rescale(0);
    }
    stats.broad_phase_ms += millis(t);
    work.weights.clear();
    if work.live.pairs.is_empty() {
        refill(&mut work.push, n, Vector3::zeros());
        work.warm.clear();
        return stats;
    }
    // The sums of eq. 49 and 53 need no reset: the local step's first update of them (in the
    // loop or, with no iteration, at the final positions) has no unchanged pair and writes
    // every vertex's, and nothing reads them before it.
    work.push.resize(n, Vector3::zeros());
    work.alpha.resize(n, 0.0);
    work.curvature.resize(n, SymmetricMatrix3::zeros());
    if let Some(fill) = weights {
        fill(&mut work.weights);
    }
    // Moved out for the descent, which borrows the rest of `work`; put back below.
    let metric = std::mem::take(&mut work.weights);
    let weights = weights.map(|_| &metric[..]);

    let z = positions;
    safe.par_iter()
        .zip(&*z)
        .map(|(s, y)| (y - s).norm())
        .collect_into_vec(&mut work.motion);
    let bound = barrier.derivative_bound();
    refill(&mut work.drift, n, 0.0);
    refill(&mut work.last_move, n, Vector3::zeros());
    refill(&mut work.damping, n, 1.0);
    // Vertices moved since the last CCD: a pair none of whose vertices moved keeps its time.
    // After the first iteration a vertex moves at most `2 eps xi` per iteration (a step of at
    // most `eps xi` under either rule, and a projection out of a collider no longer than the
    // step's depth into it), so only pairs that were within `(1 + 4 eps) xi` can reach `xi`:
    // the others skip the CCD. (`changed` is only sized here: `restart_ccd` marks every vertex.)
    work.changed.resize(n, true);
    if params.warm_start && work.warm.len() == n {
        // Line 2 with the warm start: a move like a descent move, so it counts as drift and
        // deviation (and may refresh the live pairs) before the first CCD sees the path.
        work.drift
            .par_iter_mut()
            .zip(&mut work.live.deviation[..])
            .zip(&mut z[..])
            .zip(&work.warm)
            .enumerate()
            .for_each(|(i, (((di, ei), zi), offset))| {
                if fixed[i] || *offset == Vector3::zeros() {
                    return;
                }
                let before = *zi;
                *zi += offset;
                push_out(i, &before, zi, None);
                *di = (*zi - before).norm();
                *ei = *di;
            });
        let t = Instant::now();
        work.live.cover(safe, &work.target, mesh, reach, &mut stats);
        stats.broad_phase_ms += millis(t);
    }
    restart_ccd(
        work.live.pairs.len(),
        &mut work.toi,
        &mut work.near,
        &mut work.changed,
    );
    let near_distance = (1.0 + 4.0 * eps) * xi;
    let stop = params.stop_distance(tol);
    let settled = SETTLED_SHARE * stop;
    // Eq. 53's step in the metric `W` bounds the push's slope times the largest `|W_i^-1|`
    // over the free vertices: `W` is fixed through the local step, so once.
    let compliance = match (params.step, weights) {
        (DescentStep::Uniform, Some(w)) => (0..n)
            .into_par_iter()
            .filter(|&i| !fixed[i])
            .map(|i| compliance_bound(&w[i]))
            .reduce(|| 0.0, f64::max),
        _ => 1.0,
    };
    refill(&mut work.unmeasured, n, true);
    // The live pairs before this one have their closest points at the current iterate, as
    // far as the list goes (vertices in `unmeasured` moved since).
    let mut measured = 0;
    let Workspace {
        live,
        motion,
        target,
        drift,
        push,
        alpha,
        curvature,
        changed,
        unmeasured,
        fresh,
        vertex_toi: per_vertex,
        toi,
        near,
        closest,
        last_move,
        damping,
        barrier_push: sums,
        ..
    } = work;
    for _ in 0..params.max_iters {
        // Lines 4-18: CCD between the safe positions and z^m, clamp above the threshold.
        let t = Instant::now();
        let changed_now = &*changed;
        // Every vertex of the path from `z^{k-1}` to `z^m` is within `motion_i + drift_i` of
        // `z^{k-1}` (see `pair_cache`): a pair whose distance bound over such moves exceeds
        // `xi` cannot reach `xi` on it, so its CCD is skipped.
        let drift_now = &*drift;
        stats.ccd_queries += toi
            .par_iter_mut()
            .zip(&live.pairs)
            .zip(&*near)
            .zip(&live.start)
            .map(|(((hit, p), &near), &d0)| {
                if !near || p.distance_bound(d0, motion, drift_now) > xi {
                    *hit = None;
                } else if p.v.iter().any(|&v| changed_now[v as usize]) {
                    *hit = p.ccd(safe, z, xi, &params.ccd);
                    return 1;
                }
                0
            })
            .sum::<usize>();
        vertex_toi(&live.pairs, toi, per_vertex, n);
        z.par_iter_mut()
            .zip(changed.par_iter_mut())
            .zip(unmeasured.par_iter_mut())
            .zip(live.deviation.par_iter_mut())
            .enumerate()
            .for_each(|(i, (((zi, moved), unmeasured), ei))| {
                let ti = per_vertex[i];
                *moved = !fixed[i] && ti < 1.0 && ti > params.toi_threshold;
                if *moved {
                    *zi = safe[i] + (*zi - safe[i]) * ti;
                    *ei = (1.0 - ti) * motion[i] + ti * *ei;
                    *unmeasured = true;
                }
            });
        stats.ccd_ms += millis(t);
        // The clamps may have taken a vertex beyond its allowance.
        let t = Instant::now();
        if let Some(kept) = live.cover(safe, target, mesh, reach, &mut stats) {
            restart_ccd(live.pairs.len(), toi, near, changed);
            measured = measured.min(kept);
        }
        stats.broad_phase_ms += millis(t);

        // Lines 19-27: distances, weights and the descent direction of eq. 49, evaluated
        // afresh for the pairs with a vertex that moved since (and the pairs new in the list).
        let t = Instant::now();
        closest_within(
            &live.pairs,
            &live.start,
            motion,
            drift,
            reach,
            z,
            (measured, &*unmeasured),
            closest,
            fresh,
        );
        // A pair left out by `closest_within` is not near: it is at least `reach` apart,
        // which is beyond `(1 + 4 eps) xi` whenever `d_hat >= 4 eps xi` (the defaults), so the
        // full evaluation would not call it near either.
        near.par_iter_mut()
            .zip(&*closest)
            .for_each(|(near, c)| *near = c.separation.norm() < near_distance);
        sums.update(
            &live.pairs,
            (live.version, measured),
            closest,
            (&live.fade, &live.scale),
            fresh,
            &barrier,
            mu,
            VertexSums {
                push,
                alpha,
                curvature,
            },
        );
        #[cfg(test)]
        super::tests::assert_as_if_evaluated_afresh(
            live,
            (motion, drift, reach),
            z,
            closest,
            (&barrier, mu),
            (push, alpha, curvature),
        );
        measured = live.pairs.len();
        unmeasured.par_iter_mut().for_each(|u| *u = false);
        let lambda = match params.step {
            DescentStep::Uniform => {
                let (alpha_0, farthest) = (0..n)
                    .into_par_iter()
                    .filter(|&i| !fixed[i])
                    .map(|i| (alpha[i], (target[i] - z[i]).norm()))
                    .reduce(|| (0.0, 0.0), |a, b| (a.0.max(b.0), a.1.max(b.1)));
                // Eq. 53, in the metric `W` (the push's bound times the largest `|W_i^-1|`).
                Some((eps * xi / (mu * alpha_0 * bound * compliance + farthest)).min(1.0))
            }
            DescentStep::Curvature => None,
        };
        let longest = eps * xi;
        let moved = z
            .par_iter_mut()
            .zip(drift.par_iter_mut())
            .zip(changed.par_iter_mut())
            .zip(unmeasured.par_iter_mut())
            .zip(live.deviation.par_iter_mut())
            .zip(last_move.par_iter_mut())
            .zip(damping.par_iter_mut())
            .enumerate()
            .map(|(i, ((((((zi, di), ci), ui), ei), last), damp))| {
                if fixed[i] {
                    return 0.0;
                }
                let before = *zi;
                let direction = push[i] + proximal_pull(weights, i, &(target[i] - *zi));
                // No push and at its target (most vertices of a draping cloth): no move. The
                // global step left its target out of the colliders.
                if direction == Vector3::zeros() {
                    return 0.0;
                }
                // The move is `M_i^-1` times the direction, taken in the metric `M_i^-1`:
                // `M_i = W_i / lambda` for eq. 53's step, `W_i + K_i` for the curvature rule
                // (None: the identity). `M_i` is positive definite unless `K_i` is not finite;
                // then the vertex stays (a NaN position is caught by the global step). With
                // `W_i = I` away from contact `K_i = 0`: no inverse needed.
                let k = &curvature[i];
                let system = match (lambda, weights) {
                    (Some(_), None) => None,
                    (Some(_), Some(w)) => Some(w[i]),
                    (None, Some(w)) => Some(*k + w[i]),
                    (None, None) => (*k != SymmetricMatrix3::zeros()).then(|| k.plus_identity(1.0)),
                };
                let (step, metric) = match system.map(|s| s.try_inverse()) {
                    None => (direction, None),
                    Some(Some(inverse)) => (inverse.mul_vector(&direction), Some(inverse)),
                    Some(None) => (Vector3::zeros(), None),
                };
                // The longest move: the curvature rule's bound (eq. 53's step is within it).
                let (proposed, cap) = match lambda {
                    Some(lambda) => (step * lambda, None),
                    None => (step, Some(longest)),
                };
                let take = |damp: f64| {
                    damped_move(i, &before, &proposed, metric.as_ref(), cap, damp, push_out)
                };
                let step = match settle_or_move(&before, take, settled, last, damp) {
                    Move::Settled(length) => return length,
                    Move::Taken { end, length } => {
                        *zi = end;
                        length
                    }
                };
                *ci = true;
                *ui = true;
                *di += step;
                *ei += step;
                step
            })
            .reduce(|| 0.0, f64::max);
        stats.iterations += 1;
        stats.descent_ms += millis(t);

        // A vertex moved beyond its allowance: the live pairs may miss a pair now (NaN counts
        // as beyond). Refresh them and start the CCD afresh on the new list.
        let t = Instant::now();
        if let Some(kept) = live.cover(safe, target, mesh, reach, &mut stats) {
            restart_ccd(live.pairs.len(), toi, near, changed);
            measured = measured.min(kept);
        }
        stats.broad_phase_ms += millis(t);
        if moved < stop {
            break;
        }
    }

    // Coulomb friction between membranes (see `friction.rs`): a move like a descent move, out
    // of the colliders, counted as drift and deviation (and refreshing the live pairs).
    work.friction_move.clear();
    if work.step_start.len() == n {
        let t = Instant::now();
        let friction = Friction {
            coefficient: &work.friction,
            start: &work.step_start,
        };
        let moves = &mut work.friction_move;
        if friction_moves(
            &friction,
            &work.barrier_push,
            (z, &work.push),
            weights,
            fixed,
            moves,
        ) {
            z.par_iter_mut()
                .zip(&mut work.friction_move[..])
                .zip(&mut work.drift[..])
                .zip(&mut work.live.deviation[..])
                .zip(&mut work.changed[..])
                .zip(&mut work.unmeasured[..])
                .enumerate()
                .for_each(|(i, (((((zi, m), di), ei), ci), ui))| {
                    if *m == Vector3::zeros() {
                        return;
                    }
                    let before = *zi;
                    *zi += *m;
                    push_out(i, &before, zi, None);
                    *m = *zi - before;
                    let length = m.norm();
                    (*di, *ei, *ci, *ui) = (*di + length, *ei + length, true, true);
                });
            if let Some(kept) = work.live.cover(safe, &work.target, mesh, reach, &mut stats) {
                restart_ccd(
                    work.live.pairs.len(),
                    &mut work.toi,
                    &mut work.near,
                    &mut work.changed,
                );
                measured = measured.min(kept);
            }
        } else {
            work.friction_move.clear();
        }
        stats.descent_ms += millis(t);
    }

    if let Some(kept) = guarantee(safe, z, fixed, mesh, params, work, &mut stats) {
        measured = measured.min(kept);
    }
    work.weights = metric;

    // The sums at the final positions: as in the loop, only the pairs with a vertex that
    // moved since the last evaluation (the last descent move, the guarantee's clamps) or new
    // in the list are evaluated afresh.
    let t = Instant::now();
    closest_within(
        &work.live.pairs,
        &work.live.start,
        &work.motion,
        &work.drift,
        reach,
        z,
        (measured, &work.unmeasured),
        &mut work.closest,
        &mut work.fresh,
    );
    let scales = &work.live.scale;
    stats.active_pairs = work
        .closest
        .par_iter()
        .enumerate()
        .filter(|(k, c)| c.separation.norm() < scales.get(*k).copied().unwrap_or(1.0) * reach)
        .count();
    stats.barrier = barrier_energy(
        &work.closest,
        (&work.live.fade, &work.live.scale),
        &barrier,
        mu,
    );
    work.barrier_push.update(
        &work.live.pairs,
        (work.live.version, measured),
        &work.closest,
        (&work.live.fade, &work.live.scale),
        &work.fresh,
        &barrier,
        mu,
        VertexSums {
            push: &mut work.push,
            alpha: &mut work.alpha,
            curvature: &mut work.curvature,
        },
    );
    #[cfg(test)]
    super::tests::assert_as_if_evaluated_afresh(
        &work.live,
        (&work.motion, &work.drift, reach),
        z,
        &work.closest,
        (&barrier, mu),
        (&work.push, &work.alpha, &work.curvature),
    );
    // The next warm start: this step's own move where the barrier pushes and no clamp of
    // the guarantee pass moved the vertex.
    work.warm.clear();
    if params.warm_start {
        work.warm.par_extend(
            work.push
                .par_iter()
                .zip(&work.clamped)
                .zip(&*z)
                .zip(&work.target)
                .map(|(((p, &clamped), zi), yi)| {
                    if clamped || *p == Vector3::zeros() {
                        Vector3::zeros()
                    } else {
                        zi - yi
                    }
                }),
        );
    }
    stats.descent_ms += millis(t);
    stats
}

/// Writes into `closest` the closest points at `z` of the pairs from `measured` on and of those
/// with a vertex marked in `unmeasured` (`(measured, unmeasured)`), and marks them in `fresh`;
/// the others keep theirs, as none of their vertices moved. `closest[..measured]` must hold the
/// last evaluation of the same pairs in the same places, with `start` and `drift` unchanged
/// for them since (`drift` changes only for a vertex that moves, which is then marked). A
/// pair whose distance bound (from its distance `start` at the safe positions, the vertices'
/// `motion` and their total descent moves `drift`, all m) is at least `reach` feels no
/// barrier, so its closest points are not needed, and it gets [`FAR`].
#[allow(clippy::too_many_arguments)]
pub(super) fn closest_within(
    pairs: &[Pair],
    start: &[f64],
    motion: &[f64],
    drift: &[f64],
    reach: f64,
    z: &[Vector3<f64>],
    (measured, unmeasured): (usize, &[bool]),
    closest: &mut Vec<Closest>,
    fresh: &mut Vec<bool>,
) {
    closest.resize(pairs.len(), FAR);
    fresh.resize(pairs.len(), false);
    closest
        .par_iter_mut()
        .zip(fresh.par_iter_mut())
        .zip(pairs.par_iter().zip(start))
        .enumerate()
        .for_each(|(k, ((c, fresh), (p, &d0)))| {
            *fresh = k >= measured || p.v.iter().any(|&v| unmeasured[v as usize]);
            if !*fresh {
                return;
            }
            *c = if p.distance_bound(d0, motion, drift) >= reach {
                FAR
            } else {
                p.closest(z)
            };
        });
}

/// Stands for the closest points of a pair beyond the barrier's reach: no weights, an infinite
/// separation (so no barrier, not active, and NaN as its direction is never taken).
const FAR: Closest = Closest {
    weights: [0.0; 4],
    separation: Vector3::new(f64::INFINITY, 0.0, 0.0),
};
