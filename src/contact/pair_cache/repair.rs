//! Repairs of a build: a few vertices that strayed beyond their skins get larger ones, and the
//! pairs that the raised limits reach are added, instead of a build afresh.

use rayon::prelude::*;

use super::super::broad_phase::{BroadPhase, ContactMesh};
use super::super::primitive_pairs::close_primitive_pairs;
use super::build::{limit, triangle_box, within_limit};
use super::PairCache;

impl PairCache {
    /// Repairs the build ([`PairCache::repair`]) and tells whether it then covers the
    /// allowances `allowance` (m), its region pairs' motions included.
    pub(super) fn repair_to_cover(
        &mut self,
        mesh: &ContactMesh,
        reach: f64,
        allowance: &[f64],
    ) -> bool {
        self.repair(mesh, reach) && self.regions.hold() && self.covers(allowance)
    }

    /// Repairs the build where the motion still fits every region pair's skin but a few vertices
    /// strayed beyond their own (`dev_i > R_i`, as [`PairCache::covers`] last measured): raises
    /// their skins to `R_i = 2 dev_i + reach / 4` (room for as much stray again, and a quarter
    /// reach) or less, so that every far region pair keeps half its slack
    /// ([`super::super::regions::Regions::most_raised_skin`]), lowers the far region pairs' skins
    /// to match ([`super::super::regions::Regions::raise`]) and adds the primitive pairs that the
    /// raised limits now reach. Such a pair has a side with a raised vertex, so its owner
    /// ([`super::super::primitive_pairs::Owners`]) is a pair of a triangle of that vertex with
    /// another whose box overlaps: the build's box for a triangle without a raised vertex, and
    /// among the triangles of raised vertices (of this repair and the ones before it since the
    /// build) the boxes with their raised padding. It keeps the pairs within their new limit and
    /// not within their old one (the cache holds those already). Returns false where the build must
    /// be made afresh instead: a NaN or infinite stray, one beyond the skin the far region pairs
    /// leave room for, or more raised vertices since the build than [`MOST_RAISED`] allows (then
    /// the skins may have changed and only a build puts them right).
    pub(super) fn repair(&mut self, mesh: &ContactMesh, reach: f64) -> bool {
        let strayed: Vec<u32> = (0..self.skin.len() as u32)
            .filter(|&i| self.deviation[i as usize] > self.skin[i as usize])
            .collect();
        if strayed.is_empty()
            || strayed
                .iter()
                .any(|&i| !self.deviation[i as usize].is_finite())
            || (self.raised.len() + strayed.len()) as f64 > MOST_RAISED * self.skin.len() as f64
        {
            return false;
        }
        let raised_skins: Vec<f64> = strayed
            .iter()
            .map(|&i| {
                let wanted = 2.0 * self.deviation[i as usize] + 0.25 * reach;
                wanted.min(self.regions.most_raised_skin(i as usize))
            })
            .collect();
        if strayed
            .iter()
            .zip(&raised_skins)
            .any(|(&i, r)| r.is_nan() || self.deviation[i as usize] > *r)
        {
            return false;
        }
        let before = self.skin.clone();
        for (&i, &r) in strayed.iter().zip(&raised_skins) {
            self.skin[i as usize] = r;
        }
        self.regions.raise(&self.skin, &strayed, reach);
        self.raised.extend_from_slice(&strayed);
        self.raised.sort_unstable();
        self.raised.dedup();
        let triangles_of = |vertices: &[u32]| {
            let mut of: Vec<u32> = vertices
                .iter()
                .flat_map(|&v| self.owners.of(v).iter().copied())
                .collect();
            of.sort_unstable();
            of.dedup();
            of
        };
        let (fresh, raised) = (triangles_of(&strayed), triangles_of(&self.raised));
        let reference = &self.reference;
        let triangles = mesh.triangles;
        let mut boxes: Vec<(u32, u32)> = fresh
            .par_iter()
            .flat_map_iter(|&t| {
                let t3 = &triangles[t as usize];
                let (lo, hi) = triangle_box(reference, t3, self.padding(t3, reach));
                let mut near = Vec::new();
                self.broad_phase.overlapping(lo, hi, &mut near);
                near.into_iter()
                    .filter(move |&u| mesh.may_touch(t as usize, u as usize))
                    .map(move |u| (t.min(u), t.max(u)))
            })
            .collect();
        let raised_triangles: Vec<[u32; 3]> =
            raised.iter().map(|&t| triangles[t as usize]).collect();
        let raised_body: Vec<u32> = raised.iter().map(|&t| mesh.body[t as usize]).collect();
        let raised_padding: Vec<f64> = raised_triangles
            .iter()
            .map(|t| self.padding(t, reach))
            .collect();
        let among_raised = ContactMesh {
            triangles: &raised_triangles,
            body: &raised_body,
            self_contact: mesh.self_contact,
        };
        boxes.extend(
            BroadPhase::default()
                .candidate_pairs(reference, reference, &among_raised, &raised_padding)
                .iter()
                .map(|&(a, b)| (raised[a as usize], raised[b as usize]))
                .map(|(a, b)| (a.min(b), a.max(b))),
        );
        boxes.par_sort_unstable();
        boxes.dedup();
        let mut chunks = Vec::new();
        let (skin, regions) = (&self.skin, &self.regions);
        close_primitive_pairs(
            mesh,
            Some(&self.owners),
            &boxes,
            reference,
            |p| limit(skin, regions, reach, p),
            |p, d| !within_limit(&before, regions, reach, p, d),
            &mut chunks,
        );
        // Appended after the arranged pairs, which keep their places, their order, their
        // index by vertex and the sweep's record of them: arranging the build's millions
        // afresh would cost a good part of a build for a few hundred pairs.
        self.pairs.extend(chunks.into_iter().flatten());
        self.is_live.resize(self.pairs.len(), false);
        true
    }
}

/// The most vertices, as a share of all, that a build may have raised skins for by
/// [`PairCache::repair`] before it is built afresh instead (a cost trade-off only: a repair
/// costs what the raised vertices' triangles cost, a build what the whole mesh costs, and
/// every raised skin keeps more pairs, each looked at by every filter until the next build).
pub(super) const MOST_RAISED: f64 = 1.0 / 64.0;
