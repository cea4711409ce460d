//! Per-vertex indices of lists of vertices (triangles, primitive pairs): for each vertex, the
//! lists it belongs to, in increasing order, as compressed rows.

/// Fills `start` and `entries` so that the items holding vertex `v` (of `vertices`) are
/// `entries[start[v]..start[v + 1]]`, in increasing order: a counting sort of `items` (each
/// with distinct vertices).
pub(super) fn index_by_vertex<const K: usize>(
    items: impl Iterator<Item = [u32; K]> + Clone,
    vertices: usize,
    start: &mut Vec<u32>,
    entries: &mut Vec<u32>,
) {
    start.clear();
    start.resize(vertices + 1, 0);
    let mut count = 0;
    for item in items.clone() {
        for v in item {
            start[v as usize + 1] += 1;
        }
        count += K;
    }
    for v in 0..vertices {
        start[v + 1] += start[v];
    }
    let mut next = start.clone();
    entries.clear();
    entries.resize(count, 0);
    for (k, item) in items.enumerate() {
        for v in item {
            entries[next[v as usize] as usize] = k as u32;
            next[v as usize] += 1;
        }
    }
}
