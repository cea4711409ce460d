//! What a sweep reads of each vertex for the bound from the build ([`PairCache::sweep`]:
//! the pair's distance at the reference positions less the moves since), packed into 32
//! bytes: the displacements `[w_i, g_i]` (m) in `f32`, the allowance `A_i` (m) rounded up to
//! `f32`, and the vertex's patch. A sweep looks at every near pair of the build (0.66M on
//! the 120 x 120 cloth), each at four vertices scattered over the mesh (the pairs are in
//! order of distance, not of place): the `f64` displacements alone (48 bytes a vertex) do not
//! fit a core's cache at 14K vertices, the packed records (one cache line at most) do.
//!
//! The bound stays a lower bound of the pair's distance on the path. Rounding each
//! coordinate to the nearest `f32` moves it by at most `2^-24` of its size, so a vertex's
//! packed displacement lies within `sqrt(3) 2^-24 M` (m) of the exact one, with `M` the
//! largest coordinate of any displacement, and a difference of two within twice that:
//! [`PackedShift::bound`] is the same bound ([`Pair::relative_distance_bound_of`]) with the
//! largest relative move taken [`MARGIN`]` (M + f32::MIN_POSITIVE)` (m) larger
//! (`f32::MIN_POSITIVE` covers the absolute error of subnormal values), and rounding the
//! allowances up only lowers it (the subtractions and the sum after the move round
//! monotonically, so the packed bound is at most the exact one). A NaN or
//! infinite displacement gives a NaN or infinite `M`, and then every pair a NaN or minus
//! infinite bound (the exact bound only the pairs of that vertex): the sweep then takes the
//! fresh bounds, slower and as correct.
//!
//! [`PairCache::sweep`]: super::PairCache

use nalgebra::Vector3;
use rayon::prelude::*;

use super::super::patches::Patches;
use super::super::primitive_pairs::Pair;
use crate::geometry::bounds::{nan_max, round_down};

/// `2^-20`: above the `2 sqrt(3) 2^-24` (about `2^-21.2`) of the module doc, with room for
/// the round-off of the difference itself (at most `2^-52` of it).
const MARGIN: f64 = 1.0 / (1u64 << 20) as f64;

/// One vertex as a sweep reads it (module doc).
#[derive(Clone, Copy, Default)]
#[repr(C, align(32))]
struct PackedVertex {
    /// `[w_i, g_i]` rounded to the nearest `f32` (m).
    shift: [[f32; 3]; 2],
    /// `A_i` rounded up to `f32` (m).
    allowance: f32,
    /// The vertex's patch ([`Patches::of_side`] of the vertex alone).
    patch: u32,
}

/// The packed vertices of the last [`PackedShift::pack`] and its margin.
#[derive(Default)]
pub(super) struct PackedShift {
    vertices: Vec<PackedVertex>,
    /// `MARGIN (M + f32::MIN_POSITIVE)` (m), NaN or infinite where `M` is.
    margin: f64,
}

impl PackedShift {
    /// Packs the displacements `shift` (`[w_i, g_i]`, m), the allowances `allowance` (m)
    /// and the vertices' patches in `patches`.
    pub fn pack(&mut self, shift: &[[Vector3<f64>; 2]], allowance: &[f64], patches: &Patches) {
        shift
            .par_iter()
            .zip(allowance)
            .enumerate()
            .map(|(i, (s, &a))| PackedVertex {
                shift: s.map(|d| [d.x as f32, d.y as f32, d.z as f32]),
                allowance: -round_down(-a),
                patch: patches.of_side(&[i as u32]) as u32,
            })
            .collect_into_vec(&mut self.vertices);
        let largest = shift
            .par_iter()
            .map(|s| {
                s.iter()
                    .flat_map(|d| d.iter())
                    .fold(0.0, |m, c| nan_max(m, c.abs()))
            })
            .reduce(|| 0.0, nan_max);
        self.margin = MARGIN * (largest + f64::from(f32::MIN_POSITIVE));
    }

