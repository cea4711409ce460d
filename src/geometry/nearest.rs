//! The distance from every point of a set to its nearest other point, by a k-d tree: the
//! points split at the median of their box's longest side, recursively, so building takes
//! `O(n log n)` and a query about `O(log n)` whatever the points' spacing (a cell list needs a
//! cell size, which is what a particle body's nearest distances are checked against:
//! [`crate::particles::Particles::new`]).

use nalgebra::Vector3;
use rayon::prelude::*;

/// Points of a range searched one by one rather than split further.
const LEAF: usize = 8;

/// Ranges at least this long are split on two threads.
const PARALLEL_SPLIT: usize = 1 << 14;

/// A k-d tree over `points` in the order `order`: a range `lo..hi` longer than [`LEAF`] is
/// split at its middle `mid = lo + (hi - lo) / 2` along the axis `axis[mid]`, the points
/// `lo..mid` at or below point `order[mid]`'s coordinate on that axis, `mid + 1..hi` at or
/// above it.
struct Tree<'a> {
    points: &'a [Vector3<f64>],
    order: Vec<u32>,
    axis: Vec<u8>,
}

impl<'a> Tree<'a> {
    fn new(points: &'a [Vector3<f64>]) -> Self {
        let mut order: Vec<u32> = (0..points.len() as u32).collect();
        let mut axis = vec![0; points.len()];
        split(points, &mut order, &mut axis);
        Self {
            points,
            order,
            axis,
        }
    }

    /// The squared distance (m^2) from point `i` to its nearest other point in `lo..hi`, or
    /// `best` if none is nearer.
    fn nearest(&self, i: usize, lo: usize, hi: usize, mut best: f64) -> f64 {
        let q = &self.points[i];
        let mut try_point = |j: u32| {
            if j as usize != i {
                best = best.min((self.points[j as usize] - q).norm_squared());
            }
        };
        if hi - lo <= LEAF {
            self.order[lo..hi].iter().for_each(|&j| try_point(j));
            return best;
        }
        let mid = lo + (hi - lo) / 2;
        try_point(self.order[mid]);
        let axis = usize::from(self.axis[mid]);
        let gap = q[axis] - self.points[self.order[mid] as usize][axis];
        let (near, far) = if gap < 0.0 {
            ((lo, mid), (mid + 1, hi))
        } else {
            ((mid + 1, hi), (lo, mid))
        };
        best = self.nearest(i, near.0, near.1, best);
        // Every point on the far side is at least |gap| away along `axis`.
        if gap * gap < best {
            best = self.nearest(i, far.0, far.1, best);
        }
        best
    }
}

/// Orders `order` (with its `axis` labels) into the k-d tree of [`Tree`].
fn split(points: &[Vector3<f64>], order: &mut [u32], axis: &mut [u8]) {
    if order.len() <= LEAF {
        return;
    }
    let (mut lo, mut hi) = (points[order[0] as usize], points[order[0] as usize]);
    for &i in order.iter() {
        lo = lo.inf(&points[i as usize]);
        hi = hi.sup(&points[i as usize]);
    }
    let longest = (hi - lo).imax();
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&i, &j| {
        points[i as usize][longest].total_cmp(&points[j as usize][longest])
    });
    axis[mid] = longest as u8;
    let (below, rest) = order.split_at_mut(mid);
    let (axis_below, axis_rest) = axis.split_at_mut(mid);
    let (above, axis_above) = (&mut rest[1..], &mut axis_rest[1..]);
    if below.len() >= PARALLEL_SPLIT {
        rayon::join(
            || split(points, below, axis_below),
            || split(points, above, axis_above),
        );
    } else {
        split(points, below, axis_below);
        split(points, above, axis_above);
    }
}

/// The distance (m) from every `every`-th of `points` (m, finite; the points 0, `every`,
/// `2 every`, ...; `every` >= 1) to its nearest other point of them all: 0 where another point
/// shares its position, infinite for a lone point.
pub fn nearest_distances(points: &[Vector3<f64>], every: usize) -> Vec<f64> {
    let tree = Tree::new(points);
    (0..points.len())
        .into_par_iter()
        .step_by(every.max(1))
        .map(|i| tree.nearest(i, 0, points.len(), f64::INFINITY).sqrt())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::nearest_distances;
    use crate::test_rng::Rng;
    use nalgebra::Vector3;

    /// Scattered points (a cloud, a plane, a line, with repeats): the tree's nearest distances
    /// equal those of the search over every pair, bit for bit.
    #[test]
    fn matches_the_search_over_every_pair() {
        let mut rng = Rng::new(7);
        let cloud: Vec<Vector3<f64>> = (0..700).map(|_| rng.vector()).collect();
        let plane: Vec<Vector3<f64>> = cloud.iter().map(|p| Vector3::new(p.x, p.y, 0.5)).collect();
        let line: Vec<Vector3<f64>> = (0..300)
            .map(|k| Vector3::new(0.01 * f64::from(k % 150), 0.0, 0.0))
            .collect();
        for points in [cloud, plane, line] {
            let brute: Vec<f64> = (0..points.len())
                .map(|i| {
                    (0..points.len())
                        .filter(|&j| j != i)
                        .map(|j| (points[j] - points[i]).norm_squared())
                        .fold(f64::INFINITY, f64::min)
                        .sqrt()
                })
                .collect();
            assert_eq!(nearest_distances(&points, 1), brute);
            let every_third: Vec<f64> = brute.iter().copied().step_by(3).collect();
            assert_eq!(nearest_distances(&points, 3), every_third);
        }
        assert_eq!(
            nearest_distances(&[Vector3::zeros()], 1),
            vec![f64::INFINITY]
        );
    }
}
