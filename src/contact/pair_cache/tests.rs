//! Tests of the pair cache.

use nalgebra::Vector3;

use super::super::primitive_pairs::close_primitive_pairs;
use super::super::test_meshes::{brute_force_pairs, grid_triangles, spiral, two_copies};
use super::build::{limit, SKIN_MOVES, SKIN_RINGS};
use super::filter::OUTLYING_SHARE;
use super::*;
use crate::geometry::distance::tests::Rng;

/// One local step's moves: the safe positions, the global step's result, per vertex the
/// clamp factor `t_i` in `[0, 1]` (1: not clamped) and the allowance `A_i` (m), at least
/// `(1 - t_i) |y_i - s_i|`.
struct Moves<'a> {
    safe: &'a [Vector3<f64>],
    target: &'a [Vector3<f64>],
    clamp: &'a [f64],
    allowance: &'a [f64],
}

impl<'a> Moves<'a> {
    fn new(
        safe: &'a [Vector3<f64>],
        target: &'a [Vector3<f64>],
        clamp: &'a [f64],
        allowance: &'a [f64],
    ) -> Self {
        Moves {
            safe,
            target,
            clamp,
            allowance,
        }
    }

    /// Checks that every pair of `every` within `reach` (m) is in `live`, at points along
    /// the paths `s + tau (z - s)` (the ends included) to iterates `z_i = s_i + t_i (y_i -
    /// s_i) + e_i`, with `|e_i|` up to what the allowance leaves, `A_i - (1 - t_i) |y_i -
    /// s_i|` (so `|z_i - y_i| <= A_i`, as the local step keeps it); returns how many were
    /// within reach.
    fn assert_live_hold_every_pair_within_reach(
        &self,
        every: &[Pair],
        live: &[Pair],
        reach: f64,
        rng: &mut Rng,
        step: usize,
    ) -> usize {
        let mut within = 0;
        let mut live = live.to_vec();
        live.sort_unstable();
        let z: Vec<_> = (0..self.safe.len())
            .map(|i| {
                let (s, y, t) = (self.safe[i], self.target[i], self.clamp[i]);
                let slack = self.allowance[i] - (1.0 - t) * (y - s).norm();
                assert!(slack >= 0.0, "vertex {i}: the allowance misses the clamp");
                s + (y - s) * t + rng.vector() * (slack / 3f64.sqrt())
            })
            .collect();
        for tau in [0.0, 0.3, 0.7, 1.0] {
            let x: Vec<_> = self
                .safe
                .iter()
                .zip(&z)
                .map(|(s, z)| s + (z - s) * tau)
                .collect();
            for p in every {
                if p.closest(&x).separation.norm() < reach {
                    within += 1;
                    assert!(live.binary_search(p).is_ok(), "step {step}: missed {p:?}");
                }
            }
        }
        within
    }
}

impl PairCache {
    /// Checks that every cached pair whose bounds may come within `reach` (m) for the
    /// allowances `allowance` (m), on the path the sweep last measured, is in `live`;
    /// returns how many of them repairs added.
    fn assert_live_hold_every_cached_pair_that_may_come_within(
        &self,
        live: &[Pair],
        allowance: &[f64],
        reach: f64,
        step: usize,
    ) -> usize {
        let mut live = live.to_vec();
        live.sort_unstable();
        let mut repaired = 0;
        for (k, (p, _)) in self.pairs.iter().enumerate() {
            if self.may_come_within(k, allowance, reach) {
                assert!(
                    live.binary_search(p).is_ok(),
                    "step {step}: cached pair {k} of {} ({} arranged) is not live",
                    self.pairs.len(),
                    self.arranged
                );
                repaired += usize::from(k >= self.arranged);
            }
        }
        repaired
    }

    /// Checks that the stored pairs are exactly those of `every` closer than their limit
    /// at the reference positions (brute force), each with its distance there rounded
    /// down.
    fn assert_stores_exactly_the_pairs_within_their_limit(
        &self,
        every: &[Pair],
        reach: f64,
        step: usize,
    ) {
        let r = &self.reference;
        let limit = |p: &Pair| limit(&self.skin, &self.regions, reach, p);
        for (p, d) in &self.pairs {
            assert!(
                f64::from(*d) <= p.closest(r).separation.norm(),
                "step {step}"
            );
            assert!(f64::from(*d) < limit(p), "step {step}");
        }
        let mut stored: Vec<Pair> = self.pairs.iter().map(|(p, _)| *p).collect();
        stored.sort_unstable();
        let mut close: Vec<Pair> = every
            .iter()
            .copied()
            .filter(|p| p.closest(r).separation.norm() < limit(p))
            .collect();
        close.sort_unstable();
        assert_eq!(stored, close, "step {step}");
    }
}

/// A test mesh: positions (m), triangles, the body of each triangle and whether each body
/// has self-contact.
struct TestMesh {
    positions: Vec<Vector3<f64>>,
    triangles: Vec<[u32; 3]>,
    body: Vec<u32>,
    self_contact: Vec<bool>,
}

