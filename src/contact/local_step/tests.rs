//! Tests of the contact local step.

use nalgebra::Vector3;

use super::super::barrier::Barrier;
use super::super::barrier_push::tests::{assert_same_sums, sums_from_scratch, Sums};
use super::super::broad_phase::ContactMesh;
use super::super::parallel_fade::{default_parallel_angle, sin2_limit};
use super::super::primitive_pairs::Pair;
use super::descent::closest_within;
use super::live_pairs::LivePairs;
use super::moves::{damped_move, settle_or_move, Move};
use super::*;
use crate::geometry::distance::Closest;
use crate::symmetric::SymmetricMatrix3;

/// No colliders to keep out of.
const FREE: &PushOut = &|_, _, _, _| {};

/// No solver tolerance: the local step stops at [`STOP_FRACTION`] `eps xi`.
const NO_TOL: f64 = 0.0;

/// A [`PushOut`] for `colliders`: every move from where the vertex is, to their surfaces.
fn pushing_out_of(
    colliders: &[crate::collider::ColliderModel<f64>],
) -> impl Fn(usize, &Vector3<f64>, &mut Vector3<f64>, Option<&SymmetricMatrix3<f64>>) + Sync + '_ {
    move |_, from, zi, metric| {
        *zi = crate::collider::push_out_of_colliders(
            colliders,
            crate::collider::MoveStart::Now(*from),
            *zi,
            0.0,
            metric,
        );
    }
}

type Scene = (Vec<Vector3<f64>>, Vec<Vector3<f64>>, Vec<[u32; 3]>);

/// Two parallel triangles, the upper pushed through the lower by the "global step".
fn crossing() -> Scene {
    let v = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
    let lower = [v(0., 0., 0.), v(1., 0., 0.), v(0., 1., 0.)];
    let safe: Vec<_> = lower
        .iter()
        .copied()
        .chain(lower.iter().map(|p| p + v(0.1, 0.1, 0.01)))
        .collect();
    let target: Vec<_> = lower
        .iter()
        .copied()
        .chain(lower.iter().map(|p| p + v(0.1, 0.1, -0.01)))
        .collect();
    (safe, target, vec![[0, 1, 2], [3, 4, 5]])
}

#[test]
fn a_crossing_move_is_stopped_and_the_pair_kept_apart() {
    let (safe, target, triangles) = crossing();
    let params = ContactParams {
        thickness: 2e-3,
        d_hat: 4e-3,
        ..ContactParams::default()
    };
    let body = [0, 0];
    let mesh = ContactMesh {
        triangles: &triangles,
        body: &body,
        self_contact: &[true],
    };
    let mut z = target.clone();
    let fixed = vec![false; 6];
    let mut work = Workspace::default();
    let stats = resolve_contacts(
        &safe, &mut z, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
    );
    assert_eq!(stats.candidate_pairs, 1);
    assert!(stats.active_pairs > 0 && stats.iterations > 0);
    let lowest_upper = z[3..].iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
    let highest_lower = z[..3].iter().map(|p| p.z).fold(f64::NEG_INFINITY, f64::max);
    assert!(
        lowest_upper - highest_lower > params.eps * params.thickness,
        "gap {}",
        lowest_upper - highest_lower
    );
    // Without self-contact nothing happens.
    let mesh = ContactMesh {
        self_contact: &[false],
        ..mesh
    };
    let mut z = target.clone();
    let stats = resolve_contacts(
        &safe, &mut z, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
    );
    assert_eq!(stats.candidate_pairs, 0);
    assert_eq!(z, target);
}

/// A workspace that served a bigger scene before gives the same result as a fresh one
/// (without the warm start, which carries the last local step's moves on by design).
#[test]
fn a_reused_workspace_gives_the_fresh_result() {
    let (safe, target, triangles) = crossing();
    let params = ContactParams {
        thickness: 2e-3,
        d_hat: 4e-3,
        warm_start: false,
        ..ContactParams::default()
    };
    let solve = |work: &mut Workspace, scale: f64| {
        let safe: Vec<_> = safe.iter().map(|p| p * scale).collect();
        let mut z: Vec<_> = target.iter().map(|p| p * scale).collect();
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &[0, 1],
            self_contact: &[true, true],
        };
        let stats = resolve_contacts(
            &safe,
            &mut z,
            &[false; 6],
            None,
            &mesh,
            &params,
            NO_TOL,
            FREE,
            work,
        );
        let counts = (
            stats.candidate_pairs,
            stats.active_pairs,
            stats.iterations,
            stats.clamped,
        );
        (z, counts, work.push().to_vec())
    };
    let mut used = Workspace::default();
    solve(&mut used, 0.5);
    let fresh = solve(&mut Workspace::default(), 1.0);
    let (_, (_, active, _, _), _) = &fresh;
    assert!(*active > 0);
    assert_eq!(solve(&mut used, 1.0), fresh);
}

/// A small triangle held by its target `y` inside the barrier over a large fixed one, with
/// no pair but its three vertices' point-triangle pairs in reach: eq. 47 then separates
/// per vertex, and its minimum solves `z - y = -mu B'(z - xi)` (heights above the lower
/// triangle, m). The target is `xi + depth d_hat` high and `slide` (m) along `x` from the
/// safe positions; the barrier pushes along `z` only, so the minimum keeps the target's `x`
/// and `y`. Returns the root, found by bisection, and the local step's result, target and
/// iterations for `params` (from [`pressing`]), run with `work`.
fn pressed_triangle(
    params: &ContactParams,
    depth: f64,
    slide: f64,
    work: &mut Workspace,
) -> (f64, [Vector3<f64>; 3], [Vector3<f64>; 3], usize) {
    pressed_triangle_in(None, params, NO_TOL, depth, slide, work)
}

/// [`pressed_triangle`] with the proximal term in the metric `W` at every vertex (`None`:
/// the identity): the minimum solves `W (z - y) = -mu B'(h - xi) e_z`, so `z - y` is
/// `W^-1 e_z` times `-mu B'`, and its height `h` solves `h - y_z = -(W^-1)_zz mu B'(h - xi)`
/// (the root returned). `tol` is the solver's tolerance passed to [`resolve_contacts`].
fn pressed_triangle_in(
    metric: Option<SymmetricMatrix3<f64>>,
    params: &ContactParams,
    tol: f64,
    depth: f64,
    slide: f64,
    work: &mut Workspace,
) -> (f64, [Vector3<f64>; 3], [Vector3<f64>; 3], usize) {
    let (xi, d_hat) = (params.thickness, params.d_hat);
    let v = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
    let lower = [v(-1., -1., 0.), v(2., -1., 0.), v(-1., 2., 0.)];
    let upper = |h: f64| [v(0.1, 0.1, h), v(0.12, 0.1, h), v(0.1, 0.12, h)];
    let (start, pressed) = (xi + 0.95 * d_hat, xi + depth * d_hat);
    let safe: Vec<_> = lower.iter().chain(&upper(start)).copied().collect();
    let target = upper(pressed).map(|p| p + v(slide, 0.0, 0.0));
    let mut z: Vec<_> = lower.iter().chain(&target).copied().collect();
    let fixed = [true, true, true, false, false, false];
    let mesh = ContactMesh {
        triangles: &[[0, 1, 2], [3, 4, 5]],
        body: &[0, 1],
        self_contact: &[false, false],
    };
    let fill = |w: &mut Vec<SymmetricMatrix3<f64>>| w.extend(metric.into_iter().cycle().take(6));
    let weights = metric.is_some().then_some(&fill as &ProximalWeights);
    let stats = resolve_contacts(
        &safe, &mut z, &fixed, weights, &mesh, params, tol, FREE, work,
    );
    assert_eq!(stats.active_pairs, 3);
    let barrier = params.barrier();
    let compliance = metric.map_or(1.0, |w| w.try_inverse().unwrap().diagonal[2]);
    let (mut below, mut above) = (pressed, xi + d_hat);
    for _ in 0..200 {
        let mid = 0.5 * (below + above);
        let excess = mid - pressed + compliance * params.weight * barrier.derivative(mid - xi);
        if excess > 0.0 {
            above = mid;
        } else {
            below = mid;
        }
    }
    (below, [z[3], z[4], z[5]], target, stats.iterations)
}

