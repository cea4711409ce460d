//! Per-vertex indices of lists of vertices (triangles, primitive pairs, patch halos): for each
//! vertex, the lists it belongs to, in increasing order, as compressed rows.

use super::counting_sort::counting_sort;

/// Fills `start` and `entries` so that the items holding vertex `v` (of `vertices`) are
/// `entries[start[v]..start[v + 1]]`, in increasing order: a counting sort of `items` (each
/// with distinct vertices).
pub(super) fn index_by_vertex<const K: usize>(
    items: impl Iterator<Item = [u32; K]> + Clone + Sync,
    vertices: usize,
    start: &mut Vec<u32>,
    entries: &mut Vec<u32>,
) {
    index_incidences(
        items
            .enumerate()
            .flat_map(|(k, item)| item.map(|v| (k as u32, v))),
        vertices,
        start,
        entries,
    );
}

/// Fills `start` and `entries` so that the items `k` of the incidences `(k, v)` with vertex
/// `v` (of `vertices`) are `entries[start[v]..start[v + 1]]`, in the order of `incidences`
/// (increasing when the items come in increasing order, each incidence once).
pub(super) fn index_incidences(
    incidences: impl Iterator<Item = (u32, u32)> + Clone + Sync,
    vertices: usize,
    start: &mut Vec<u32>,
    entries: &mut Vec<u32>,
) {
    counting_sort(
        incidences.map(|(k, v)| (v as usize, k)),
        vertices,
        start,
        entries,
    );
}