impl TestMesh {
    /// The rolled-up grid of [`spiral`], one body.
    fn rolled(n: u32, gap: f64, rng: &mut Rng) -> Self {
        let (positions, triangles) = spiral(n, gap, rng);
        let body = vec![0; triangles.len()];
        TestMesh {
            positions,
            triangles,
            body,
            self_contact: vec![true],
        }
    }

    /// Two flat square sheets of `side x side` vertices 2 cm apart, in the planes `x = 0`
    /// and `x = apart` (m), bodies 0 and 1.
    fn two_sheets(side: u32, apart: f64) -> Self {
        let sheet = |x: f64| {
            (0..side * side).map(move |v| {
                Vector3::new(x, 0.02 * f64::from(v / side), 0.02 * f64::from(v % side))
            })
        };
        let positions = sheet(0.0).chain(sheet(apart)).collect();
        let (triangles, body) = two_copies(&grid_triangles(side), side * side);
        TestMesh {
            positions,
            triangles,
            body,
            self_contact: vec![true, true],
        }
    }

    fn mesh(&self) -> ContactMesh<'_> {
        ContactMesh {
            triangles: &self.triangles,
            body: &self.body,
            self_contact: &self.self_contact,
        }
    }
}

/// A non-manifold mesh: the rolled-up grid with a fin on some of its edges (a third
/// triangle on an edge two triangles already share, its tip 4 mm off the grid). A build
/// stores exactly the primitive pairs closer than their limit (brute force over all
/// primitive pairs), as on a manifold mesh: the owners of pairs on such edges are looked up
/// among all their triangles.
#[test]
fn a_build_on_non_manifold_edges_stores_every_close_pair() {
    let mut rng = Rng::new(23);
    let mut rolled = TestMesh::rolled(10, 0.03, &mut rng);
    let fins: Vec<[u32; 3]> = rolled.triangles.iter().step_by(7).copied().collect();
    for [a, b, c] in fins {
        let tip = rolled.positions[c as usize] + Vector3::new(0.0, 0.0, 0.004);
        rolled.triangles.push([a, b, rolled.positions.len() as u32]);
        rolled.positions.push(tip);
        rolled.body.push(0);
    }
    let mesh = rolled.mesh();
    let safe = rolled.positions.clone();
    let (_, every) = brute_force_pairs(&mesh, &safe);
    let (reach, allowance) = (0.02, vec![0.002; safe.len()]);
    let mut cache = PairCache::default();
    let mut live = Vec::new();
    assert_eq!(
        cache.live_pairs(&safe, &safe, &allowance, &mesh, reach, &mut live),
        Renewal::Built
    );
    let limit = |p: &Pair| limit(&cache.skin, &cache.regions, reach, p);
    let mut stored: Vec<Pair> = cache.pairs.iter().map(|(p, _)| *p).collect();
    stored.sort_unstable();
    let mut close: Vec<Pair> = every
        .iter()
        .copied()
        .filter(|p| p.closest(&safe).separation.norm() < limit(p))
        .collect();
    close.sort_unstable();
    assert!(close.len() > 100, "{} close pairs", close.len());
    assert_eq!(stored, close);
}

/// The rolled-up grid (layers a little more than the barrier's reach apart) moving over
/// several local steps: the live pairs hold every primitive pair of non-adjacent triangles
/// that a brute-force search finds within `reach` along the way; each build's candidates
/// are exactly the triangle pairs that own (see [`Owners`]) a primitive pair closer than
/// its limit `reach + max_P R + max_Q R` (brute force), at the first build fewer than three
/// quarters of the box pairs, and its stored primitive pairs are exactly those closer than
/// their limit (brute force over all primitive pairs): expanding only the owned pairs loses
/// none.
#[test]
fn crumpled_grid_keeps_every_pair_a_brute_force_search_finds() {
    let mut rng = Rng::new(19);
    let rolled = TestMesh::rolled(14, 0.03, &mut rng);
    let mesh = rolled.mesh();
    let mut safe = rolled.positions.clone();
    let (all, every) = brute_force_pairs(&mesh, &safe);
    let (reach, allowance) = (0.02, vec![0.002; safe.len()]);
    let clamp = vec![1.0; safe.len()];
    let mut cache = PairCache::default();
    let mut live = Vec::new();
    let mut builds = Vec::new();
    let mut within = 0;
    for (k, size) in [0.002, 0.004, 0.015, 0.002, 0.004].into_iter().enumerate() {
        let target: Vec<_> = safe.iter().map(|p| p + rng.vector() * size).collect();
        let renewal = cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live);
        builds.push(renewal);
        if renewal == Renewal::Built {
            let r = &cache.reference;
            let limit = |p: &Pair| limit(&cache.skin, &cache.regions, reach, p);
            let near: Vec<_> = all
                .iter()
                .copied()
                .filter(|&pair| {
                    let mut owned = Vec::new();
                    let candidates = close_primitive_pairs(
                        &mesh,
                        Some(&cache.owners),
                        &[pair],
                        r,
                        limit,
                        |_, _| true,
                        &mut owned,
                    );
                    !candidates.is_empty()
                })
                .collect();
            let mut candidates = cache.candidates.clone();
            candidates.sort_unstable();
            assert_eq!(candidates, near, "step {k}");
            assert!(
                k > 0 || 4 * cache.candidates() < 3 * cache.box_pairs(),
                "step {k}: {} candidates of {} box pairs",
                cache.candidates(),
                cache.box_pairs()
            );
            cache.assert_stores_exactly_the_pairs_within_their_limit(&every, reach, k);
        }
        let moves = Moves::new(&safe, &target, &clamp, &allowance);
        within += moves.assert_live_hold_every_pair_within_reach(&every, &live, reach, &mut rng, k);
        safe = target;
    }
    assert!(within > 100, "the scene has pairs within reach: {within}");
    use Renewal::{Built, Kept};
    assert_eq!(builds, [Built, Kept, Built, Kept, Kept]);
}