/// The vertices of a flat `side x side` grid of `spacing` (m) in the plane `z = height`,
/// moved by `shift` spacings along x, row by row.
fn flat_grid(
    side: u32,
    spacing: f64,
    shift: f64,
    height: f64,
) -> impl Iterator<Item = Vector3<f64>> {
    (0..side * side).map(move |v| {
        let (i, j) = (f64::from(v % side), f64::from(v / side));
        Vector3::new(spacing * (i + shift), spacing * j, height)
    })
}

/// Two 6 x 6 grids of 1 cm spacing, the lower one fixed at height 0, the upper one moved by
/// `offset` (in spacings, along `x`) and pressed from `xi + 0.95 d_hat` to
/// `xi + 0.3 d_hat` with every vertex jittered by up to 0.3 mm: their edges are parallel,
/// so the closest points of edge-edge pairs jump along the edges as they move, and the
/// barrier's push on a vertex with them. Returns the local step's iterations and, over the
/// upper grid's vertices, the longest step of the curvature rule at the result,
/// `|(I + K_i)^-1 (p_i + y_i - z_i)|` (m): zero at the minimum of eq. 47.
fn pressed_grids(offset: f64, params: &ContactParams) -> (usize, f64) {
    let mut rng = crate::test_rng::Rng::new(7);
    let (side, spacing) = (6_u32, 0.01);
    let (xi, d_hat) = (params.thickness, params.d_hat);
    let grid = |shift: f64, height: f64| flat_grid(side, spacing, shift, height);
    let lower: Vec<_> = grid(0.0, 0.0).collect();
    let safe: Vec<_> = lower
        .iter()
        .copied()
        .chain(grid(offset, xi + 0.95 * d_hat))
        .collect();
    let target: Vec<_> = lower
        .iter()
        .copied()
        .chain(grid(offset, xi + 0.3 * d_hat).map(|p| p + rng.vector() * 3e-4))
        .collect();
    use super::super::test_meshes::{grid_triangles, two_copies};
    let (triangles, body) = two_copies(&grid_triangles(side), side * side);
    let n = lower.len();
    let fixed: Vec<bool> = (0..2 * n).map(|v| v < n).collect();
    let mesh = ContactMesh {
        triangles: &triangles,
        body: &body,
        self_contact: &[false, false],
    };
    let mut z = target.clone();
    let mut work = Workspace::default();
    let stats = resolve_contacts(
        &safe, &mut z, &fixed, None, &mesh, params, NO_TOL, FREE, &mut work,
    );
    let longest = (n..2 * n)
        .map(|i| {
            let direction = work.push()[i] + target[i] - z[i];
            let inverse = work.curvature[i].plus_identity(1.0).try_inverse().unwrap();
            inverse.mul_vector(&direction).norm()
        })
        .fold(0.0, f64::max);
    (stats.iterations, longest)
}

/// The local step of a later global iteration on two `side x side` grids pressed together:
/// from the last one's result as the safe positions (which had moved little since the
/// one before), towards a target moved by up to 2 micrometres (a hundredth of the allowance
/// `eps xi`), except for the last `strays` vertices, moved 0.7 times their allowance. It ends
/// where a fresh workspace's local step ends (no warm start in either), with the push
/// summed over every pair. Returns its figures and whether it filtered the pairs afresh.
fn shifted_local_step(side: u32, strays: usize) -> (ContactStats, bool) {
    let params = ContactParams {
        warm_start: false,
        ..pressing(DescentStep::Curvature, 400)
    };
    let mut rng = crate::test_rng::Rng::new(3);
    let spacing = 0.01;
    let (xi, d_hat) = (params.thickness, params.d_hat);
    let grid = |height: f64| flat_grid(side, spacing, 0.3, height);
    let safe: Vec<_> = grid(0.0).chain(grid(xi + 0.95 * d_hat)).collect();
    let target: Vec<_> = grid(0.0)
        .chain(grid(xi + 0.3 * d_hat).map(|p| p + rng.vector() * 3e-4))
        .collect();
    use super::super::test_meshes::{grid_triangles, two_copies};
    let (triangles, body) = two_copies(&grid_triangles(side), side * side);
    let n = safe.len() / 2;
    let fixed: Vec<bool> = (0..2 * n).map(|v| v < n).collect();
    let mesh = ContactMesh {
        triangles: &triangles,
        body: &body,
        self_contact: &[false, false],
    };
    // The first local step moves the upper grid millimetres (its second filters afresh).
    let mut work = Workspace::default();
    let mut first = safe.clone();
    for _ in 0..2 {
        let mut next = target.clone();
        resolve_contacts(
            &first, &mut next, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
        );
        first = next;
    }
    let allowance = &work.live.allowance;
    let moved: Vec<_> = target
        .iter()
        .enumerate()
        .map(|(i, p)| match i {
            _ if fixed[i] => *p,
            _ if i >= 2 * n - strays => p + Vector3::x() * (0.7 * allowance[i]),
            _ => p + rng.vector() * 2e-6,
        })
        .collect();
    let mut kept = moved.clone();
    let stats = resolve_contacts(
        &first, &mut kept, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
    );
    assert!(stats.active_pairs > 0);
    // The CCD's distances at the safe positions are this local step's, kept list or not.
    for (p, &d) in work.live.pairs.iter().zip(&work.live.start) {
        assert_eq!(d, p.closest(&first).separation.norm());
    }
    assert_push_from_every_pair(&mesh, &first, &kept, &params, &work);
    let mut fresh = moved.clone();
    resolve_contacts(
        &first,
        &mut fresh,
        &fixed,
        None,
        &mesh,
        &params,
        NO_TOL,
        FREE,
        &mut Workspace::default(),
    );
    for (a, b) in kept.iter().zip(&fresh) {
        assert!((a - b).norm() < 1e-12, "{a} vs {b}");
    }
    (stats, work.live.filtered_target == moved)
}

/// After a shift of every vertex by a hundredth of its allowance, the local step keeps the
/// live pairs: no filter, no refresh. With two vertices of 288 shifted by 0.7 of their
/// allowance it raises their allowances and refreshes once (here the raised allowances,
/// millimetres from the first local step's approach, outgrow the build's skins, so the
/// extension falls back to a build); with four (more than 1 %) it filters afresh at once.
/// Every time it ends where a fresh workspace does.
#[test]
fn a_local_step_after_a_small_shift_keeps_the_live_pairs() {
    let (stats, filtered) = shifted_local_step(6, 0);
    assert!(!filtered && stats.live_refreshes == 0, "{stats:?}");
    let (stats, _) = shifted_local_step(12, 2);
    assert_eq!(stats.live_refreshes, 1, "{stats:?}");
    let (stats, filtered) = shifted_local_step(12, 4);
    assert!(filtered && stats.live_refreshes >= 1, "{stats:?}");
}

