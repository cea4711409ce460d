//! The guarantee pass after the descent (not in Lu et al. 2023): CCD from the safe positions
//! once more, clamping every vertex of a colliding pair to its time of impact.

use std::time::Instant;

use nalgebra::Vector3;
use rayon::prelude::*;

use super::super::broad_phase::ContactMesh;
use super::super::primitive_pairs::Pair;
use super::params::{ContactParams, CLAMP_PASSES};
use super::refill;
use super::stats::ContactStats;
use super::workspace::Workspace;
use crate::timing::millis;

/// The final clamp (see the module doc) over the live pairs in `work`: marks the vertices it
/// moves in `work.unmeasured`, adds to `stats` their number, the CCD queries it made and its
/// time (a refresh of the live pairs after a clamp counting as broad phase). Returns, where
/// it refreshed the live pairs, how many of those before are still in their places at the
/// head of the list (the least over its refreshes).
pub(super) fn guarantee(
    safe: &[Vector3<f64>],
    z: &mut [Vector3<f64>],
    fixed: &[bool],
    mesh: &ContactMesh,
    params: &ContactParams,
    work: &mut Workspace,
    stats: &mut ContactStats,
) -> Option<usize> {
    let t = Instant::now();
    let (floor, reach) = (params.eps * params.thickness, params.barrier().reach());
    let Workspace {
        live,
        target,
        motion,
        drift,
        floors,
        toi,
        vertex_toi: per_vertex,
        clamped,
        unmeasured,
        ..
    } = work;
    refill(clamped, z.len(), false);
    let mut stale = true;
    let mut kept: Option<usize> = None;
    let mut refreshing = 0.0;
    for pass in 0..=CLAMP_PASSES {
        if stale {
            // Each pair's separation floor, from its distance at the safe positions; pairs
            // already touching there cannot be helped and are skipped, and so are pairs whose
            // distance bound stays above the floor (the clamps below only bring vertices
            // closer to safety, so the bound holds on every path `z^{k-1} -> z` the passes
            // test).
            live.pairs
                .par_iter()
                .zip(&live.start)
                .map(|(p, &d0)| {
                    let min = floor.min(0.9 * d0);
                    if p.distance_bound(d0, motion, drift) > min {
                        0.0
                    } else {
                        min
                    }
                })
                .collect_into_vec(floors);
        }
        stats.ccd_queries += floors.iter().filter(|&&min| min > 0.0).count();
        live.pairs
            .par_iter()
            .zip(&*floors)
            .map(|(p, &min)| {
                if min > 0.0 {
                    p.ccd(safe, z, min, &params.ccd)
                } else {
                    None
                }
            })
            .collect_into_vec(toi);
        if toi.iter().all(Option::is_none) {
            break;
        }
        vertex_toi(&live.pairs, toi, per_vertex, z.len());
        for (i, zi) in z.iter_mut().enumerate() {
            let ti = per_vertex[i];
            if fixed[i] || ti >= 1.0 {
                continue;
            }
            let keep = if pass < CLAMP_PASSES { ti } else { 0.0 };
            *zi = safe[i] + (*zi - safe[i]) * keep;
            live.deviation[i] = (1.0 - keep) * motion[i] + keep * live.deviation[i];
            clamped[i] = true;
            unmeasured[i] = true;
        }
        // The clamps may have taken a vertex beyond its allowance: the next pass and the
        // final evaluation look at the clamped positions.
        let r = Instant::now();
        let refreshed = live.cover(safe, target, mesh, reach, stats);
        stale = refreshed.is_some();
        kept = match (kept, refreshed) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        refreshing += millis(r);
    }
    stats.clamped = clamped.iter().filter(|&&m| m).count();
    stats.broad_phase_ms += refreshing;
    stats.ccd_ms += millis(t) - refreshing;
    kept
}

/// Writes into `t` the smallest time of impact per vertex over the pairs that collide (1 where
/// none).
pub(super) fn vertex_toi(pairs: &[Pair], toi: &[Option<f64>], t: &mut Vec<f64>, n: usize) {
    refill(t, n, 1.0);
    for (pair, hit) in pairs.iter().zip(toi) {
        if let Some(time) = hit {
            for &v in &pair.v {
                t[v as usize] = t[v as usize].min(*time);
            }
        }
    }
}
