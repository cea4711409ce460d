//! Patches of a mesh: connected groups of at most [`PATCH_SIZE`] vertices, each with a halo,
//! so that a bound over a primitive pair's vertices can be taken over two patches instead
//! (see [`super::sweep`], where it bounds the fall of a pair's distance bound).
//!
//! A patch is grown breadth-first over the triangles' edges from its first vertex. Its halo
//! holds every vertex of every triangle with a vertex in the patch. Each side of a primitive
//! pair (a vertex, an edge or a triangle of the mesh) lies in one triangle with its first
//! vertex, so the whole side lies in the halo of that vertex's patch ([`Patches::of_side`]).
//! For per-vertex values `delta_i` (m), a patch `P` with centre `m_P` (the mean of `delta`
//! over its halo) and radius `rho_P = max_{j in halo(P)} |delta_j - m_P|` then gives, for
//! every `a` in the halo of `P` and `b` in that of `Q`, `|delta_a - delta_b| <= rho_P +
//! |m_P - m_Q| + rho_Q`. Neighbours move alike, so on a sheet that bends and folds the radii
//! stay far below the spread of `delta` over the whole body.

use nalgebra::Vector3;

use crate::geometry::bounds::nan_max;
use crate::geometry::vertex_index::{index_by_vertex, index_incidences};

/// The most vertices in a patch: smaller patches give tighter radii, larger ones fewer
/// patches to measure at every filter (a cost trade-off only; any partition is correct).
pub(super) const PATCH_SIZE: usize = 32;

/// The patch of a vertex that belongs to no triangle.
const NO_PATCH: u32 = u32::MAX;

/// A partition of a mesh's vertices into patches, and each patch's halo.
#[derive(Default)]
pub(super) struct Patches {
    /// Per vertex: its patch, [`NO_PATCH`] for a vertex of no triangle.
    of_vertex: Vec<u32>,
    /// The halo of patch `p` is `halo[halo_start[p]..halo_start[p + 1]]`, increasing.
    halo_start: Vec<u32>,
    halo: Vec<u32>,
}

impl Patches {
    /// Partitions the vertices of `triangles` (of `vertices` vertices) into patches of at most
    /// [`PATCH_SIZE`] vertices.
    pub fn new(triangles: &[[u32; 3]], vertices: usize) -> Self {
        Self::with_size(triangles, vertices, PATCH_SIZE)
    }