/// Two parallel grids `reach + 1.02 A` apart, the upper one's vertices with the allowance
/// `A` = 2 mm and the lower one's a thousandth of it: no pair can come within reach, and
/// none is live. The upper grid then shifts down by `0.45 A` (the list is kept), and its
/// vertices deviate by
/// `0.6 A <= A`: together `1.05 A`, so the local step may look at pairs within reach, and
/// [`LivePairs::cover`] must refresh the list (the deviation alone is within the
/// allowance). Afterwards every pair a brute-force search finds within reach at the
/// nearest positions the step may look at is live.
#[test]
fn a_kept_list_counts_the_shift_since_its_filter_against_the_allowance() {
    use super::super::test_meshes::{brute_force_pairs, grid_triangles, two_copies};
    let (side, spacing, reach, a) = (6_u32, 0.01, 0.005, 0.002);
    let grid = |height: f64| flat_grid(side, spacing, 0.3, height);
    let gap = reach + 1.02 * a;
    let safe: Vec<_> = grid(0.0).chain(grid(gap)).collect();
    let n = safe.len() / 2;
    let (triangles, body) = two_copies(&grid_triangles(side), side * side);
    let mesh = ContactMesh {
        triangles: &triangles,
        body: &body,
        self_contact: &[false, false],
    };
    let mut stats = ContactStats::default();
    let mut live = LivePairs {
        allowance: (0..2 * n)
            .map(|i| if i < n { a / 1000.0 } else { a })
            .collect(),
        deviation: vec![0.0; 2 * n],
        ..LivePairs::default()
    };
    live.filter(&safe, &safe, &mesh, reach, &mut stats);
    assert!(live.pairs.is_empty(), "{} pairs live", live.pairs.len());

    let shift = 0.45 * a;
    let shifted: Vec<_> = grid(0.0).chain(grid(gap - shift)).collect();
    let sin2 = sin2_limit(default_parallel_angle());
    live.start(
        &shifted,
        &shifted,
        a / 1000.0,
        &mesh,
        reach,
        sin2,
        &mut stats,
    );
    assert_eq!(stats.live_refreshes, 1, "the list is kept: {stats:?}");
    assert_eq!(live.filtered_safe, safe);

    let deviation = 0.6 * a;
    for e in &mut live.deviation[n..] {
        *e = deviation;
    }
    assert!(live
        .cover(&shifted, &shifted, &mesh, reach, &mut stats)
        .is_some());
    let nearest: Vec<_> = grid(0.0).chain(grid(gap - shift - deviation)).collect();
    let (_, every) = brute_force_pairs(&mesh, &nearest);
    let within: Vec<_> = every
        .iter()
        .filter(|p| p.closest(&nearest).separation.norm() < reach)
        .collect();
    assert!(within.len() > 50, "{} pairs within reach", within.len());
    let missed = within.iter().filter(|p| !live.pairs.contains(p)).count();
    assert_eq!(
        missed,
        0,
        "{missed} of {} pairs within reach not live",
        within.len()
    );
}

/// Pressed onto a grid of parallel edges (aligned with it, or half a spacing off), a grid
/// comes to rest at the balance of eq. 47 within 40 iterations (21 and 30 here), the
/// curvature rule's step there below 4 % of `eps xi` (1.7 % and 0.7 %). Without the
/// halving of reversed moves, vertices whose edge-edge closest points jump as they move
/// go back and forth for good: 400 iterations do not stop the descent, and it ends up to
/// 11 % of `eps xi` from the balance.
#[test]
fn a_grid_pressed_onto_parallel_edges_comes_to_rest_instead_of_cycling() {
    let params = pressing(DescentStep::Curvature, 400);
    let eps_xi = params.eps * params.thickness;
    for offset in [0.0, 0.5] {
        let (iterations, longest) = pressed_grids(offset, &params);
        assert!(iterations < 40, "offset {offset}: {iterations} iterations");
        assert!(
            longest < 0.04 * eps_xi,
            "offset {offset}: step {} eps xi",
            longest / eps_xi
        );
    }
}

/// The parameters of [`pressed_triangle`]: `xi = 2 mm`, `d_hat = 4 mm`.
fn pressing(step: DescentStep, max_iters: usize) -> ContactParams {
    ContactParams {
        thickness: 2e-3,
        d_hat: 4e-3,
        max_iters,
        step,
        ..ContactParams::default()
    }
}

/// Eq. 53's step in a metric `W` with `|W^-1| = 4` (a vertex lighter than the mean): one
/// iteration from a target whose gap is `eps xi`, where the push reaches the slope bound,
/// moves each vertex by at most `eps xi` (the bound times the largest `|W_i^-1|`); with
/// the bound in the identity it would move about four times that.
#[test]
fn eq_53_in_a_light_metric_moves_no_vertex_beyond_eps_xi() {
    let metric = SymmetricMatrix3 {
        diagonal: [0.25; 3],
        upper: [0.0; 3],
    };
    let params = pressing(DescentStep::Uniform, 1);
    let eps_xi = params.eps * params.thickness;
    let depth = eps_xi / params.d_hat;
    let (_, z, target, iterations) = pressed_triangle_in(
        Some(metric),
        &params,
        NO_TOL,
        depth,
        0.0,
        &mut Workspace::default(),
    );
    assert_eq!(iterations, 1);
    let longest = z
        .iter()
        .zip(&target)
        .map(|(p, t)| (p - t).norm())
        .fold(0.0, f64::max);
    assert!(
        longest <= eps_xi * (1.0 + 1e-9),
        "{longest} against {eps_xi}"
    );
    assert!(
        longest > 0.5 * eps_xi,
        "the push must be near its bound: {longest}"
    );
}

/// The solver's tolerance bounds how far from the minimum of eq. 47 the local step may
/// stop: on its own stopping test (`1 % eps xi`, 2 um here) the pressed triangle ends
/// within `eps xi / 100` of it (1.3 um, 13 iterations), at `tol = 10 nm` within `tol`
/// (1.4 nm, 21 iterations; its stop at `tol / 5`). Above the own stopping distance, `tol`
/// changes nothing.
#[test]
fn a_tighter_solver_tolerance_takes_the_local_step_closer_to_its_minimum() {
    let params = pressing(DescentStep::Curvature, 100);
    let eps_xi = params.eps * params.thickness;
    let solve = |tol: f64| {
        let (root, z, _, iterations) =
            pressed_triangle_in(None, &params, tol, 0.3, 0.0, &mut Workspace::default());
        let error = z.iter().map(|p| (p.z - root).abs()).fold(0.0, f64::max);
        (error, iterations)
    };
    let (own, own_iterations) = solve(NO_TOL);
    let (tight, tight_iterations) = solve(1e-8);
    assert!(own < 0.01 * eps_xi, "{own}");
    assert!(
        own > 1e-8,
        "the own stop must be the looser one here: {own}"
    );
    assert!(tight < 1e-8, "{tight} m from the minimum at tol = 1e-8 m");
    assert!(tight_iterations > own_iterations);
    assert_eq!(solve(1e-4), (own, own_iterations));
}

