//! The reference motions that the pair cache measures its skins from (see
//! [`super::pair_cache`], "Reuse"): one per *region*, a connected group of at most
//! [`region_size`] vertices of one body (64 on meshes of up to 64K vertices; [`Patches`]),
//! instead of one per body.
//!
//! The reuse argument holds for any vertex groups `G` with any common motions `c_G(tau)`
//! affine in `tau`: with the displacements `u_i(tau)` of vertex `i` from the build's positions
//! `r`, every point of a primitive pair's sides moves relative to the other side by at most
//! `max_{a, b} |u_a - u_b| <= max_a dev_a + max_b dev_b + |c_P - c_Q|`, where `P` and `Q` are the
//! regions whose halos hold the two sides ([`Patches::of_side`]) and `dev_i` bounds `|u_i -
//! c_G|` for every region `G` whose halo holds `i`. Measured from its region's mean, a skirt
//! swinging down as a whole deviates little, where from its body's mean (the whole cloth, its
//! middle at rest on the ball) it deviates by the swing, and body-mean skins keep candidate
//! pairs all over the skirt.
//!
//! What the regions cost instead is a skin per pair of regions, `S_PQ` (m), that
//! `T_PQ = max_{tau} |c_P(tau) - c_Q(tau)|` must stay below until the next build, for *every*
//! pair of regions, also those far apart whose relative motion is large. A build sets
//! `S_PQ = max(K_PQ, gap_PQ - reach - R_P - R_Q)`: `K_PQ` room for the regions' relative
//! motion, `gap_PQ` the distance between the boxes of their halos at `r` and `R_P` the largest
//! vertex skin over the halo of `P`. A primitive pair of the regions `P`, `Q` is then kept
//! when it is closer than `reach + R_A + R_B + S_PQ` (`R_A`, `R_B` the largest skins of its
//! two sides); where the second term of `S_PQ` is the larger (the regions are *far*), that
//! limit is at most `gap_PQ`, below the distance of any such pair, so far regions keep no
//! pair and their skins cost nothing but the check `T_PQ <= S_PQ`, made for all `n^2` region
//! pairs at every filter (one to two thousand regions at most, see [`region_size`]; patches
//! are not always full). `S_PQ` is symmetric to the last bit: a primitive pair's limit reads
//! it with its sides' regions in the pair's order, the box padding in either.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::patches::Patches;
use crate::geometry::bounds::{bounding_box, box_gap, nan_max};

/// The most vertices per region on meshes of up to 64K vertices (more on larger ones, see
/// [`region_size`]): smaller regions follow the motion more closely (smaller skins, fewer
/// cached pairs), more regions cost more region pairs to check (a cost trade-off only; any
/// partition is correct).
pub(super) const REGION_SIZE: usize = 64;

/// About the most regions a mesh is cut into (see [`region_size`]).
const MOST_REGIONS: usize = 1024;

/// The most vertices per region for a mesh of `vertices` vertices: [`REGION_SIZE`], or more
/// where that would give more than about [`MOST_REGIONS`] regions.
pub(super) fn region_size(vertices: usize) -> usize {
    REGION_SIZE.max(vertices.div_ceil(MOST_REGIONS))
}

/// A mesh's regions, their motions since a build, and the skins of their pairs.
#[derive(Default)]
pub(super) struct Regions {
    /// The partition, with halos.
    patches: Patches,
    /// Per vertex, the regions whose halos hold it (compressed rows).
    halos_start: Vec<u32>,
    halos: Vec<u32>,
    /// Per region: the mean `[c^w, c^g]` of the vertex displacements over its halo (m).
    motion: Vec<[Vector3<f64>; 2]>,
    /// `T_PQ` per region pair, row-major (m): `max(|c_P^w - c_Q^w|, |c_P^g - c_Q^g|)`,
    /// infinite where NaN.
    relative_motion: Vec<f64>,
    /// `S_PQ` per region pair, row-major (m): how far `T_PQ` may grow before a build.
    skin: Vec<f64>,
    /// Per region pair: whether its regions are near (`S_PQ = K_PQ`; they may hold cached
    /// pairs).
    may_hold: Vec<bool>,
    /// Per region, at the last build: the box `(lo, hi)` of its halo (m; NaN where a position
    /// is) and `R_P`, the largest vertex skin over its halo (m).
    halo_box: Vec<(Vector3<f64>, Vector3<f64>)>,
    halo_skin: Vec<f64>,
}