/// The rolled-up grid falling fast (5 reaches per local step, each vertex jittered by up
/// to 3 mm on top), first freely, then with every other vertex clamped back towards its
/// safe position by its own factor, beside the same moves without the fall: the live
/// pairs hold every pair a brute-force search finds within `reach` on the local step's
/// paths. Falling freely, the common motion costs nothing: the build is kept as long as at
/// rest (the absolute motion of 0.1 m per step would force one every step), and it caches
/// and keeps live as many pairs as at rest. Clamped, vertices lag behind their neighbours
/// by up to 0.1 m, and more than three times as many pairs are live.
#[test]
fn a_falling_grid_keeps_few_pairs_live_unless_clamped() {
    /// Per local step: whether it built, the cached and the live pairs.
    fn run(fall: Vector3<f64>, within: &mut [usize; 2]) -> Vec<(bool, usize, usize)> {
        let mut rng = Rng::new(23);
        let rolled = TestMesh::rolled(12, 0.03, &mut rng);
        let mesh = rolled.mesh();
        let mut safe = rolled.positions.clone();
        let (_, every) = brute_force_pairs(&mesh, &safe);
        let (reach, drift) = (0.02, 0.001);
        let mut cache = PairCache::default();
        let mut live = Vec::new();
        let mut steps = Vec::new();
        for k in 0..6 {
            let clamped = k >= 3;
            let target: Vec<_> = safe
                .iter()
                .map(|p| p + fall + rng.vector() * 0.003)
                .collect();
            let clamp: Vec<f64> = (0..safe.len())
                .map(|i| {
                    if clamped && i % 2 == 0 {
                        rng.uniform().abs()
                    } else {
                        1.0
                    }
                })
                .collect();
            let allowance: Vec<f64> = (0..safe.len())
                .map(|i| (1.0 - clamp[i]) * (target[i] - safe[i]).norm() + drift)
                .collect();
            let built = cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live)
                != Renewal::Kept;
            steps.push((built, cache.pairs.len(), live.len()));
            let moves = Moves::new(&safe, &target, &clamp, &allowance);
            within[usize::from(clamped)] +=
                moves.assert_live_hold_every_pair_within_reach(&every, &live, reach, &mut rng, k);
            // The next local step starts where this one ended (unclamped: the whole move).
            safe = (0..safe.len())
                .map(|i| safe[i] + (target[i] - safe[i]) * clamp[i])
                .collect();
        }
        steps
    }
    let mut within = [0, 0];
    let falling = run(Vector3::new(0.0, 0.0, -0.1), &mut within);
    let resting = run(Vector3::zeros(), &mut [0, 0]);
    assert!(falling[0].0);
    let close = |a: usize, b: usize| a.abs_diff(b) * 100 <= b;
    for (k, (f, r)) in falling.iter().zip(&resting).enumerate().take(3) {
        assert_eq!(f.0, r.0, "step {k}: built {f:?} at rest {r:?}");
        assert!(
            close(f.1, r.1) && close(f.2, r.2),
            "step {k}: {f:?} at rest {r:?}"
        );
    }
    assert_eq!(falling[1..3].iter().filter(|f| f.0).count(), 0);
    let free = falling[..3].iter().map(|f| f.2).max().unwrap();
    for (k, f) in falling.iter().enumerate().skip(3) {
        assert!(
            f.2 > 3 * free,
            "step {k}: {f:?}, free fall at most {free} live"
        );
    }
    assert!(
        within[0] > 100 && within[1] > within[0],
        "the scene has pairs within reach: {within:?}"
    );
}