/// The curvature step reaches the minimum of eq. 47 within its stopping test: 13
/// iterations, about 10 of them the approach at `eps xi` per iteration, and 0.7 % of
/// `eps xi` from the minimum. Eq. 53's uniform step creeps, its steepest slope bound being
/// about 180 times the proximal term's here: at the default cap it is still nearly 5 `eps xi`
/// short, and without a cap its moves fall below the stopping test's `1 % eps xi` while it
/// is still more than `eps xi` short (1.1 here).
#[test]
fn the_curvature_step_reaches_the_minimum_that_the_uniform_step_creeps_towards() {
    let eps_xi = 0.1 * 2e-3;
    let (root, z, _, iterations) = pressed_triangle(
        &pressing(DescentStep::Curvature, 32),
        0.3,
        0.0,
        &mut Workspace::default(),
    );
    for p in z {
        assert!((p.z - root).abs() < 0.02 * eps_xi, "{} vs {root}", p.z);
    }
    assert!(iterations < 20, "{iterations} iterations");
    let (root, z, _, iterations) = pressed_triangle(
        &pressing(DescentStep::Uniform, 32),
        0.3,
        0.0,
        &mut Workspace::default(),
    );
    assert_eq!(iterations, 32);
    for p in z {
        assert!(root - p.z > 4.0 * eps_xi, "{} vs {root}", p.z);
    }
    let cap = 100_000;
    let (root, z, _, iterations) = pressed_triangle(
        &pressing(DescentStep::Uniform, cap),
        0.3,
        0.0,
        &mut Workspace::default(),
    );
    assert!(iterations < cap, "{iterations} iterations");
    for p in z {
        assert!(root - p.z > eps_xi, "{} vs {root}", p.z);
    }
}

/// In a metric `W` that couples `x` to `z` ([`ProximalMetric::Jacobi`] gives each vertex
/// its own), the pressed triangle's minimum moves along `W^-1 e_z`: up to the height where
/// `(W^-1)_zz mu B'` balances the press (2.13 mm above the target, against 1.54 mm with the
/// identity) and sideways by `(W^-1)_xz / (W^-1)_zz` (-0.4) times that rise. The curvature
/// step in `W + K` reaches it within its stopping test (18 iterations, 13 with the
/// identity).
#[test]
fn a_weighted_proximal_term_moves_the_minimum_along_its_metric() {
    let eps_xi = 0.1 * 2e-3;
    let metric = SymmetricMatrix3 {
        diagonal: [2.0, 1.0, 0.5],
        upper: [0.0, 0.8, 0.0],
    };
    let params = pressing(DescentStep::Curvature, 64);
    let (root, z, target, iterations) = pressed_triangle_in(
        Some(metric),
        &params,
        NO_TOL,
        0.3,
        0.0,
        &mut Workspace::default(),
    );
    let rise = root - target[0].z;
    let inverse = metric.try_inverse().unwrap();
    let sideways = inverse.upper[1] / inverse.diagonal[2] * rise;
    assert!(sideways < -2.0 * eps_xi, "{sideways}");
    for (p, t) in z.iter().zip(&target) {
        assert!((p.z - root).abs() < 0.02 * eps_xi, "{} vs {root}", p.z);
        assert!(
            (p.x - t.x - sideways).abs() < 0.02 * eps_xi,
            "{} vs {}",
            p.x - t.x,
            sideways
        );
        assert!((p.y - t.y).abs() < 0.02 * eps_xi, "{} vs {}", p.y, t.y);
    }
    assert!(iterations < 24, "{iterations} iterations");
    // Eq. 53's step in `W` creeps, but along the same line: `z - y` stays along `W^-1 e_z`.
    let params = pressing(DescentStep::Uniform, 200);
    let (_, z, target, _) = pressed_triangle_in(
        Some(metric),
        &params,
        NO_TOL,
        0.3,
        0.0,
        &mut Workspace::default(),
    );
    for (p, t) in z.iter().zip(&target) {
        let moved = p - t;
        assert!(moved.z > eps_xi, "{moved}");
        let along = inverse.upper[1] / inverse.diagonal[2];
        assert!(
            (moved.x - along * moved.z).abs() < 1e-9 * moved.z,
            "{moved}"
        );
    }
}

/// Pulled `10 eps xi` sideways to a target below `xi`, the triangle is clamped by the CCD
/// about a quarter of the way short, in the barrier, and the descent has to slide it the
/// rest along the contact while pushing it up: it reaches the target's place and the
/// barrier's balance height within 20 iterations. The barrier is stiff only along its
/// normal: a step scaled by the curvature's trace, the same in every direction, slides by
/// a small fraction of the lag per iteration and ends the local step more than `eps xi`
/// short.
#[test]
fn the_curvature_step_slides_freely_along_the_contact() {
    let eps_xi = 0.1 * 2e-3;
    let slide = 10.0 * eps_xi;
    let (root, z, target, iterations) = pressed_triangle(
        &pressing(DescentStep::Curvature, 32),
        -0.25,
        slide,
        &mut Workspace::default(),
    );
    for (p, t) in z.iter().zip(&target) {
        assert!((p.z - root).abs() < 0.02 * eps_xi, "{} vs {root}", p.z);
        assert!((p.xy() - t.xy()).norm() < 0.02 * eps_xi, "{p} vs {t}");
    }
    assert!(iterations < 20, "{iterations} iterations");
}

/// Every local step of these tests checks, at every iteration, that the closest points it
/// kept for the pairs none of whose vertices moved, and the sums it kept for the vertices
/// none of whose pairs changed, are those of a fresh evaluation of every pair, to the bit:
/// the kept ones are exact, not an approximation.
pub(super) fn assert_as_if_evaluated_afresh(
    live: &LivePairs,
    (motion, drift, reach): (&[f64], &[f64], f64),
    z: &[Vector3<f64>],
    closest: &[Closest],
    (barrier, mu): (&Barrier, f64),
    (push, alpha, curvature): (&[Vector3<f64>], &[f64], &[SymmetricMatrix3<f64>]),
) {
    let (mut fresh, mut every) = (Vec::new(), Vec::new());
    let none_moved = vec![false; z.len()];
    closest_within(
        &live.pairs,
        &live.start,
        motion,
        drift,
        reach,
        z,
        (0, &none_moved),
        &mut every,
        &mut fresh,
    );
    for (k, (kept, afresh)) in closest.iter().zip(&every).enumerate() {
        assert!(
            kept.weights == afresh.weights && kept.separation == afresh.separation,
            "pair {k}: kept {kept:?}, afresh {afresh:?}"
        );
    }
    let sums = sums_from_scratch(
        &live.pairs,
        &every,
        (&live.fade, &live.scale),
        z.len(),
        (barrier, mu),
    );
    let kept = (push.to_vec(), alpha.to_vec(), curvature.to_vec());
    assert_same_sums(&kept, &sums);
}