impl Regions {
    /// Cuts the mesh of `triangles` (of `vertices` vertices) into regions.
    pub fn new(triangles: &[[u32; 3]], vertices: usize) -> Self {
        let patches = Patches::with_size(triangles, vertices, region_size(vertices));
        let (mut halos_start, mut halos) = (Vec::new(), Vec::new());
        patches.halos_by_vertex(&mut halos_start, &mut halos);
        Regions {
            patches,
            halos_start,
            halos,
            ..Default::default()
        }
    }

    /// The number of regions.
    pub fn count(&self) -> usize {
        self.patches.count()
    }

    /// The regions whose halos hold vertex `v`.
    pub fn holding(&self, v: usize) -> &[u32] {
        &self.halos[self.halos_start[v] as usize..self.halos_start[v + 1] as usize]
    }

    /// Measures each region's common motion, the mean of the displacements `shift`
    /// (`[w_i, g_i]` per vertex, m) over its halo, and `T_PQ` for every region pair.
    pub fn measure(&mut self, shift: &[[Vector3<f64>; 2]]) {
        let patches = &self.patches;
        (0..patches.count())
            .into_par_iter()
            .map(|p| {
                let halo = patches.halo(p);
                let sum = halo.iter().fold([Vector3::zeros(); 2], |[w, g], &v| {
                    let [dw, dg] = shift[v as usize];
                    [w + dw, g + dg]
                });
                sum.map(|s| s / halo.len() as f64)
            })
            .collect_into_vec(&mut self.motion);
        let (motion, n) = (&self.motion, self.count());
        self.relative_motion.resize(n * n, 0.0);
        self.relative_motion
            .par_chunks_mut(n.max(1))
            .enumerate()
            .for_each(|(p, row)| {
                for (q, t) in row.iter_mut().enumerate() {
                    let [pw, pg] = motion[p];
                    let [qw, qg] = motion[q];
                    *t = infinite_if_nan(nan_max((pw - qw).norm(), (pg - qg).norm()));
                }
            });
    }

    /// `max_G max(|w_i - c_G^w|, |g_i - c_G^g|)` over the regions `G` whose halos hold vertex
    /// `i`, with `[w_i, g_i]` = `shift` (m; 0 for a vertex of no triangle, NaN if a figure is).
    pub fn deviation(&self, i: usize, [w, g]: &[Vector3<f64>; 2]) -> f64 {
        self.holding(i).iter().fold(0.0, |d, &p| {
            let [cw, cg] = &self.motion[p as usize];
            nan_max(d, nan_max((w - cw).norm(), (g - cg).norm()))
        })
    }

    /// `max_G |g - c_G^g|` over the regions `G` whose halos hold vertex `i` (m): its motion
    /// to the target relative to its regions.
    pub fn target_deviation(&self, i: usize, g: &Vector3<f64>) -> f64 {
        self.holding(i).iter().fold(0.0, |d, &p| {
            nan_max(d, (g - self.motion[p as usize][1]).norm())
        })
    }