/// Two rolled-up grids (two bodies) flying into each other (8 reaches per local step
/// relative to each other, each vertex jittered by up to 3 mm): the live pairs hold every
/// pair a brute-force search finds within `reach`, across the bodies included; the
/// approach renews the build every [`SKIN_MOVES`] steps or one sooner (the skins of the
/// region pairs across hold about that many steps of it), and each build keeps no more
/// pairs within a body than the same grid alone at rest.
#[test]
fn two_bodies_flying_into_each_other_keep_every_pair_across() {
    let mut rng = Rng::new(31);
    let (one, triangles_one) = spiral(10, 0.03, &mut rng);
    let (other, _) = spiral(10, 0.03, &mut rng);
    let n = one.len() as u32;
    let offset = Vector3::new(0.45, 0.0, 0.0);
    let mut safe: Vec<_> = one
        .iter()
        .copied()
        .chain(other.iter().map(|p| p + offset))
        .collect();
    let (triangles, body) = two_copies(&triangles_one, n);
    let mesh = ContactMesh {
        triangles: &triangles,
        body: &body,
        self_contact: &[true, true],
    };
    let (_, every) = brute_force_pairs(&mesh, &safe);
    let across = |p: &Pair| (p.v[0] < n) != (p.v[3] < n);
    let (reach, allowance) = (0.02, vec![0.001; safe.len()]);
    let clamp = vec![1.0; safe.len()];
    // One grid alone, resting with the same jitter: its cached pairs.
    let alone = {
        let mesh = ContactMesh {
            triangles: &triangles_one,
            body: &body[..triangles_one.len()],
            self_contact: &[true],
        };
        let jittered: Vec<_> = one.iter().map(|p| p + rng.vector() * 0.003).collect();
        let mut cache = PairCache::default();
        cache.live_pairs(
            &one,
            &jittered,
            &allowance[..one.len()],
            &mesh,
            reach,
            &mut Vec::new(),
        );
        cache.pairs.len()
    };
    let mut cache = PairCache::default();
    let mut live = Vec::new();
    let mut builds = Vec::new();
    let mut within = [0, 0];
    let steps = 3 * SKIN_MOVES as usize;
    for k in 0..steps {
        let target: Vec<_> = (0..safe.len())
            .map(|i| {
                let towards = if i < n as usize { 0.08 } else { -0.08 };
                safe[i] + Vector3::new(towards, 0.0, 0.0) + rng.vector() * 0.003
            })
            .collect();
        let built =
            cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live) != Renewal::Kept;
        builds.push(built);
        if built {
            let own = cache.pairs.iter().filter(|(p, _)| !across(p)).count();
            assert!(
                own <= 2 * alone + alone / 10,
                "step {k}: {own} pairs within the bodies, {alone} alone"
            );
        }
        let moves = Moves::new(&safe, &target, &clamp, &allowance);
        let (own, apart): (Vec<Pair>, Vec<Pair>) = every.iter().partition(|p| !across(p));
        within[0] +=
            moves.assert_live_hold_every_pair_within_reach(&own, &live, reach, &mut rng, k);
        within[1] +=
            moves.assert_live_hold_every_pair_within_reach(&apart, &live, reach, &mut rng, k);
        safe = target;
    }
    assert!(
        within[0] > 100 && within[1] > 100,
        "pairs within reach: {within:?}"
    );
    // The jitter of the regions' means eats into the room of the last step or so.
    let at: Vec<usize> = (0..steps).filter(|&k| builds[k]).collect();
    assert_eq!(at[0], 0);
    assert!(
        at.windows(2)
            .all(|w| (SKIN_MOVES as usize - 1..=SKIN_MOVES as usize).contains(&(w[1] - w[0]))),
        "builds at steps {at:?}"
    );
}

/// Two flat sheets facing each other at rest, 0.2 m apart, until one sets off towards
/// the other (5 mm per local step, each vertex jittered by up to 0.5 mm, allowances of
/// 1 cm): the build at rest keeps no pair across (their regions are far, and the skins of
/// far regions hold the approach until they come near), a second build comes before the
/// first pair across within reach, and the live pairs hold every pair a brute-force
/// search finds within `reach` all the way into contact. Flat sheets make the boxes of
/// the regions' halos as close as their triangles, so every term of a far region pair's
/// skin counts.
#[test]
fn a_body_setting_off_renews_the_build_before_it_comes_near() {
    let mut rng = Rng::new(37);
    let side = 12u32;
    let n = side * side;
    let sheets = TestMesh::two_sheets(side, 0.2);
    let (mesh, mut safe) = (sheets.mesh(), sheets.positions.clone());
    let (_, every) = brute_force_pairs(&mesh, &safe);
    let across: Vec<Pair> = every
        .iter()
        .copied()
        .filter(|p| (p.v[0] < n) != (p.v[3] < n))
        .collect();
    let (reach, allowance) = (0.02, vec![0.01; safe.len()]);
    let clamp = vec![1.0; safe.len()];
    let (mut cache, mut live, mut builds, mut within) =
        (PairCache::default(), Vec::new(), Vec::new(), Vec::new());
    for k in 0..40 {
        let target: Vec<_> = (0..safe.len())
            .map(|i| {
                let set_off = i >= n as usize && k >= 2;
                let towards = if set_off { -0.005 } else { 0.0 };
                safe[i] + Vector3::new(towards, 0.0, 0.0) + rng.vector() * 0.0005
            })
            .collect();
        let built =
            cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live) != Renewal::Kept;
        builds.push(built);
        if k == 0 {
            let kept = cache.pairs.iter();
            assert!(kept.clone().all(|(p, _)| (p.v[0] < n) == (p.v[3] < n)));
        }
        let moves = Moves::new(&safe, &target, &clamp, &allowance);
        within.push(
            moves.assert_live_hold_every_pair_within_reach(&across, &live, reach, &mut rng, k),
        );
        safe = target;
    }
    let first_within = within.iter().position(|&w| w > 0).expect("contact");
    assert!(
        within.iter().sum::<usize>() > 50,
        "pairs across within reach: {within:?}"
    );
    assert!(
        builds[0] && builds[1..=first_within].contains(&true),
        "builds {builds:?}, pairs within reach {within:?}"
    );
}