/// A grid falling through another, fixed one (its target 2 mm under it, from 5.1 mm over
/// it, with jitter), the same grid pressed onto it from within the barrier's reach, and the
/// two grids free and crossing: the descent extends its live pairs, filters them afresh
/// mid-descent, and settles some vertices while others go on (each iteration checks that
/// what it kept is exact, see [`assert_as_if_evaluated_afresh`]). The grids stay `eps xi`
/// apart, and the push is the one summed over every pair. (No CCD clamp happens after the
/// first iteration here: the clamps' marking of their vertices is tested by
/// [`a_settled_vertex_clamped_mid_descent_has_its_pairs_measured_again`] and, for the
/// guarantee pass, by
/// [`the_guarantee_pass_keeps_out_a_move_from_within_the_threshold_and_measures_its_push`].)
#[test]
fn local_steps_that_refresh_their_pairs_keep_exact_closest_points() {
    use super::super::test_meshes::{grid_triangles, two_copies};
    let params = ContactParams::default();
    let (xi, d_hat) = (params.thickness, params.d_hat);
    let side = 8_u32;
    let (triangles, body) = two_copies(&grid_triangles(side), side * side);
    let mesh = ContactMesh {
        triangles: &triangles,
        body: &body,
        self_contact: &[false, false],
    };
    let n = (side * side) as usize;
    let mut rng = crate::test_rng::Rng::new(11);
    for (from, to, lower_to, fixed_lower) in [
        (xi + 0.6 * d_hat, -2e-3, 0.0, true),
        (xi + 0.95 * d_hat, xi + 0.3 * d_hat, 0.0, true),
        (xi + 0.6 * d_hat, -4e-3, 4e-3, false),
    ] {
        let fixed: Vec<bool> = (0..2 * n).map(|v| fixed_lower && v < n).collect();
        let safe: Vec<_> = flat_grid(side, 0.01, 0.0, 0.0)
            .chain(flat_grid(side, 0.01, 0.3, from))
            .collect();
        let jitter = if fixed_lower { 0.0 } else { 1e-3 };
        let mut z: Vec<_> = flat_grid(side, 0.01, 0.0, lower_to)
            .map(|p| (p, jitter))
            .chain(flat_grid(side, 0.01, 0.3, to).map(|p| (p, 1e-3)))
            .map(|(p, jitter)| p + rng.vector() * jitter)
            .collect();
        let mut work = Workspace::default();
        let stats = resolve_contacts(
            &safe, &mut z, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
        );
        assert!(
            stats.iterations > 3 && stats.live_refreshes > 1,
            "{stats:?}"
        );
        assert_push_from_every_pair(&mesh, &safe, &z, &params, &work);
    }
}

/// A vertex that has settled and is clamped by the CCD mid-descent gets its pairs measured
/// again. The triangle `(q, c, d)` slides 0.3 mm to its target and rests there, 7.6 mm over
/// a fixed triangle: beyond the barrier's reach of 7.5 mm, so no force, but within reach
/// of the distance bound, so its pairs with it are evaluated. A test hook in the collider
/// pass lowers the free vertex `p` of a third triangle `(p, a, b)`, far above, by 0.1 mm
/// per iteration (the descent goes on), then throws it under `(q, c, d)`, twice. The CCD
/// then clamps `q`, `c` and `d` back along their slides, though the descent did not move
/// them since: after the second throw (the first rebuilds the live pairs, which makes
/// every pair fresh anyway) only the clamp marks their pairs with the fixed triangle, whose
/// closest points [`assert_as_if_evaluated_afresh`] checks at every iteration (without the
/// mark, they are those from before the clamp).
#[test]
fn a_settled_vertex_clamped_mid_descent_has_its_pairs_measured_again() {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let params = ContactParams {
        max_iters: 20,
        ..ContactParams::default()
    };
    let v = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
    let height = 0.004;
    let below = height - 0.0076;
    // q, c, d; p, a, b; the fixed triangle below.
    let safe = vec![
        v(0.005, 0.005, height),
        v(0.010, 0.005, height),
        v(0.005, 0.010, height),
        v(0.0075, 0.002, 0.018),
        v(0.0075, 0.002, 0.014),
        v(0.0075, -0.003, 0.014),
        v(0.0, 0.0, below),
        v(0.02, 0.0, below),
        v(0.0, 0.02, below),
    ];
    let slide = v(3e-4, 0.0, 0.0);
    let mut z = safe.clone();
    z[..3].iter_mut().for_each(|x| *x += slide);
    let fixed = [false, false, false, false, true, true, true, true, true];
    let mesh = ContactMesh {
        triangles: &[[0, 1, 2], [3, 4, 5], [6, 7, 8]],
        body: &[0, 1, 2],
        self_contact: &[false; 3],
    };
    const P: usize = 3;
    const THROW: usize = 5;
    const THROWS: [usize; 2] = [THROW, 4 * THROW];
    let calls = AtomicUsize::new(0);
    let lower_then_throw: &PushOut = &|i, before, zi, _| {
        if i != P {
            return;
        }
        let call = calls.fetch_add(1, Ordering::Relaxed);
        if call < THROW {
            *zi = before - v(0.0, 0.0, 1e-4);
        } else if THROWS.iter().any(|&t| (t..t + 4).contains(&call)) {
            // The throw, again where the move is cut to `eps xi` after it, and where the
            // move is halved and taken again as it reverses the last one.
            *zi = v(0.0075, 0.008, 0.0);
        }
    };
    let mut work = Workspace::default();
    // `p` starts off its target (a warm start), so that the descent moves it, and the hook
    // with it, from the first iteration on: a vertex with no push at its target takes no move.
    let mut warm = vec![Vector3::zeros(); safe.len()];
    warm[P] = v(0.0, 0.0, -1e-4);
    work.set_warm_start(&warm);
    let stats = resolve_contacts(
        &safe,
        &mut z,
        &fixed,
        None,
        &mesh,
        &params,
        NO_TOL,
        lower_then_throw,
        &mut work,
    );
    assert!(calls.load(Ordering::Relaxed) >= THROWS[1] + 4, "{stats:?}");
    assert_push_from_every_pair(&mesh, &safe, &z, &params, &work);
}

/// A small triangle resting on a floor (a collider), under a large one tilted by 20
/// degrees and fixed within the barrier's reach: the barrier pushes the small one down into
/// the floor and along it, towards where the roof rises. The floor takes the push's normal
/// part; the rest slides the triangle along the floor, to the minimum of eq. 47 there
/// (Karush-Kuhn-Tucker): the descent direction `g_i = p_i + y_i - z_i` has no part along
/// the floor and points into it. The curvature step moves in `(I + K_i)^-1` with `K_i`
/// stiff along the roof's normal: a normal projection out of the floor after such a
/// move stops the slide where the move points straight into the floor, with `g_i`'s
/// part along the floor left unbalanced (6 `eps xi` here). Two more ways to fail it: cutting
/// the move to `eps xi` before the projection (the proposal is mostly into the floor, so
/// what is left along it crawls), and halving the moves whenever the proposal, not the
/// move taken, points against the last move (every iteration here).
#[test]
fn a_triangle_pressed_onto_a_collider_by_a_slanted_roof_slides_to_the_balance() {
    use crate::collider::{Collider, MovingCollider, Shape};
    let params = pressing(DescentStep::Curvature, 32);
    let eps_xi = params.eps * params.thickness;
    let floor = MovingCollider::new(Collider::fixed(
        Shape::plane([0.0; 3], [0.0, 0.0, 1.0]).unwrap(),
    ))
    .during_step::<f64>(0.0, 1.0);
    let floors = [floor];
    let v = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
    let small = [v(0.1, 0.1, 0.), v(0.102, 0.1, 0.), v(0.1, 0.102, 0.)];
    let tilt = 20f64.to_radians();
    let (up, along) = (
        v(tilt.sin(), 0.0, tilt.cos()),
        v(tilt.cos(), 0.0, -tilt.sin()),
    );
    let centre = v(0.1007, 0.1007, 0.0) + up * (params.thickness + 0.4 * params.d_hat);
    let roof = [
        centre - along - Vector3::y(),
        centre + along * 2.0 - Vector3::y(),
        centre - along + Vector3::y() * 2.0,
    ];
    let safe: Vec<_> = small.iter().chain(&roof).copied().collect();
    let mut z = safe.clone();
    let fixed = [false, false, false, true, true, true];
    let mesh = ContactMesh {
        triangles: &[[0, 1, 2], [3, 4, 5]],
        body: &[0, 1],
        self_contact: &[false, false],
    };
    let push_out = pushing_out_of(&floors);
    let mut work = Workspace::default();
    let stats = resolve_contacts(
        &safe, &mut z, &fixed, None, &mesh, &params, NO_TOL, &push_out, &mut work,
    );
    assert_eq!(stats.active_pairs, 3);
    // About 7 moves of `eps xi` along the floor, then the approach (14 here).
    assert!(stats.iterations < 20, "{} iterations", stats.iterations);
    for i in 0..3 {
        let g = work.push()[i] + safe[i] - z[i];
        assert!(z[i].z.abs() < 1e-12, "vertex {i} off the floor: {}", z[i]);
        assert!(
            safe[i].x - z[i].x > eps_xi,
            "vertex {i} has not slid: {}",
            z[i]
        );
        assert!(g.xy().norm() < 0.02 * eps_xi, "vertex {i}: g = {g}");
        assert!(g.z < 0.0, "vertex {i}: g = {g}");
    }
}