    /// Sets the skins `S_PQ` of a build at `reference` (m) from the vertex skins `skin` (m)
    /// and the motions last measured (module doc): `K_PQ = moves |c_P^g - c_Q^g| + reach / 4`
    /// for two regions (0 for a region with itself), none (infinite) for two regions of one
    /// body without self-contact (`vertex_body`, `self_contact`). Returns per region the
    /// largest `S` over the regions near it (m), which pads its triangles' boxes.
    pub fn set_skins(
        &mut self,
        reference: &[Vector3<f64>],
        skin: &[f64],
        vertex_body: &[u32],
        self_contact: &[bool],
        moves: f64,
        reach: f64,
    ) -> Vec<f64> {
        let patches = &self.patches;
        let n = patches.count();
        // Per region: the box of its halo at `reference`, the largest skin over it, its body.
        let halos: Vec<(Vector3<f64>, Vector3<f64>, f64, u32)> = (0..n)
            .into_par_iter()
            .map(|p| {
                let halo = patches.halo(p);
                let mut largest: f64 = 0.0;
                for &v in halo {
                    largest = nan_max(largest, skin[v as usize]);
                }
                // A position not finite makes the box the whole space: near every region.
                let (lo, hi) = bounding_box(halo.iter().map(|&v| &reference[v as usize]));
                (lo, hi, largest, vertex_body[halo[0] as usize])
            })
            .collect();
        self.halo_box = halos.iter().map(|&(lo, hi, _, _)| (lo, hi)).collect();
        self.halo_skin = halos.iter().map(|&(_, _, r, _)| r).collect();
        let motion = &self.motion;
        let rows: Vec<(Vec<f64>, Vec<bool>)> = (0..n)
            .into_par_iter()
            .map(|p| {
                let (plo, phi, pr, pb) = halos[p];
                (0..n)
                    .map(|q| {
                        let (qlo, qhi, qr, qb) = halos[q];
                        if p == q {
                            return (0.0, true);
                        }
                        if pb == qb && !self_contact[pb as usize] {
                            return (f64::INFINITY, false);
                        }
                        let room = infinite_if_nan(
                            moves * (motion[p][1] - motion[q][1]).norm() + 0.25 * reach,
                        );
                        let gap = box_gap((plo, phi), (qlo, qhi));
                        // A NaN gap counts as near; `pr + qr` first keeps `S` symmetric.
                        let far = far_skin(gap, reach, pr, qr);
                        if far > room {
                            (far, false)
                        } else {
                            (room, true)
                        }
                    })
                    .unzip()
            })
            .collect();
        self.skin.clear();
        self.may_hold.clear();
        for (skin, may_hold) in rows {
            self.skin.extend(skin);
            self.may_hold.extend(may_hold);
        }
        // An infinite `S_PQ` comes from a NaN motion, whose halo's vertices have infinite
        // skins: the boxes of the triangles that own the pairs of that region are infinite
        // already, and the other region's need not be.
        (0..n)
            .map(|p| {
                let row = p * n..(p + 1) * n;
                self.skin[row.clone()]
                    .iter()
                    .zip(&self.may_hold[row])
                    .filter(|(s, &may_hold)| may_hold && s.is_finite())
                    .fold(0.0, |m: f64, (&s, _)| m.max(s))
            })
            .collect()
    }

    /// After the vertex skins `skin` (m) of the vertices `raised` grew (a repair of the build,
    /// see [`super::pair_cache`]): recomputes `R_P` for the regions whose halos hold one and
    /// lowers the skins of their far pairs to `S_PQ = gap_PQ - reach - (R_P + R_Q)`, so that
    /// a far pair's limit stays within the gap and its regions still keep no pair. (A near
    /// pair's skin `K_PQ` does not depend on `R`; [`Regions::hold`] then tells whether the
    /// motion still fits the lowered skins.)
    pub fn raise(&mut self, skin: &[f64], raised: &[u32], reach: f64) {
        let mut touched: Vec<usize> = raised
            .iter()
            .flat_map(|&v| self.holding(v as usize).iter().map(|&p| p as usize))
            .collect();
        touched.sort_unstable();
        touched.dedup();
        for &p in &touched {
            self.halo_skin[p] = self
                .patches
                .halo(p)
                .iter()
                .fold(0.0, |m, &v| nan_max(m, skin[v as usize]));
        }
        let n = self.count();
        for &p in &touched {
            for q in 0..n {
                // Near pairs keep `K_PQ`; an infinite skin is a pair of one body without
                // self-contact, which keeps no pair whatever the motion.
                if self.may_hold[p * n + q] || self.skin[p * n + q] == f64::INFINITY {
                    continue;
                }
                let far = far_skin(
                    box_gap(self.halo_box[p], self.halo_box[q]),
                    reach,
                    self.halo_skin[p],
                    self.halo_skin[q],
                );
                self.skin[p * n + q] = far;
                self.skin[q * n + p] = far;
            }
        }
    }

    /// The largest skin (m) a repair may raise vertex `v`'s to and leave every far pair of
    /// the regions holding it half its slack `S_PQ - T_PQ` (see [`Regions::raise`]): the
    /// least `R_P + (S_PQ - T_PQ) / 2` over those regions `P` and the regions `Q` far from
    /// them (infinite where there is none; NaN where a motion is).
    pub fn most_raised_skin(&self, v: usize) -> f64 {
        let n = self.count();
        self.holding(v)
            .iter()
            .map(|&p| p as usize)
            .flat_map(|p| (0..n).map(move |q| (p, p * n + q)))
            .filter(|&(_, k)| !self.may_hold[k] && self.skin[k] != f64::INFINITY)
            .map(|(p, k)| self.halo_skin[p] + 0.5 * (self.skin[k] - self.relative_motion[k]))
            .fold(f64::INFINITY, |m, x| {
                if m.is_nan() || x.is_nan() {
                    f64::NAN
                } else {
                    m.min(x)
                }
            })
    }

    /// Whether every region pair's `T_PQ` is within its skin `S_PQ` (false where NaN).
    pub fn hold(&self) -> bool {
        self.relative_motion.len() == self.skin.len()
            && self
                .relative_motion
                .par_iter()
                .zip(&self.skin)
                .all(|(t, s)| t <= s)
    }

