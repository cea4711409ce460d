//! Vertex neighbourhoods in compressed sparse row (CSR) form, with the index of every bond's
//! reverse, so that forces can be gathered per vertex without atomics.

use crate::error::{invalid, Result};
use crate::mesh::TriangleMesh;

/// The k-ring neighbourhood of every vertex of a mesh: vertex `i`'s neighbours are
/// `indices[offsets[i]..offsets[i + 1]]`, sorted ascending. The relation is symmetric, and
/// `reverse[b]` is the bond `j -> i` for the bond `b = i -> j`.
#[derive(Debug, Clone, PartialEq)]
pub struct Neighborhood {
    pub offsets: Vec<u32>,
    pub indices: Vec<u32>,
    pub reverse: Vec<u32>,
}

impl Neighborhood {
    /// Most bonds a neighbourhood may hold (about 4 GB of rest data in f64): a k that large
    /// is a mistake, and is refused rather than exhausting memory.
    pub const MAX_BONDS: usize = 100_000_000;

    /// Vertices within `k` mesh edges of each vertex (k = 1: the 1-ring of the paper). Fails
    /// when the neighbourhoods would hold more than [`Self::MAX_BONDS`] bonds.
    pub fn k_ring(mesh: &TriangleMesh, k: usize) -> Result<Self> {
        let n = mesh.num_vertices();
        let mut adjacency: Vec<Vec<u32>> = vec![Vec::new(); n];
        for tri in mesh.triangles() {
            for a in 0..3 {
                let (i, j) = (tri[a], tri[(a + 1) % 3]);
                adjacency[i as usize].push(j);
                adjacency[j as usize].push(i);
            }
        }
        for list in &mut adjacency {
            list.sort_unstable();
            list.dedup();
        }
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0u32);
        let mut indices = Vec::new();
        let mut depth = vec![usize::MAX; n];
        let mut frontier = Vec::new();
        let mut reached = Vec::new();
        for start in 0..n {
            depth[start] = 0;
            frontier.clear();
            frontier.push(start as u32);
            reached.clear();
            for level in 1..=k {
                let mut next = Vec::new();
                for &v in &frontier {
                    for &w in &adjacency[v as usize] {
                        if depth[w as usize] == usize::MAX {
                            depth[w as usize] = level;
                            next.push(w);
                            reached.push(w);
                        }
                    }
                }
                frontier = next;
            }
            reached.sort_unstable();
            indices.extend_from_slice(&reached);
            if indices.len() > Self::MAX_BONDS {
                return Err(invalid!(
                    "neighbors={k} gives more than {} bonds (vertex {start} alone has {}); use a smaller k",
                    Self::MAX_BONDS,
                    reached.len()
                ));
            }
            offsets.push(indices.len() as u32);
            depth[start] = usize::MAX;
            for &w in &reached {
                depth[w as usize] = usize::MAX;
            }
        }
        let reverse = reverse_bonds(&offsets, &indices);
        Ok(Self {
            offsets,
            indices,
            reverse,
        })
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    /// True when there are no vertices.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Bond index range of vertex `i`.
    pub fn bonds(&self, i: usize) -> std::ops::Range<usize> {
        self.offsets[i] as usize..self.offsets[i + 1] as usize
    }

    /// Neighbours of vertex `i`.
    pub fn of(&self, i: usize) -> &[u32] {
        &self.indices[self.bonds(i)]
    }
}

/// For each bond `i -> j`, the index of `j -> i` (neighbour lists are sorted, so a binary
/// search finds it).
fn reverse_bonds(offsets: &[u32], indices: &[u32]) -> Vec<u32> {
    let mut reverse = vec![0u32; indices.len()];
    for i in 0..offsets.len() - 1 {
        for b in offsets[i] as usize..offsets[i + 1] as usize {
            let j = indices[b] as usize;
            let row = &indices[offsets[j] as usize..offsets[j + 1] as usize];
            let pos = row
                .binary_search(&(i as u32))
                .expect("k-ring neighbourhoods are symmetric by construction");
            reverse[b] = offsets[j] + pos as u32;
        }
    }
    reverse
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 3x3 vertex grid, two triangles per cell with the same diagonal.
    fn grid3() -> TriangleMesh {
        let mut v = Vec::new();
        for j in 0..3 {
            for i in 0..3 {
                v.push([i as f64, j as f64, 0.0]);
            }
        }
        let mut t = Vec::new();
        for j in 0..2i64 {
            for i in 0..2i64 {
                let a = j * 3 + i;
                t.push([a, a + 1, a + 4]);
                t.push([a, a + 4, a + 3]);
            }
        }
        TriangleMesh::new(v, t).unwrap()
    }

    #[test]
    fn one_ring_of_the_centre_is_its_six_mesh_neighbours() {
        let nb = Neighborhood::k_ring(&grid3(), 1).unwrap();
        assert_eq!(nb.of(4), &[0, 1, 3, 5, 7, 8]);
        assert_eq!(nb.of(0), &[1, 3, 4]);
    }

    #[test]
    fn two_ring_reaches_everything_in_a_small_grid_and_reverse_is_an_involution() {
        let nb = Neighborhood::k_ring(&grid3(), 2).unwrap();
        assert_eq!(nb.of(4).len(), 8);
        assert_eq!(nb.of(0), &[1, 2, 3, 4, 5, 6, 7, 8]);
        for i in 0..nb.len() {
            for b in nb.bonds(i) {
                let r = nb.reverse[b] as usize;
                assert_eq!(nb.indices[r] as usize, i);
                assert_eq!(nb.reverse[r] as usize, b);
            }
        }
    }
}