/// A descent move along a 1 cm ball, from a point on it: the proposal (5 mm along, 2 mm
/// in) is taken out of the ball, 5.5 mm from the start, and then cut to the longest move,
/// 0.2 mm (and 0.1 mm at half damping). The cut point is on the chord to the projected
/// end, 53 micrometres inside the ball (13 at half damping); it is projected out again, so
/// the move ends on the surface, up to 5 % short of the longest move (the projection
/// shortens it by 3.4 %, 0.8 % at half damping). Without the second projection the vertex
/// would end inside.
#[test]
fn a_move_cut_along_a_ball_ends_on_its_surface() {
    use crate::collider::{Collider, MovingCollider, Shape};
    let radius = 0.01;
    let ball = Shape::sphere([0.0; 3], radius).unwrap();
    let balls = [MovingCollider::new(Collider::fixed(ball.clone())).during_step::<f64>(0.0, 1.0)];
    let push_out = pushing_out_of(&balls);
    let before = Vector3::new(0.0, 0.0, radius);
    let proposed = Vector3::new(0.005, 0.0, -0.002);
    let longest = 2e-4;
    for damp in [1.0, 0.5] {
        let end = damped_move(0, &before, &proposed, None, Some(longest), damp, &push_out);
        let depth = ball.signed_distance(&end);
        assert!(
            depth.abs() < 1e-12,
            "damp {damp}: {depth:e} m from the surface"
        );
        let moved = (end - before).norm();
        assert!(
            (0.95 * longest * damp..=longest * damp).contains(&moved) && end.x > 0.0,
            "damp {damp}: moved {moved} to {end}"
        );
    }
}

/// The halving of an overshooting vertex's moves and the settled rule: a move too short to
/// be taken reverses nothing (its damping and last move stay), a long one against the last
/// move is halved and taken, and one that halving makes too short is not taken (but the
/// halving stays).
#[test]
fn a_move_too_short_to_take_leaves_the_damping_and_the_last_move_alone() {
    let before = Vector3::new(0.3, -0.2, 1.0);
    let settled = 1e-6;
    let decide = |proposed: Vector3<f64>, last: &mut Vector3<f64>, damp: &mut f64| {
        settle_or_move(&before, |d| before + proposed * d, settled, last, damp)
    };
    let first = Vector3::new(1e-4, 0.0, 0.0);
    let (mut last, mut damp) = (first, 1.0);

    let back = Vector3::new(-0.5e-6, 0.0, 0.0);
    match decide(back, &mut last, &mut damp) {
        Move::Settled(length) => assert!((length - 0.5e-6).abs() < 1e-12, "{length}"),
        taken => panic!("{taken:?}"),
    }
    assert_eq!(
        (last, damp),
        (first, 1.0),
        "a short move changed the descent"
    );

    let far_back = Vector3::new(-1e-4, 0.0, 0.0);
    let end = before + far_back * 0.5;
    let length = (end - before).norm();
    assert_eq!(
        decide(far_back, &mut last, &mut damp),
        Move::Taken { end, length }
    );
    assert_eq!((last, damp), (end - before, 0.5));

    let onwards = Vector3::new(-2e-4, 1e-4, 0.0);
    let end = before + onwards * 0.5;
    let length = (end - before).norm();
    assert_eq!(
        decide(onwards, &mut last, &mut damp),
        Move::Taken { end, length }
    );
    assert_eq!(
        (last, damp),
        (end - before, 0.5),
        "a move along the last one halved"
    );

    let (mut last, mut damp) = (first, 1.0);
    let barely = Vector3::new(-1.5e-6, 0.0, 0.0);
    match decide(barely, &mut last, &mut damp) {
        Move::Settled(length) => assert!((length - 0.75e-6).abs() < 1e-12, "{length}"),
        taken => panic!("{taken:?}"),
    }
    assert_eq!((last, damp), (first, 0.5));
}

/// A local step repeated on the same positions starts from where the last one ended: it
/// stops after one move below the stopping test and returns the same positions (within
/// it). Cold, it repeats the whole approach.
#[test]
fn a_warm_start_continues_the_last_local_step() {
    let eps_xi = 0.1 * 2e-3;
    for warm_start in [true, false] {
        let params = ContactParams {
            warm_start,
            ..pressing(DescentStep::Curvature, 32)
        };
        let mut work = Workspace::default();
        let (_, first, _, cold) = pressed_triangle(&params, 0.3, 0.0, &mut work);
        let (_, again, _, iterations) = pressed_triangle(&params, 0.3, 0.0, &mut work);
        for (a, b) in first.iter().zip(&again) {
            assert!((a - b).norm() < 0.02 * eps_xi, "{a} vs {b}");
        }
        assert!(cold > 5, "{cold} iterations");
        if warm_start {
            assert_eq!(iterations, 1);
        } else {
            assert_eq!(iterations, cold);
        }
    }
}