    /// `max T_PQ` over the near region pairs (m): every cached pair's regions are near.
    pub fn largest_near_motion(&self) -> f64 {
        self.relative_motion
            .par_iter()
            .zip(&self.may_hold)
            .filter(|(_, &may_hold)| may_hold)
            .map(|(&t, _)| t)
            .reduce(|| 0.0, nan_max)
    }

    /// The region of the halo holding the side `side` (the vertices of a vertex, edge or
    /// triangle of the mesh).
    pub fn of_side(&self, side: &[u32]) -> usize {
        self.patches.of_side(side)
    }

    /// `T_PQ` (m) of the regions `p`, `q`.
    pub fn relative_motion(&self, p: usize, q: usize) -> f64 {
        self.relative_motion[p * self.count() + q]
    }

    /// `S_PQ` (m) of the regions `p`, `q`.
    pub fn skin(&self, p: usize, q: usize) -> f64 {
        self.skin[p * self.count() + q]
    }

    /// The largest `S_PQ` (m) over the regions `P` of the vertices of `a` and `Q` of those of
    /// `b`: at least that of any primitive pair of a side of `a` and one of `b`.
    pub fn largest_skin_between(&self, a: &[u32; 3], b: &[u32; 3]) -> f64 {
        let region = |v: u32| self.patches.of_vertex(v as usize);
        a.iter()
            .filter_map(|&u| region(u))
            .flat_map(|p| b.iter().filter_map(move |&v| region(v).map(|q| (p, q))))
            .fold(0.0, |m, (p, q)| nan_max(m, self.skin(p, q)))
    }

    /// The largest of `per_region` over the regions of the vertices `vertices`.
    pub fn largest_of(&self, vertices: &[u32], per_region: &[f64]) -> f64 {
        vertices
            .iter()
            .filter_map(|&v| self.patches.of_vertex(v as usize))
            .fold(0.0, |m, p| nan_max(m, per_region[p]))
    }
}

/// The skin `S_PQ = gap - reach - (R_P + R_Q)` (m) of two far regions whose halo boxes are
/// `gap` (m) apart, with the largest vertex skins `pr`, `qr` (m) over their halos: a pair's
/// limit then stays within the gap. (`pr + qr` first keeps it symmetric to the bit.)
fn far_skin(gap: f64, reach: f64, pr: f64, qr: f64) -> f64 {
    gap - reach - (pr + qr)
}

