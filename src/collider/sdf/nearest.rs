//! Nearest triangle of a mesh to a point: a bounding volume hierarchy (axis-aligned boxes,
//! median split along the longest axis of the triangle centroids, up to [`LEAF_SIZE`]
//! triangles per leaf) searched branch-and-bound, nearer child first, pruning every box that
//! lies farther than the best triangle found so far. A query costs about `O(log m)` exact
//! point-triangle distances for `m` triangles.

use nalgebra::Vector3;

use crate::geometry::distance::{point_triangle_closest, Closest};

/// Triangles per leaf.
const LEAF_SIZE: usize = 4;

/// A box of the tree: an inner node (`count == 0`, children `self + 1` and `first`) or a leaf
/// holding `order[first..first + count]`.
#[derive(Debug, Clone, Copy)]
struct Node {
    lo: Vector3<f64>,
    hi: Vector3<f64>,
    first: u32,
    count: u32,
}

impl Node {
    /// Squared distance (m^2) from `p` to the box (0 inside).
    #[inline]
    fn distance_squared(&self, p: &Vector3<f64>) -> f64 {
        let outside = (self.lo - p).sup(&(p - self.hi)).sup(&Vector3::zeros());
        outside.norm_squared()
    }
}

/// The closest point of a mesh to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nearest {
    /// Index of the triangle holding the closest point.
    pub triangle: usize,
    /// Barycentric coordinates of the closest point on that triangle (exact zeros on its
    /// edges and vertices).
    pub weights: [f64; 3],
    /// `p - closest point` (m).
    pub separation: Vector3<f64>,
}

impl Nearest {
    /// From a point-triangle query on `triangle` (weights `[1, -w_0, -w_1, -w_2]`).
    fn of(triangle: usize, closest: &Closest) -> Self {
        let w = closest.weights;
        Self {
            triangle,
            weights: [-w[1], -w[2], -w[3]],
            separation: closest.separation,
        }
    }
}

/// Bounding volume hierarchy over the triangles of a mesh.
#[derive(Debug, Clone)]
pub struct TriangleTree {
    nodes: Vec<Node>,
    order: Vec<u32>,
    corners: Vec<[Vector3<f64>; 3]>,
}

impl TriangleTree {
    /// The tree of triangles given by their corners (m); at least one triangle.
    pub fn new(corners: Vec<[Vector3<f64>; 3]>) -> Self {
        assert!(!corners.is_empty(), "a triangle tree needs triangles");
        let centroids: Vec<Vector3<f64>> =
            corners.iter().map(|c| (c[0] + c[1] + c[2]) / 3.0).collect();
        let mut order: Vec<u32> = (0..corners.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * corners.len() / LEAF_SIZE + 1);
        build(&mut nodes, &mut order, 0, &corners, &centroids);
        Self {
            nodes,
            order,
            corners,
        }
    }

    /// The closest point of the mesh to `p`, starting from the candidate triangle `hint` (the
    /// nearest triangle of a neighbouring point, usually nearest here too or nearly): its
    /// distance bounds the search from the start, which then opens few boxes.
    pub fn nearest_from(&self, p: &Vector3<f64>, hint: usize) -> Nearest {
        let [a, b, c] = &self.corners[hint];
        let closest = point_triangle_closest(p, a, b, c);
        let mut best = closest.distance_squared();
        let mut found = Nearest::of(hint, &closest);
        let mut stack: Vec<(u32, f64)> = Vec::with_capacity(64);
        stack.push((0, self.nodes[0].distance_squared(p)));
        while let Some((index, reach)) = stack.pop() {
            if reach >= best {
                continue;
            }
            let node = &self.nodes[index as usize];
            if node.count > 0 {
                let range = node.first as usize..(node.first + node.count) as usize;
                for &t in &self.order[range] {
                    let [a, b, c] = &self.corners[t as usize];
                    let closest = point_triangle_closest(p, a, b, c);
                    let d2 = closest.distance_squared();
                    if d2 < best {
                        best = d2;
                        found = Nearest::of(t as usize, &closest);
                    }
                }
            } else {
                let (left, right) = (index + 1, node.first);
                let dl = self.nodes[left as usize].distance_squared(p);
                let dr = self.nodes[right as usize].distance_squared(p);
                // Pushed last, popped first: the nearer child.
                if dl < dr {
                    stack.push((right, dr));
                    stack.push((left, dl));
                } else {
                    stack.push((left, dl));
                    stack.push((right, dr));
                }
            }
        }
        found
    }
}

/// Appends the subtree of `order[offset..offset + len]` (with `order` that slice) to `nodes`.
fn build(
    nodes: &mut Vec<Node>,
    order: &mut [u32],
    offset: usize,
    corners: &[[Vector3<f64>; 3]],
    centroids: &[Vector3<f64>],
) {
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    let mut clo = lo;
    let mut chi = hi;
    for &t in order.iter() {
        for c in &corners[t as usize] {
            lo = lo.inf(c);
            hi = hi.sup(c);
        }
        clo = clo.inf(&centroids[t as usize]);
        chi = chi.sup(&centroids[t as usize]);
    }
    let me = nodes.len();
    nodes.push(Node {
        lo,
        hi,
        first: offset as u32,
        count: order.len() as u32,
    });
    if order.len() <= LEAF_SIZE {
        return;
    }
    let axis = (chi - clo).imax();
    let half = order.len() / 2;
    order.select_nth_unstable_by(half, |a, b| {
        centroids[*a as usize][axis].total_cmp(&centroids[*b as usize][axis])
    });
    let (left, right) = order.split_at_mut(half);
    build(nodes, left, offset, corners, centroids);
    let right_index = nodes.len();
    build(nodes, right, offset + half, corners, centroids);
    nodes[me].first = right_index as u32;
    nodes[me].count = 0;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::distance::point_triangle_distance_squared;
    use crate::test_rng::Rng;

    /// The tree finds the same nearest distance as checking every triangle, for random
    /// triangles and points near and far.
    #[test]
    fn tree_agrees_with_brute_force() {
        let mut rng = Rng::new(11);
        let mut next = move || rng.uniform();
        let corners: Vec<[Vector3<f64>; 3]> = (0..500)
            .map(|_| {
                let c = Vector3::new(next(), next(), next());
                let mut e = || c + Vector3::new(next(), next(), next()) * 0.1;
                [e(), e(), e()]
            })
            .collect();
        let tree = TriangleTree::new(corners.clone());
        for _ in 0..300 {
            let p = Vector3::new(next(), next(), next()) * 1.5;
            let brute = corners
                .iter()
                .map(|[a, b, c]| point_triangle_distance_squared(&p, a, b, c))
                .fold(f64::INFINITY, f64::min);
            let found = tree.nearest_from(&p, 0);
            let hinted = tree.nearest_from(&p, 123);
            assert!((hinted.separation.norm_squared() - brute).abs() <= 1e-14 * (1.0 + brute));
            assert!((found.separation.norm_squared() - brute).abs() <= 1e-14 * (1.0 + brute));
            let [a, b, c] = &corners[found.triangle];
            let w = found.weights;
            let on = a * w[0] + b * w[1] + c * w[2];
            assert!((p - on - found.separation).norm() < 1e-14);
        }
    }
}