/// A pair's fade scales everything it adds to a vertex: its push, its share of eq. 53's
/// `alpha` and its curvature `K_i`. An edge-edge pair of two edges 2 mm apart and turned
/// by half the fade angle (within the barrier's reach of 7.5 mm) adds `m` (about 7/16)
/// times what it adds unfaded; turned to parallel, nothing.
#[test]
fn a_pairs_fade_scales_its_push_share_and_curvature() {
    use super::super::parallel_fade::edge_edge_fade;
    let params = ContactParams::default();
    let sin2 = sin2_limit(params.parallel_angle);
    let pair = [Pair {
        edge_edge: true,
        v: [0, 1, 2, 3],
    }];
    let crossing = |theta: f64| {
        let (c, s) = (theta.cos(), theta.sin());
        [
            Vector3::new(-0.01, 0.0, 0.0),
            Vector3::new(0.01, 0.0, 0.0),
            Vector3::new(-0.01 * c, -0.01 * s, 0.002),
            Vector3::new(0.01 * c, 0.01 * s, 0.002),
        ]
    };
    let terms = |x: &[Vector3<f64>], fade: f64| {
        barrier_terms(&pair, &[pair[0].closest(x)], &[fade], 4, &params)
    };
    let turned = crossing(0.5 * params.parallel_angle);
    let m = pair[0].distance_and_fade(&turned, sin2).1;
    assert_eq!(
        m,
        edge_edge_fade(&(turned[1] - turned[0]), &(turned[3] - turned[2]), sin2)
    );
    assert!((m - 7.0 / 16.0).abs() < 1e-3, "{m}");
    let (full, faded) = (terms(&turned, 1.0), terms(&turned, m));
    for v in 0..4 {
        assert!(full.0[v].norm() > 0.0 && full.1[v] > 0.0);
        assert!((faded.0[v] - full.0[v] * m).norm() < 1e-15 * full.0[v].norm().max(1.0));
        assert!((faded.1[v] - full.1[v] * m).abs() < 1e-15);
        let (k, k_full) = (faded.2[v].to_matrix(), full.2[v].to_matrix() * m);
        assert!((k - k_full).norm() <= 1e-12 * k_full.norm(), "vertex {v}");
    }
    let parallel = crossing(0.0);
    let m = pair[0].distance_and_fade(&parallel, sin2).1;
    assert_eq!(m, 0.0);
    let (push, alpha, curvature) = terms(&parallel, m);
    assert!(push.iter().all(|p| *p == Vector3::zeros()) && alpha.iter().all(|&a| a == 0.0));
    assert!(curvature.iter().all(|k| *k == SymmetricMatrix3::zeros()));
}

/// At the result `z` of a local step from `safe`, no two primitives are closer than
/// `eps xi`, and the barrier push the local step left in `work` equals the one summed over
/// every primitive pair (brute force, each pair faded as at `safe`): the live pairs held
/// every pair within the barrier's reach, and the descent saw them.
fn assert_push_from_every_pair(
    mesh: &ContactMesh,
    safe: &[Vector3<f64>],
    z: &[Vector3<f64>],
    params: &ContactParams,
    work: &Workspace,
) {
    let (_, every) = super::super::test_meshes::brute_force_pairs(mesh, safe);
    let nearest = every
        .iter()
        .map(|p| p.closest(z).separation.norm())
        .fold(f64::INFINITY, f64::min);
    assert!(nearest >= params.eps * params.thickness, "{nearest}");
    let push = brute_force_push(&every, z, safe, params);
    for (i, (a, b)) in work.push().iter().zip(&push).enumerate() {
        assert!(
            (a - b).norm() <= 1e-12 * (1.0 + b.norm()),
            "vertex {i}: {a} vs {b}"
        );
    }
}

/// The barrier push at `z` summed over `pairs`, each pair faded as at `fade_at` (m).
fn brute_force_push(
    pairs: &[Pair],
    z: &[Vector3<f64>],
    fade_at: &[Vector3<f64>],
    params: &ContactParams,
) -> Vec<Vector3<f64>> {
    let closest: Vec<_> = pairs.iter().map(|p| p.closest(z)).collect();
    let sin2 = sin2_limit(params.parallel_angle);
    let fades: Vec<_> = pairs
        .iter()
        .map(|p| p.distance_and_fade(fade_at, sin2).1)
        .collect();
    barrier_terms(pairs, &closest, &fades, z.len(), params).0
}

/// [`BarrierPush::update`]'s push, `alpha` and `K_i` over the `n` vertices, from scratch.
fn barrier_terms(
    pairs: &[Pair],
    closest: &[Closest],
    fades: &[f64],
    n: usize,
    params: &ContactParams,
) -> Sums {
    sums_from_scratch(
        pairs,
        closest,
        (fades, &[]),
        n,
        (&params.barrier(), params.weight),
    )
}

/// A triangle lying parallel over another of the same shape (1 cm legs) and pressed into
/// its barrier while it turns by twice the fade angle: its edges are parallel to those
/// below at the safe positions, 3.6 degrees off at the target. The local step holds every
/// pair's fade as it was at the safe positions, so its push is the brute-force push with
/// the fades there (the edge-edge pairs along the legs faded out), not with the fades at
/// the result, which differs by more than a tenth of it.
#[test]
fn a_local_step_holds_the_fades_of_its_safe_positions() {
    let params = pressing(DescentStep::Curvature, 32);
    let (xi, d_hat) = (params.thickness, params.d_hat);
    let leg = 0.01;
    let triangle = |height: f64, turn: f64| {
        let (c, s) = (turn.cos(), turn.sin());
        [(0.0, 0.0), (leg, 0.0), (0.0, leg)]
            .map(|(x, y)| Vector3::new(c * x - s * y, s * x + c * y, height))
    };
    let lower = triangle(0.0, 0.0);
    let safe: Vec<_> = lower
        .iter()
        .chain(&triangle(xi + 0.95 * d_hat, 0.0))
        .copied()
        .collect();
    let turn = 2.0 * params.parallel_angle;
    let mut z: Vec<_> = lower
        .iter()
        .chain(&triangle(xi + 0.3 * d_hat, turn))
        .copied()
        .collect();
    let fixed = [true, true, true, false, false, false];
    let mesh = ContactMesh {
        triangles: &[[0, 1, 2], [3, 4, 5]],
        body: &[0, 1],
        self_contact: &[false, false],
    };
    let mut work = Workspace::default();
    resolve_contacts(
        &safe, &mut z, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
    );
    let (_, every) = super::super::test_meshes::brute_force_pairs(&mesh, &safe);
    let (held, at_result) = (
        brute_force_push(&every, &z, &safe, &params),
        brute_force_push(&every, &z, &z, &params),
    );
    for v in 3..6 {
        let (a, held, other) = (work.push()[v], held[v], at_result[v]);
        assert!(
            (a - held).norm() <= 1e-12 * held.norm(),
            "vertex {v}: {a} vs {held}"
        );
        assert!(
            (other - held).norm() > 0.1 * held.norm(),
            "vertex {v}: {other} vs {held}"
        );
    }
}

/// Three parallel triangles, `xi = d_hat = 1 mm`: the lowest fixed at height 0, the middle
/// one at rest just beyond the barrier's reach above it (0.2 mm beyond), the top one
/// pressed from beyond the reach above the middle one to `0.1 d_hat` into its barrier. The
/// middle triangle has no motion of its own: only the descent's moves (its drift), pushed
/// by the top one, bring it within the lowest one's reach, which then holds it up. The
/// push at the result is the brute-force one, the lowest triangle's barrier included.
#[test]
fn a_sheet_pushed_by_the_descent_alone_feels_the_sheet_below() {
    let params = ContactParams {
        thickness: 1e-3,
        d_hat: 1e-3,
        ..ContactParams::default()
    };
    let reach = params.barrier().reach();
    let v = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
    let lowest = [v(-1., -1., 0.), v(2., -1., 0.), v(-1., 2., 0.)];
    let small = |h: f64| [v(0.1, 0.1, h), v(0.12, 0.1, h), v(0.1, 0.12, h)];
    let middle = reach + 2e-4;
    let top = small(middle + reach + 5e-4);
    let pressed = small(middle + params.thickness + 0.1 * params.d_hat);
    let stack = |upper: [Vector3<f64>; 3]| -> Vec<_> {
        lowest
            .iter()
            .chain(&small(middle))
            .chain(&upper)
            .copied()
            .collect()
    };
    let (safe, target) = (stack(top), stack(pressed));
    let mesh = ContactMesh {
        triangles: &[[0, 1, 2], [3, 4, 5], [6, 7, 8]],
        body: &[0, 1, 2],
        self_contact: &[false; 3],
    };
    let fixed = [true, true, true, false, false, false, false, false, false];
    let mut z = target.clone();
    let mut work = Workspace::default();
    resolve_contacts(
        &safe, &mut z, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
    );
    assert_push_from_every_pair(&mesh, &safe, &z, &params, &work);
    let lowered = z[3..6].iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
    assert!(
        lowered < reach - 1e-4,
        "middle triangle at {lowered}, reach {reach}"
    );
}