/// `x`, or infinity where it is NaN (a NaN motion counts as infinitely far).
fn infinite_if_nan(x: f64) -> f64 {
    if x.is_nan() {
        f64::INFINITY
    } else {
        x
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_meshes::{spiral, two_copies};
    use super::*;
    use crate::geometry::distance::tests::Rng;

    /// On two rolled-up grids (two bodies, 0.3 m apart) moving apart with jitter: every
    /// vertex's deviation bounds its distance from the common motion of every region whose
    /// halo holds it, `T` and `S` are symmetric to the bit, a far pair's skin leaves its
    /// regions' halo boxes at least `reach + R_P + R_Q` apart, near pairs exist across the
    /// bodies only when their room exceeds that slack, and a NaN motion breaks `hold`; a
    /// repair's raised skin keeps the far pairs far ([`Regions::most_raised_skin`],
    /// [`Regions::raise`]).
    #[test]
    fn skins_bound_the_motion_and_far_regions_stay_apart() {
        let mut rng = Rng::new(17);
        let (one, triangles) = spiral(12, 0.03, &mut rng);
        let n = one.len() as u32;
        let offset = Vector3::new(0.6, 0.0, 0.0);
        let reference: Vec<_> = one
            .iter()
            .copied()
            .chain(one.iter().map(|p| p + offset))
            .collect();
        let (both, _) = two_copies(&triangles, n);
        let vertex_body: Vec<u32> = (0..2 * n).map(|v| u32::from(v >= n)).collect();
        let mut regions = Regions::new(&both, reference.len());
        assert!(regions.count() >= 4, "{} regions", regions.count());
        let shift: Vec<[Vector3<f64>; 2]> = (0..reference.len())
            .map(|v| {
                let away = if v < n as usize { -0.01 } else { 0.01 };
                [
                    rng.vector() * 0.002,
                    Vector3::new(away, 0.0, 0.0) + rng.vector() * 0.002,
                ]
            })
            .collect();
        regions.measure(&shift);
        for (v, s) in shift.iter().enumerate() {
            let dev = regions.deviation(v, s);
            for &p in regions.holding(v) {
                let [cw, cg] = regions.motion[p as usize];
                assert!((s[0] - cw).norm() <= dev && (s[1] - cg).norm() <= dev);
                assert!((s[1] - cg).norm() <= regions.target_deviation(v, &s[1]));
            }
        }
        let skin: Vec<f64> = (0..reference.len())
            .map(|_| 0.01 + 0.01 * rng.uniform().abs())
            .collect();
        let reach = 0.02;
        let padding = regions.set_skins(&reference, &skin, &vertex_body, &[true, true], 4.0, reach);
        let count = regions.count();
        let halo_box = |regions: &Regions, p: usize| {
            let halo = regions.patches.halo(p);
            let lo = halo.iter().fold(Vector3::repeat(f64::INFINITY), |m, &v| {
                m.inf(&reference[v as usize])
            });
            let hi = halo
                .iter()
                .fold(Vector3::repeat(f64::NEG_INFINITY), |m, &v| {
                    m.sup(&reference[v as usize])
                });
            let largest = halo.iter().fold(0.0, |m: f64, &v| m.max(skin[v as usize]));
            (lo, hi, largest)
        };
        let (mut far, mut near_across) = (0, 0);
        for p in 0..count {
            for q in 0..count {
                assert_eq!(regions.skin(p, q).to_bits(), regions.skin(q, p).to_bits());
                assert_eq!(
                    regions.relative_motion(p, q).to_bits(),
                    regions.relative_motion(q, p).to_bits()
                );
                let (plo, phi, pr) = halo_box(&regions, p);
                let (qlo, qhi, qr) = halo_box(&regions, q);
                let gap = box_gap((plo, phi), (qlo, qhi));
                let pq = p * count + q;
                if regions.may_hold[pq] {
                    assert!(regions.skin(p, q) <= padding[p] && regions.skin(p, q) <= padding[q]);
                    let across = regions.patches.halo(p)[0] < n && regions.patches.halo(q)[0] >= n;
                    near_across += usize::from(across);
                } else {
                    far += 1;
                    assert!(regions.skin(p, q) + reach + pr + qr <= gap + 1e-12);
                }
            }
        }
        assert!(far > 0, "no far region pair");
        assert_eq!(
            near_across, 0,
            "the bodies are 0.3 m apart and move 1 cm per step"
        );
        assert!(regions.hold());

        // A repair raises a vertex's skin as far as its regions' far pairs allow: then every
        // far pair of theirs still leaves its halos `reach + R_P + R_Q + S` apart, keeps half
        // its slack over `T`, stays symmetric, and no skin grew.
        let v = 5;
        let most = regions.most_raised_skin(v);
        assert!(
            most.is_finite() && most > skin[v],
            "{most} over {}",
            skin[v]
        );
        let before = regions.skin.clone();
        let mut raised = skin.clone();
        raised[v] = most;
        regions.raise(&raised, &[v as u32], reach);
        let mut lowered = 0;
        for p in 0..count {
            for q in 0..count {
                let pq = p * count + q;
                assert_eq!(regions.skin(p, q).to_bits(), regions.skin(q, p).to_bits());
                assert!(regions.skin[pq] <= before[pq]);
                lowered += usize::from(regions.skin[pq] < before[pq]);
                if !regions.may_hold[pq] && regions.skin[pq].is_finite() {
                    let (plo, phi, _) = halo_box(&regions, p);
                    let (qlo, qhi, _) = halo_box(&regions, q);
                    let largest = |p: usize| {
                        let halo = regions.patches.halo(p);
                        halo.iter()
                            .fold(0.0, |m: f64, &v| m.max(raised[v as usize]))
                    };
                    let (pr, qr) = (largest(p), largest(q));
                    let gap = box_gap((plo, phi), (qlo, qhi));
                    assert!(regions.skin(p, q) + reach + pr + qr <= gap + 1e-12);
                    let slack = before[pq] - regions.relative_motion(p, q);
                    assert!(
                        regions.skin(p, q) - regions.relative_motion(p, q) >= 0.5 * slack - 1e-12
                    );
                }
            }
        }
        assert!(lowered > 0, "raising the skin lowered no far pair's");
        assert!(regions.hold());

        let mut wild = shift.clone();
        wild[0][1].x = f64::NAN;
        regions.measure(&wild);
        assert!(!regions.hold());
        assert!(regions.most_raised_skin(0).is_nan() || regions.most_raised_skin(0) < skin[0]);
    }
}