    /// A lower bound (m) of [`Pair::relative_distance_bound`] of `pair` with `distance` (m),
    /// the displacements and the allowances last packed (module doc).
    pub fn bound(&self, pair: &Pair, distance: f64) -> f64 {
        let vertex = |i: usize| &self.vertices[i];
        pair.relative_distance_bound_of(
            distance,
            self.margin,
            |i| vertex(i).shift.map(|s| Vector3::from(s.map(f64::from))),
            |i| f64::from(vertex(i).allowance),
        )
    }

    /// The patch of the side `side` ([`Patches::of_side`]) as packed.
    pub fn patch(&self, side: &[u32]) -> u32 {
        self.vertices[side[0] as usize].patch
    }
}

#[cfg(test)]
mod tests {
    use super::super::super::test_meshes::spiral;
    use super::*;
    use crate::test_rng::Rng;

    /// Displacements and allowances of sizes from nanometres to metres, on a rolled sheet's
    /// vertex-triangle and edge-edge pairs: the packed bound is never above the exact one,
    /// and below it by at most a few `2^-20` of the largest displacement; the packed patch is
    /// the patch. A NaN displacement makes every packed bound NaN (the exact one only of the
    /// pairs of its vertex). Displacements subnormal in `f32` (1e-40 m) keep the bound
    /// below the exact one within the margin's absolute term; displacements beyond `f32`'s
    /// range (1e39 m) make the packed bound NaN or minus infinity, never above the exact one.
    #[test]
    fn the_packed_bound_is_a_lower_bound_within_its_margin() {
        let mut rng = Rng::new(8);
        let (x, triangles) = spiral(30, 0.01, &mut rng);
        let n = x.len();
        let patches = Patches::new(&triangles, n);
        let mut packed = PackedShift::default();
        let mut below = 0;
        for round in 0..42 {
            let scale = match round {
                40 => 1e-40,
                41 => 1e39,
                _ => 10f64.powi(round % 10 - 9),
            };
            let mut shift: Vec<[Vector3<f64>; 2]> = (0..n)
                .map(|_| [rng.vector() * scale, rng.vector() * scale])
                .collect();
            let allowance: Vec<f64> = (0..n).map(|_| rng.uniform().abs() * scale).collect();
            let poisoned = round == 39;
            if poisoned {
                shift[7][1].y = f64::NAN;
            }
            packed.pack(&shift, &allowance, &patches);
            let largest = shift
                .iter()
                .flat_map(|s| s.iter().flat_map(|d| d.iter()))
                .fold(0.0_f64, |m, c| m.max(c.abs()));
            for _ in 0..500 {
                let k = (rng.uniform().abs() * 1e6) as usize % (triangles.len() - 40);
                let (s, t) = (triangles[k], triangles[k + 20 + k % 17]);
                let edge_edge = rng.uniform() > 0.0;
                let v = if edge_edge {
                    [s[0], s[1], t[1], t[2]]
                } else {
                    [s[2], t[0], t[1], t[2]]
                };
                let pair = Pair { edge_edge, v };
                let distance = rng.uniform().abs() * 4.0 * scale;
                let exact = pair.relative_distance_bound(distance, &shift, &allowance);
                let bound = packed.bound(&pair, distance);
                let (a, b) = pair.sides();
                for side in [a, b] {
                    assert_eq!(packed.patch(side), patches.of_side(side) as u32);
                }
                if poisoned {
                    // One NaN anywhere makes `M`, and so every packed bound, NaN.
                    assert!(bound.is_nan(), "{bound}");
                    assert_eq!(exact.is_nan(), pair.v.contains(&7), "{exact}");
                    continue;
                }
                assert_ne!(
                    bound.partial_cmp(&exact),
                    Some(std::cmp::Ordering::Greater),
                    "{bound} above {exact}"
                );
                if round == 41 {
                    assert!(!bound.is_finite(), "{bound}");
                    continue;
                }
                assert!(
                    exact - bound <= 4.0 * MARGIN * (largest + f64::from(f32::MIN_POSITIVE)),
                    "{bound} against {exact}"
                );
                below += usize::from(bound < exact);
            }
        }
        assert!(below > 10_000, "{below}");
    }
}
