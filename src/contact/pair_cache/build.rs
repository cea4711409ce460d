//! A build of the pair lists at the reference positions: the vertex and region skins, the
//! broad phase over inflated triangle boxes, and the primitive pairs within their limits.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::super::broad_phase::ContactMesh;
use super::super::patches::Patches;
use super::super::primitive_pairs::{close_primitive_pairs, Pair};
use super::super::regions::Regions;
use super::super::sweep::NO_BODY;
use super::{below, PairCache};
use crate::geometry::bounds::{bounding_box, box_gap, nan_max};
use crate::geometry::vertex_index::index_by_vertex;

impl PairCache {
    /// Builds the lists at `r = safe`. The skins are a cost trade-off only (any that pass the
    /// reuse test are correct): per vertex `R_i = q_i + reach / 4` with `q_i` the largest
    /// `M max_G |g_j - c_G^g| + A_j` (over the regions `G` whose halos hold `j`) within
    /// [`SKIN_RINGS`] triangle rings of `i`, and per region pair the `S_PQ` of
    /// [`Regions::set_skins`] with `K_PQ = M |c_P^g - c_Q^g| + reach / 4`, `M` =
    /// [`SKIN_MOVES`]: room for several more moves like the build's (for the vertex and the
    /// ones around it, so that motion spreading through a sheet does not force a build at
    /// once) and a quarter reach of slow drift. A vertex moving with the vertices around it
    /// keeps a small skin. A larger skin is reused longer but keeps more pairs (all those
    /// within the limit on a sheet: their number grows with the square of `limit / l`, `l` the
    /// edge length), each filtered at every local step, and memory is what limits the largest
    /// scenes: `M` = 4 trades a few more builds for a smaller cache and cheaper filters.
    pub(super) fn build(
        &mut self,
        safe: &[Vector3<f64>],
        target: &[Vector3<f64>],
        allowance: &[f64],
        mesh: &ContactMesh,
        reach: f64,
    ) {
        if self.patches.vertices() != safe.len() || self.triangles != mesh.triangles {
            self.patches = Patches::new(mesh.triangles, safe.len());
            self.regions = Regions::new(mesh.triangles, safe.len());
        }
        self.triangles.clear();
        self.triangles.extend_from_slice(mesh.triangles);
        self.body.clear();
        self.body.extend_from_slice(mesh.body);
        self.self_contact.clear();
        self.self_contact.extend_from_slice(mesh.self_contact);
        self.vertex_body.clear();
        self.vertex_body.resize(safe.len(), NO_BODY);
        for (t, &b) in mesh.triangles.iter().zip(mesh.body) {
            for &v in t {
                self.vertex_body[v as usize] = b;
            }
        }
        self.reference.clear();
        self.reference.extend_from_slice(safe);
        self.bodies = mesh.self_contact.len();
        self.built_reach = reach;
        self.measure_motion(safe, target);
        let finite = |v: f64| if v.is_nan() { f64::INFINITY } else { v };
        let (shift, vertex_body, regions) = (&self.shift, &self.vertex_body, &self.regions);
        (0..safe.len())
            .into_par_iter()
            .map(|i| match vertex_body[i] {
                NO_BODY => 0.0,
                _ => finite(SKIN_MOVES * regions.target_deviation(i, &shift[i][1]) + allowance[i]),
            })
            .collect_into_vec(&mut self.skin);
        spread_over_rings(&mut self.skin, mesh.triangles, SKIN_RINGS);
        self.skin.iter_mut().for_each(|r| *r += 0.25 * reach);
        self.near_skin = self.regions.set_skins(
            &self.reference,
            &self.skin,
            &self.vertex_body,
            mesh.self_contact,
            SKIN_MOVES,
            reach,
        );
        self.raised.clear();

        // NaN distances (NaN positions) are kept.
        let padding: Vec<f64> = mesh
            .triangles
            .par_iter()
            .map(|t| self.padding(t, reach))
            .collect();
        let (reference, skin, regions) = (&self.reference, &self.skin, &self.regions);
        let boxes = self
            .broad_phase
            .candidate_pairs(reference, reference, mesh, &padding);
        self.box_pairs = boxes.len();
        // The padding takes the largest skin of the regions near a triangle's; the limits of
        // a triangle pair's primitive pairs are at most `reach + (max R + max R) + max S_PQ`
        // over its own vertices' regions (`S` is symmetric and a primitive pair's regions are
        // those of a vertex of either triangle; the sums are in the order of [`limit`], so
        // rounding keeps the bound above every limit): where its triangles' boxes are farther
        // apart, none of them is kept, and their 15 distances are not worth computing.
        let triangles = mesh.triangles;
        let boxes: Vec<(u32, u32)> = boxes
            .par_iter()
            .copied()
            .filter(|&(i, j)| {
                let (a, b) = (&triangles[i as usize], &triangles[j as usize]);
                let largest = |t: &[u32; 3]| t.iter().map(|&v| skin[v as usize]).fold(0.0, nan_max);
                let bound = reach + (largest(a) + largest(b)) + regions.largest_skin_between(a, b);
                below(box_distance(reference, a, b), bound)
            })
            .collect();
        // A primitive pair beyond the limit cannot come within `reach` before the next build.
        self.owners.index(mesh, safe.len());
        let mut chunks = Vec::new();
        self.candidates = close_primitive_pairs(
            mesh,
            Some(&self.owners),
            &boxes,
            reference,
            |p| limit(skin, regions, reach, p),
            |_, _| true,
            &mut chunks,
        );
        self.order
            .arrange(&chunks, |&(_, d)| f64::from(d), &mut self.pairs);
        self.arranged = self.pairs.len();
        drop(chunks);
        self.index_pairs();
    }