/// Three slightly wavy 9 x 9 grids (1 cm spacing) falling about 5 cm in one local step,
/// with `xi = 1 mm` and a reach of 3 mm: the lowest sheet 50 mm, the other two 53 mm,
/// through the lowest (1.5 mm below them at the start), which half of their width
/// overlaps; the top one 5 mm above the middle one (beyond the reach). The CCD clamps the
/// overlap's vertices each by its own factor, holding the middle sheet back by centimetres
/// through the top one that fell on: its pairs with the middle sheet become live only
/// after the clamps. At the result no two primitives are closer than `eps xi`, and the
/// barrier push equals the one summed over every primitive pair (brute force): the live
/// pairs held every pair within the barrier's reach.
#[test]
fn sheets_falling_through_each_other_keep_every_pair_within_reach_live() {
    let n = 9u32;
    let mut safe = Vec::new();
    let mut target = Vec::new();
    let sheets = [
        (0.0, 0.0, 0.05),
        (0.045, 0.0015, 0.053),
        (0.045, 0.0065, 0.053),
    ];
    for (shift, height, fall) in sheets {
        for j in 0..n {
            for i in 0..n {
                let (u, v) = (f64::from(i) * 0.01, f64::from(j) * 0.01);
                let wave = 0.0002 * (40.0 * u).sin() * (30.0 * v).cos();
                let p = Vector3::new(u + shift, v, height + wave);
                safe.push(p);
                target.push(p - Vector3::new(0.0, 0.0, fall));
            }
        }
    }
    let mut triangles = Vec::new();
    let mut body = Vec::new();
    for sheet in 0..3 {
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let v = sheet * n * n + j * n + i;
                triangles.push([v, v + 1, v + n + 1]);
                triangles.push([v, v + n + 1, v + n]);
                body.extend([sheet, sheet]);
            }
        }
    }
    let mesh = ContactMesh {
        triangles: &triangles,
        body: &body,
        self_contact: &[true, true, true],
    };
    let params = ContactParams {
        thickness: 1e-3,
        d_hat: 2e-3,
        // Few descent moves: their drift alone would not bring the pairs in.
        max_iters: 2,
        ..ContactParams::default()
    };
    let mut z = target.clone();
    let mut work = Workspace::default();
    let fixed = vec![false; safe.len()];
    let stats = resolve_contacts(
        &safe, &mut z, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
    );
    assert!(stats.active_pairs > 0, "{stats:?}");
    // Held back by clamps: some vertices by far more than the descent's moves of at most
    // `eps xi` each could take them, others hardly at all.
    let held: Vec<f64> = z.iter().zip(&target).map(|(a, b)| (a - b).norm()).collect();
    let most = held.iter().copied().fold(0.0, f64::max);
    let least = held.iter().copied().fold(f64::INFINITY, f64::min);
    let descent = params.max_iters as f64 * params.eps * params.thickness;
    assert!(
        most > 2.0 * descent && least < 0.1 * descent,
        "{most} {least}"
    );
    assert_push_from_every_pair(&mesh, &safe, &z, &params, &work);
    // The same local step again starts from the allowances the first one needed: it
    // refreshes the live list less often, and keeps every pair `eps xi` apart. (Its
    // positions differ a little: a refresh restarts the CCD, whose additive steps can
    // report a time for pairs it would otherwise have skipped.)
    let mut again = target.clone();
    let second = resolve_contacts(
        &safe, &mut again, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
    );
    assert!(
        second.live_refreshes < stats.live_refreshes,
        "{} then {} refreshes",
        stats.live_refreshes,
        second.live_refreshes
    );
    assert_push_from_every_pair(&mesh, &safe, &again, &params, &work);
}

/// A triangle within `xi` of a fixed one that the global step takes 10 mm through it: the
/// CCD inside the descent finds the time of impact below its threshold and leaves the
/// move, the descent sees no barrier at the far side (beyond reach) and stops at once,
/// so only the guarantee pass keeps the triangle out. It clamps all three vertices, which
/// end at least the floor `eps xi` above, and the barrier push left for the next global
/// iteration is measured where the clamps left them (not where the descent last saw
/// them, beyond reach with no push). The first time the clamps take the vertices beyond
/// their allowances and the live pairs are filtered afresh; the same local step again
/// starts with room for them, keeps its list, and measures only the clamped vertices'
/// pairs afresh.
#[test]
fn the_guarantee_pass_keeps_out_a_move_from_within_the_threshold_and_measures_its_push() {
    let v = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
    let lower = [v(-1.0, -1.0, 0.0), v(2.0, -1.0, 0.0), v(-1.0, 2.0, 0.0)];
    let upper = [v(0.1, 0.1, 0.0), v(0.2, 0.1, 0.0), v(0.1, 0.2, 0.0)];
    let params = pressing(DescentStep::Curvature, 32);
    let (xi, floor) = (params.thickness, params.eps * params.thickness);
    let height = 1.5 * floor;
    let safe: Vec<_> = lower
        .iter()
        .copied()
        .chain(upper.iter().map(|p| p + v(0.0, 0.0, height)))
        .collect();
    let target: Vec<_> = lower
        .iter()
        .copied()
        .chain(upper.iter().map(|p| p - v(0.0, 0.0, 0.01)))
        .collect();
    // The time of impact at `xi` is 0 and at the floor far below the threshold.
    assert!(height < xi && (height - floor) / (height + 0.01) < params.toi_threshold);
    let triangles = [[0, 1, 2], [3, 4, 5]];
    let mesh = ContactMesh {
        triangles: &triangles,
        body: &[0, 1],
        self_contact: &[true, true],
    };
    let fixed = [true, true, true, false, false, false];
    let mut work = Workspace::default();
    for refreshes in [2, 0] {
        let mut z = target.clone();
        let stats = resolve_contacts(
            &safe, &mut z, &fixed, None, &mesh, &params, NO_TOL, FREE, &mut work,
        );
        assert_eq!(stats.iterations, 1, "{stats:?}");
        assert_eq!(stats.clamped, 3, "{stats:?}");
        assert_eq!(stats.live_refreshes, refreshes, "{stats:?}");
        for p in &z[3..] {
            assert!(floor <= p.z && p.z < height, "{p}");
        }
        assert!(work.push()[3..].iter().all(|p| p.z > 0.0));
        assert_push_from_every_pair(&mesh, &safe, &z, &params, &work);
    }
}

#[test]
fn far_apart_bodies_are_left_alone() {
    let (safe, _, triangles) = crossing();
    let body = [0, 1];
    let mesh = ContactMesh {
        triangles: &triangles,
        body: &body,
        self_contact: &[true, true],
    };
    let mut z = safe.clone();
    let params = ContactParams {
        thickness: 1e-3,
        d_hat: 2e-3,
        ..ContactParams::default()
    };
    resolve_contacts(
        &safe,
        &mut z,
        &[false; 6],
        None,
        &mesh,
        &params,
        NO_TOL,
        FREE,
        &mut Workspace::default(),
    );
    assert_eq!(z, safe);
}