/// Two sheets 5 cm apart at rest, first with a reach of 2 cm (no pair across is stored),
/// then with a reach of 8 cm (as after `Solver.set_params`): the lists are built afresh,
/// and every pair across that a brute-force search finds within the new reach is live.
#[test]
fn a_longer_reach_renews_the_build() {
    let side = 6u32;
    let n = side * side;
    let sheets = TestMesh::two_sheets(side, 0.05);
    let (mesh, safe) = (sheets.mesh(), sheets.positions.clone());
    let (_, every) = brute_force_pairs(&mesh, &safe);
    let across = |p: &Pair| (p.v[0] < n) != (p.v[3] < n);
    let allowance = vec![1e-3; safe.len()];
    let (mut cache, mut live) = (PairCache::default(), Vec::new());
    cache.live_pairs(&safe, &safe, &allowance, &mesh, 0.02, &mut live);
    assert!(!cache.pairs.iter().any(|(p, _)| across(p)));
    let renewal = cache.live_pairs(&safe, &safe, &allowance, &mesh, 0.08, &mut live);
    assert_eq!(renewal, Renewal::Built);
    let wanted: Vec<Pair> = every
        .iter()
        .copied()
        .filter(|p| across(p) && p.closest(&safe).separation.norm() < 0.08)
        .collect();
    let missed = wanted.iter().filter(|p| !live.contains(p)).count();
    assert!(wanted.len() > 100, "{} pairs across", wanted.len());
    assert_eq!(
        missed,
        0,
        "{missed} of {} pairs across missed",
        wanted.len()
    );
}

/// Two flat sheets 2.5 cm apart, at rest but for a jitter of up to 0.3 mm, while two
/// vertices of one set off towards the other, faster at every local step (allowances of
/// 2 mm): they stray beyond their skins while their regions' motions still fit, and the
/// build is repaired rather than built afresh; after every repair (and build) the stored
/// pairs are exactly those within their raised limits (brute force), and the live pairs
/// hold every pair a brute-force search finds within `reach` until the strays are 3 mm
/// from the other sheet. The live pairs also hold every cached pair whose bounds may come
/// within reach, before and after the strays' allowances grow by 1 mm and the list is
/// extended; among them are pairs that repairs added, and the extensions add some (such
/// pairs are not indexed by vertex, see [`PairCache::extend_live`]).
#[test]
fn a_few_strays_repair_the_build_and_miss_no_pair() {
    let mut rng = Rng::new(41);
    let side = 12u32;
    let n = side * side;
    let sheets = TestMesh::two_sheets(side, 0.025);
    let (mesh, mut safe) = (sheets.mesh(), sheets.positions.clone());
    let (_, every) = brute_force_pairs(&mesh, &safe);
    let strays = [n + 5 * side + 5, n + 7 * side + 6];
    let (reach, allowance) = (0.01, vec![0.002; safe.len()]);
    let clamp = vec![1.0; safe.len()];
    let (mut cache, mut live, mut renewals, mut within) =
        (PairCache::default(), Vec::new(), Vec::new(), 0);
    let (mut repaired_live, mut repaired_added) = (0, 0);
    for k in 0..8 {
        let target: Vec<_> = (0..safe.len())
            .map(|i| {
                let towards = if strays.contains(&(i as u32)) && k >= 1 {
                    -0.0008 * k as f64
                } else {
                    0.0
                };
                safe[i] + Vector3::new(towards, 0.0, 0.0) + rng.vector() * 0.0003
            })
            .collect();
        let renewal = cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live);
        renewals.push(renewal);
        if renewal != Renewal::Kept {
            cache.assert_stores_exactly_the_pairs_within_their_limit(&every, reach, k);
        }
        let moves = Moves::new(&safe, &target, &clamp, &allowance);
        within += moves.assert_live_hold_every_pair_within_reach(&every, &live, reach, &mut rng, k);
        repaired_live += cache
            .assert_live_hold_every_cached_pair_that_may_come_within(&live, &allowance, reach, k);
        let mut grown_allowance = allowance.clone();
        for &v in &strays {
            grown_allowance[v as usize] += 0.001;
        }
        let mut extended = live.clone();
        if let Some(renewal) =
            cache.extend_live(&grown_allowance, &strays, &mesh, reach, &mut extended)
        {
            assert_eq!(renewal, Renewal::Kept, "step {k}: the grown allowances fit");
            cache.assert_live_hold_every_cached_pair_that_may_come_within(
                &extended,
                &grown_allowance,
                reach,
                k,
            );
            let mut repaired: Vec<Pair> = cache.pairs[cache.arranged..]
                .iter()
                .map(|(p, _)| *p)
                .collect();
            repaired.sort_unstable();
            repaired_added += extended[live.len()..]
                .iter()
                .filter(|p| repaired.binary_search(p).is_ok())
                .count();
        }
        // The next filter starts afresh, as the local step's next refresh would.
        safe = target;
    }
    assert!(within > 100, "the scene has pairs within reach: {within}");
    assert!(
        repaired_live > 0 && repaired_added > 0,
        "repaired pairs that may come within reach: {repaired_live} live, \
         {repaired_added} added by the extensions"
    );
    let (x0, x1) = (safe[strays[0] as usize].x, safe[strays[1] as usize].x);
    assert!(
        (0.0..0.01).contains(&x0) && (0.0..0.01).contains(&x1),
        "the strays came within reach of the other sheet, short of it: {x0}, {x1}"
    );
    assert!(
        renewals.iter().filter(|&&r| r == Renewal::Repaired).count() >= 2,
        "{renewals:?}"
    );
}