    /// The padding (m) of the triangle `t`'s box at the reference positions: its largest
    /// vertex skin, half the reach and half the largest region pair skin of its vertices'
    /// regions (a primitive pair's regions are those of its sides' first vertices), so that
    /// the boxes of two triangles overlap wherever two of their primitives are within their
    /// limit.
    pub(super) fn padding(&self, t: &[u32; 3], reach: f64) -> f64 {
        t.iter().map(|&v| self.skin[v as usize]).fold(0.0, f64::max)
            + 0.5 * reach
            + 0.5 * self.regions.largest_of(t, &self.near_skin)
    }

    /// Indexes the build's pairs by vertex (the four vertices of a pair are distinct: its
    /// primitives share none) and marks none of them live, none swept (nor grouped).
    fn index_pairs(&mut self) {
        index_by_vertex(
            self.pairs.iter().map(|(pair, _)| pair.v),
            self.reference.len(),
            &mut self.by_vertex_start,
            &mut self.by_vertex,
        );
        self.is_live.clear();
        self.is_live.resize(self.pairs.len(), false);
        self.flagged = 0;
        self.sweep.valid = false;
        self.patch_groups.clear();
    }
}

/// The limit of a build (m) for the primitive pair `p`: `reach + max_A R + max_B R + S_PQ`,
/// with the vertex skins `skin` (m) over its sides `A`, `B` and the skin `S_PQ` (m) of their
/// regions `P`, `Q` (see [`super::super::regions`]).
pub(super) fn limit(skin: &[f64], regions: &Regions, reach: f64, p: &Pair) -> f64 {
    let (a, b) = p.sides();
    reach + p.spread(skin) + regions.skin(regions.of_side(a), regions.of_side(b))
}

/// Whether a build with the skins `skin` and `regions` keeps the primitive pair `p` at the
/// distance `d` (m): closer than its [`limit`], or NaN.
pub(super) fn within_limit(skin: &[f64], regions: &Regions, reach: f64, p: &Pair, d: f64) -> bool {
    d < limit(skin, regions, reach, p) || d.is_nan()
}

/// The distance (m) between the bounding boxes of the triangles `a` and `b` at `x` (m): at
/// most the distance between any of their points, 0 where a position is not finite (see
/// [`bounding_box`]).
fn box_distance(x: &[Vector3<f64>], a: &[u32; 3], b: &[u32; 3]) -> f64 {
    let bounds = |t: &[u32; 3]| bounding_box(t.iter().map(|&v| &x[v as usize]));
    box_gap(bounds(a), bounds(b))
}

/// The box `(lo, hi)` of the triangle `t` at `x` (m), inflated by `pad` (m) on every side
/// (the whole space where a position is not finite, see [`bounding_box`]).
pub(super) fn triangle_box(
    x: &[Vector3<f64>],
    t: &[u32; 3],
    pad: f64,
) -> (Vector3<f64>, Vector3<f64>) {
    let (lo, hi) = bounding_box(t.iter().map(|&v| &x[v as usize]));
    let pad = Vector3::repeat(pad);
    (lo - pad, hi + pad)
}

/// Triangle rings over which a build spreads each vertex's skin (see [`PairCache::build`]).
pub(super) const SKIN_RINGS: usize = 2;

/// How many times its motion in the build's global step a build gives each vertex as skin
/// (see [`PairCache::build`]).
pub(super) const SKIN_MOVES: f64 = 4.0;

/// Replaces each value by the largest within `rings` triangle rings of its vertex (NaN counts
/// as the largest).
fn spread_over_rings(values: &mut [f64], triangles: &[[u32; 3]], rings: usize) {
    for _ in 0..rings {
        let largest: Vec<f64> = triangles
            .par_iter()
            .map(|t| t.iter().map(|&v| values[v as usize]).fold(0.0, nan_max))
            .collect();
        for (t, m) in triangles.iter().zip(largest) {
            for &v in t {
                values[v as usize] = nan_max(values[v as usize], m);
            }
        }
    }
}