    /// Partitions the vertices of `triangles` (of `vertices` vertices) into patches of at most
    /// `size` vertices.
    pub fn with_size(triangles: &[[u32; 3]], vertices: usize, size: usize) -> Self {
        let (mut start, mut incident) = (Vec::new(), Vec::new());
        index_by_vertex(
            triangles.iter().copied(),
            vertices,
            &mut start,
            &mut incident,
        );
        let around = |v: usize| &incident[start[v] as usize..start[v + 1] as usize];
        let mut of_vertex = vec![NO_PATCH; vertices];
        let mut patches = 0u32;
        let mut queue = Vec::with_capacity(size);
        for seed in 0..vertices {
            if of_vertex[seed] != NO_PATCH || around(seed).is_empty() {
                continue;
            }
            queue.clear();
            queue.push(seed as u32);
            of_vertex[seed] = patches;
            let mut next = 0;
            'grow: while next < queue.len() {
                let v = queue[next] as usize;
                next += 1;
                for &t in around(v) {
                    for &w in &triangles[t as usize] {
                        if queue.len() == size {
                            break 'grow;
                        }
                        if of_vertex[w as usize] == NO_PATCH {
                            of_vertex[w as usize] = patches;
                            queue.push(w);
                        }
                    }
                }
            }
            patches += 1;
        }
        let mut halos = vec![Vec::new(); patches as usize];
        for t in triangles {
            for (k, &v) in t.iter().enumerate() {
                let p = of_vertex[v as usize];
                if t[..k].iter().all(|&u| of_vertex[u as usize] != p) {
                    halos[p as usize].extend_from_slice(t);
                }
            }
        }
        let mut halo_start = Vec::with_capacity(halos.len() + 1);
        let mut halo = Vec::new();
        halo_start.push(0);
        for mut h in halos {
            h.sort_unstable();
            h.dedup();
            halo.extend_from_slice(&h);
            halo_start.push(halo.len() as u32);
        }
        Patches {
            of_vertex,
            halo_start,
            halo,
        }
    }

    /// The number of patches.
    pub fn count(&self) -> usize {
        self.halo_start.len().saturating_sub(1)
    }

    /// The number of vertices partitioned.
    pub fn vertices(&self) -> usize {
        self.of_vertex.len()
    }

    /// The patch in whose halo the whole side `side` (the vertices of a mesh vertex, edge or
    /// triangle) lies: that of its first vertex.
    pub fn of_side(&self, side: &[u32]) -> usize {
        self.of_vertex[side[0] as usize] as usize
    }

    /// The halo of patch `p`.
    pub fn halo(&self, p: usize) -> &[u32] {
        &self.halo[self.halo_start[p] as usize..self.halo_start[p + 1] as usize]
    }

    /// The patch of vertex `v`, `None` for a vertex of no triangle.
    pub fn of_vertex(&self, v: usize) -> Option<usize> {
        let p = self.of_vertex[v];
        (p != NO_PATCH).then_some(p as usize)
    }

    /// Per vertex, the patches whose halos hold it, as compressed rows: those of vertex `v`
    /// are `entries[start[v]..start[v + 1]]`, increasing.
    pub fn halos_by_vertex(&self, start: &mut Vec<u32>, entries: &mut Vec<u32>) {
        index_incidences(
            (0..self.count()).flat_map(|p| self.halo(p).iter().map(move |&v| (p as u32, v))),
            self.vertices(),
            start,
            entries,
        );
    }

    /// The centre `m_P` and radius `rho_P` (module doc) of `delta` over the halo of patch `p`;
    /// NaN radius where a value is NaN.
    pub fn centre_and_radius(
        &self,
        p: usize,
        delta: impl Fn(usize) -> Vector3<f64>,
    ) -> (Vector3<f64>, f64) {
        let halo = self.halo(p);
        let centre = halo
            .iter()
            .map(|&j| delta(j as usize))
            .sum::<Vector3<f64>>()
            / halo.len() as f64;
        let radius = halo
            .iter()
            .map(|&j| (delta(j as usize) - centre).norm())
            .fold(0.0, nan_max);
        (centre, radius)
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_meshes::spiral;
    use super::*;
    use crate::geometry::distance::tests::Rng;

    /// On a rolled sheet: every vertex of a triangle is in a patch of at most
    /// [`PATCH_SIZE`] vertices, every triangle lies in the halo of each of its vertices'
    /// patches (so every side of a primitive pair lies in the halo of [`Patches::of_side`]),
    /// and the patches are mostly full (about `vertices / PATCH_SIZE` of them).
    #[test]
    fn every_triangle_lies_in_the_halos_of_its_vertices_patches() {
        let mut rng = Rng::new(3);
        let (positions, triangles) = spiral(40, 0.01, &mut rng);
        let n = positions.len();
        let patches = Patches::new(&triangles, n + 5);
        let mut size = vec![0; patches.count()];
        for v in 0..n {
            size[patches.of_side(&[v as u32])] += 1;
        }
        assert!(
            size.iter().all(|&s| (1..=PATCH_SIZE).contains(&s)),
            "{size:?}"
        );
        assert!(
            patches.count() <= 2 * n.div_ceil(PATCH_SIZE),
            "{} patches of {n} vertices",
            patches.count()
        );
        assert_eq!(patches.vertices(), n + 5);
        assert!((n..n + 5).all(|v| patches.of_vertex[v] == NO_PATCH));
        for t in &triangles {
            for k in 0..3 {
                let side = [t[k], t[(k + 1) % 3], t[(k + 2) % 3]];
                let halo = patches.halo(patches.of_side(&side));
                assert!(side.iter().all(|v| halo.binary_search(v).is_ok()), "{t:?}");
            }
        }
    }

    /// The module doc's bound holds for random values over the halos of every two patches,
    /// and is tight for a patch pair whose values are two constants.
    #[test]
    fn centres_and_radii_bound_every_difference_across_two_halos() {
        let mut rng = Rng::new(8);
        let (positions, triangles) = spiral(24, 0.01, &mut rng);
        let patches = Patches::new(&triangles, positions.len());
        let delta: Vec<Vector3<f64>> = positions
            .iter()
            .map(|x| x * 0.1 + rng.vector() * 0.01)
            .collect();
        let motion: Vec<_> = (0..patches.count())
            .map(|p| patches.centre_and_radius(p, |j| delta[j]))
            .collect();
        for p in 0..patches.count() {
            for q in 0..patches.count() {
                let ((mp, rp), (mq, rq)) = (motion[p], motion[q]);
                let bound = rp + (mp - mq).norm() + rq;
                for &a in patches.halo(p) {
                    for &b in patches.halo(q) {
                        let d = (delta[a as usize] - delta[b as usize]).norm();
                        assert!(d <= bound + 1e-12, "{d} > {bound}");
                    }
                }
            }
        }
        let (m, r) = patches.centre_and_radius(0, |_| Vector3::new(1.0, 2.0, 3.0));
        assert!(r < 1e-12 && (m - Vector3::new(1.0, 2.0, 3.0)).norm() < 1e-12);
        let (_, r) = patches.centre_and_radius(0, |_| Vector3::new(f64::NAN, 0.0, 0.0));
        assert!(r.is_nan());
    }
}