/// Two sheets 18 mm apart, jittered by up to 0.3 mm, while two vertices of one head for
/// the other at 3 mm per local step, from the build on (so that the build stores their
/// pairs with the other sheet): their deviations reach 14 mm and the others' stay near
/// 3 mm, so the filter's horizon from all but the two (`reach + 2 D + max T`) is less than
/// half of the one from the farthest (`D` = the largest deviation) and leaves out their
/// pairs with the other sheet; found by the index by vertex, those that may come within
/// reach are still live (every cached pair that may, and every pair within reach by brute
/// force).
#[test]
fn a_few_fast_vertices_do_not_make_every_pair_near() {
    let mut rng = Rng::new(47);
    let side = 24u32;
    let n = side * side;
    let sheets = TestMesh::two_sheets(side, 0.018);
    let (mesh, rest) = (sheets.mesh(), sheets.positions.clone());
    let (_, every) = brute_force_pairs(&mesh, &rest);
    let strays = [n + 9 * side + 9, n + 14 * side + 12];
    assert_eq!((OUTLYING_SHARE * f64::from(2 * n)) as usize, strays.len());
    let (reach, allowance) = (0.008, vec![0.002; rest.len()]);
    let clamp = vec![1.0; rest.len()];
    let (mut cache, mut live, mut within) = (PairCache::default(), Vec::new(), 0);
    let (mut safe, mut beyond_live) = (rest.clone(), 0);
    for k in 0..4 {
        let target: Vec<_> = (0..rest.len())
            .map(|i| {
                let towards = if strays.contains(&(i as u32)) {
                    -0.003 * (k + 1) as f64
                } else {
                    0.0
                };
                rest[i] + Vector3::new(towards, 0.0, 0.0) + rng.vector() * 0.0003
            })
            .collect();
        let renewal = cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live);
        assert_eq!(renewal == Renewal::Built, k == 0, "step {k}: {renewal:?}");
        let (near, outlying) = cache.near(reach);
        assert_eq!(outlying, strays, "step {k}");
        let farthest = cache.deviation.iter().copied().fold(0.0, f64::max);
        let near_by_farthest = cache.order.within(reach + 2.0 * farthest + cache.apart);
        if k >= 2 {
            assert!(
                2 * near < near_by_farthest,
                "step {k}: {near} pairs near, {near_by_farthest} by the farthest deviation"
            );
        }
        let mut live_sorted = live.clone();
        live_sorted.sort_unstable();
        beyond_live += cache.pairs[near..cache.arranged]
            .iter()
            .filter(|(p, _)| live_sorted.binary_search(p).is_ok())
            .count();
        cache.assert_live_hold_every_cached_pair_that_may_come_within(&live, &allowance, reach, k);
        let moves = Moves::new(&safe, &target, &clamp, &allowance);
        within += moves.assert_live_hold_every_pair_within_reach(&every, &live, reach, &mut rng, k);
        safe = target;
    }
    assert!(within > 100, "the scene has pairs within reach: {within}");
    assert!(
        beyond_live > 0,
        "live pairs beyond the horizon: {beyond_live}"
    );
}

/// One edge of the rolled-up grid swinging fast (up to 0.05 m per local step, the rest
/// jittered by up to 3 mm): the live pairs hold every pair within reach (brute force),
/// the moving vertices and those within `SKIN_RINGS` rings of them (a ring is a column of
/// the grid) get skins for the motion, and the vertices of regions away from it (more than
/// a quarter of the sheet) keep the small skins of their own jitter.
#[test]
fn a_swinging_edge_leaves_the_rest_of_the_sheet_a_small_skin() {
    let mut rng = Rng::new(43);
    let n = 24;
    let rolled = TestMesh::rolled(n, 0.03, &mut rng);
    let mesh = rolled.mesh();
    let mut safe = rolled.positions.clone();
    let (_, every) = brute_force_pairs(&mesh, &safe);
    let (reach, allowance) = (0.02, vec![0.001; safe.len()]);
    let clamp = vec![1.0; safe.len()];
    // Column `i` of the grid: the edge i = 0 swings, columns 0..=3 are within 3 rings.
    let column = |v: usize| v % n as usize;
    let (mut cache, mut live, mut within) = (PairCache::default(), Vec::new(), 0);
    for k in 0..4 {
        let target: Vec<_> = (0..safe.len())
            .map(|v| {
                let swing = if column(v) == 0 { 0.05 } else { 0.0 };
                safe[v] + Vector3::new(0.0, 0.0, swing) + rng.vector() * 0.003
            })
            .collect();
        if cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live) == Renewal::Built {
            // A vertex at rest strays from the mean of a region at rest by at most twice
            // the jitter; one whose regions' halos hold a swinging vertex (within the
            // rings its skin spreads over) strays by their share of the swing.
            let jitter = SKIN_MOVES * 2.0 * 0.003 * 3f64.sqrt() + 0.001 + 0.25 * reach;
            let regions = &cache.regions;
            let swinging: Vec<u32> = (0..safe.len())
                .filter(|&v| column(v) == 0)
                .flat_map(|v| regions.holding(v).to_vec())
                .collect();
            let mut near_swing: Vec<bool> = (0..safe.len())
                .map(|v| regions.holding(v).iter().any(|p| swinging.contains(p)))
                .collect();
            for _ in 0..SKIN_RINGS {
                let before = near_swing.clone();
                for t in mesh.triangles {
                    if t.iter().any(|&v| before[v as usize]) {
                        t.iter().for_each(|&v| near_swing[v as usize] = true);
                    }
                }
            }
            let away = near_swing.iter().filter(|&&n| !n).count();
            assert!(away > safe.len() / 4, "{away} vertices away from the swing");
            for (v, &r) in cache.skin.iter().enumerate() {
                if column(v) <= SKIN_RINGS {
                    let swung = SKIN_MOVES * 0.04;
                    assert!(
                        r > swung,
                        "step {k}: vertex {v} swings or is near, skin {r}"
                    );
                } else if !near_swing[v] {
                    assert!(r < jitter, "step {k}: vertex {v} at rest, skin {r}");
                }
            }
        }
        let moves = Moves::new(&safe, &target, &clamp, &allowance);
        within += moves.assert_live_hold_every_pair_within_reach(&every, &live, reach, &mut rng, k);
        safe = target;
    }
    assert!(within > 100, "the scene has pairs within reach: {within}");
}

/// Growing the allowances of some vertices and extending the live list gives the list a
/// full filter gives for the grown allowances, whether the build still covers them (a
/// few vertices by a few millimetres), is repaired for them (one vertex by 0.3 m: the
/// extension repairs, as the filter does) or is built afresh (a third of the vertices by
/// 0.3 m, too many to repair: the extension declines and the filter builds).
#[test]
fn extending_the_live_pairs_equals_filtering_them_afresh() {
    let mut rng = Rng::new(41);
    let rolled = TestMesh::rolled(12, 0.03, &mut rng);
    let mesh = rolled.mesh();
    let safe = rolled.positions.clone();
    let (_, all_pairs) = brute_force_pairs(&mesh, &safe);
    let reach = 0.02;
    let target: Vec<_> = safe.iter().map(|p| p + rng.vector() * 0.004).collect();
    let mut allowance = vec![0.001; safe.len()];
    let (mut extended, mut afresh) = (PairCache::default(), PairCache::default());
    let (mut by_extension, mut by_filter) = (Vec::new(), Vec::new());
    extended.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut by_extension);
    afresh.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut by_filter);
    let first = by_extension.len();
    use Renewal::{Built, Kept, Repaired};
    for (round, (every, by, expected)) in [
        (7, 0.004, Kept),
        (5, 0.004, Kept),
        (1000, 0.3, Repaired),
        (3, 0.3, Built),
    ]
    .into_iter()
    .enumerate()
    {
        let grown: Vec<u32> = (0..safe.len() as u32).step_by(every).collect();
        for &v in &grown {
            allowance[v as usize] += by;
        }
        let renewal = extended
            .extend_live(&allowance, &grown, &mesh, reach, &mut by_extension)
            .unwrap_or_else(|| {
                extended.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut by_extension)
            });
        let renewal_afresh =
            afresh.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut by_filter);
        assert_eq!([renewal, renewal_afresh], [expected; 2], "round {round}");
        if renewal == Repaired {
            extended.assert_stores_exactly_the_pairs_within_their_limit(&all_pairs, reach, round);
        }
        let sorted = |pairs: &[Pair]| {
            let mut pairs = pairs.to_vec();
            pairs.sort_unstable();
            pairs
        };
        assert_eq!(sorted(&by_extension), sorted(&by_filter), "round {round}");
    }
    assert!(by_extension.len() > first, "the growth made pairs live");
}

/// Local steps as the solver makes them, on a rolled-up sheet falling as a whole while a
/// strip of it swings (several local steps per time step, each starting where the last
/// one's target was, the target moving a little between them, some allowances growing):
/// the live pairs hold every pair that comes within reach (brute force), more than a
/// third of the filters get away without a sweep, and they keep at most half again as
/// many pairs live as a sweep afresh.
#[test]
fn refiltering_since_the_sweep_holds_every_pair_within_reach() {
    let mut rng = Rng::new(17);
    let rolled = TestMesh::rolled(11, 0.02, &mut rng);
    let mesh = rolled.mesh();
    let mut safe = rolled.positions.clone();
    let n = safe.len();
    let (_, every) = brute_force_pairs(&mesh, &safe);
    let reach = 0.012;
    let clamp = vec![1.0; n];
    let (mut cache, mut fresh) = (PairCache::default(), PairCache::default());
    let (mut live, mut afresh) = (Vec::new(), Vec::new());
    let (mut refilters, mut sweeps, mut calls, mut within) = (0, 0, 0, 0);
    for step in 0..8 {
        let fall = Vector3::new(0.0, 0.0, -0.004);
        let swing = |i: usize| if i % 11 < 2 { 0.006 * step as f64 } else { 0.0 };
        let mut target: Vec<_> = safe
            .iter()
            .enumerate()
            .map(|(i, p)| p + fall + Vector3::new(swing(i), 0.0, 0.0))
            .collect();
        let mut allowance = vec![0.0005; n];
        for local in 0..4 {
            if local > 0 {
                safe = target.clone();
            }
            for y in target.iter_mut() {
                *y += rng.vector() * 1e-3;
            }
            if local == 2 {
                for a in allowance.iter_mut().step_by(9) {
                    *a += 0.0005;
                }
            }
            let swept = cache.sweeps();
            let renewal = cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live);
            let swept = cache.sweeps() - swept;
            assert!(swept <= 1, "{swept} sweeps in one filter");
            // A build leaves no sweep to refilter from.
            assert!(
                renewal != Renewal::Built || swept == 1,
                "a build without a sweep"
            );
            let moves = Moves::new(&safe, &target, &clamp, &allowance);
            within += moves
                .assert_live_hold_every_pair_within_reach(&every, &live, reach, &mut rng, calls);
            fresh.sweep.valid = false;
            fresh.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut afresh);
            assert!(
                live.len() <= afresh.len() * 3 / 2 + 10,
                "step {step}, local step {local}: {} live, {} afresh",
                live.len(),
                afresh.len()
            );
            calls += 1;
            sweeps += swept;
            refilters += 1 - swept;
        }
        safe = target;
    }
    assert!(within > 1000, "pairs came within reach: {within}");
    assert!(refilters > calls / 3, "{refilters} refilters of {calls}");
    assert!(sweeps > 2, "{sweeps} sweeps");
}

/// Over a sequence of local steps (small moves that reuse the build, a large one that
/// forces a new build), the live pairs hold every primitive pair a fresh brute-force
/// search finds within `reach` anywhere on the way from the safe positions to the target
/// moved by up to the allowance, and the small moves reuse the build.
#[test]
fn live_pairs_hold_every_pair_that_comes_within_reach() {
    let mut rng = Rng::new(7);
    let n = 100;
    let mut safe = Vec::new();
    for _ in 0..n {
        let centre = rng.vector() * 0.6;
        safe.extend((0..3).map(|_| centre + rng.vector() * 0.08));
    }
    let triangles: Vec<[u32; 3]> = (0..n as u32)
        .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
        .collect();
    let body = vec![0; n];
    let mesh = ContactMesh {
        triangles: &triangles,
        body: &body,
        self_contact: &[true],
    };
    let (all, every) = brute_force_pairs(&mesh, &safe);
    assert_eq!(
        all.len(),
        n * (n - 1) / 2,
        "a soup: every triangle pair may touch"
    );
    let (reach, allowance) = (0.03, vec![0.005; safe.len()]);
    let clamp = vec![1.0; safe.len()];
    let mut cache = PairCache::default();
    let mut live = Vec::new();
    let mut builds = Vec::new();
    let mut within = 0;
    for (k, size) in [0.01, 0.005, 0.005, 0.3, 0.01].into_iter().enumerate() {
        let target: Vec<_> = safe.iter().map(|p| p + rng.vector() * size).collect();
        builds.push(cache.live_pairs(&safe, &target, &allowance, &mesh, reach, &mut live));
        if k < 3 {
            // Before the large move: the bounds are small, so few pairs are live.
            assert!(
                live.len() < every.len() / 10,
                "step {k}: {} live",
                live.len()
            );
        }
        let moves = Moves::new(&safe, &target, &clamp, &allowance);
        within += moves.assert_live_hold_every_pair_within_reach(&every, &live, reach, &mut rng, k);
        safe = target;
    }
    assert!(within > 100, "the scene has pairs within reach: {within}");
    use Renewal::{Built, Kept};
    assert_eq!(builds, [Built, Kept, Kept, Built, Kept]);
    // Another mesh (self-contact off) forces a build and finds nothing.
    let mesh = ContactMesh {
        self_contact: &[false],
        ..mesh
    };
    assert_eq!(
        cache.live_pairs(&safe, &safe, &allowance, &mesh, reach, &mut live),
        Renewal::Built
    );
    assert!(live.is_empty() && cache.candidates() == 0);
}
