//! Per-vertex indices of lists of vertices (triangles, primitive pairs, patch halos): for each
//! vertex, the lists it belongs to, in increasing order, as compressed rows.

use crate::geometry::counting_sort::counting_sort;

/// Fills `start` and `entries` so that the items holding vertex `v` (of `vertices`) are
/// `entries[start[v]..start[v + 1]]`, in increasing order: a counting sort of `items` (each
/// with distinct vertices).
pub(crate) fn index_by_vertex<const K: usize>(
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
pub(crate) fn index_incidences(
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::Rng;

    /// Every vertex's row holds exactly the items that hold it, in increasing order (compared
    /// with a sort of the incidences), and the vertices of no item have empty rows.
    #[test]
    fn rows_hold_each_vertexs_items_in_increasing_order() {
        let mut rng = Rng::new(3);
        let mut below = |n: u32| (rng.uniform() * f64::from(n)) as u32;
        let vertices = 5000;
        let items: Vec<[u32; 3]> = (0..20_000)
            .map(|_| {
                let first = below(4000);
                [first + 2 + below(50), first, first + 1]
            })
            .collect();
        let mut expected: Vec<(u32, u32)> = items
            .iter()
            .enumerate()
            .flat_map(|(k, item)| item.map(|v| (v, k as u32)))
            .collect();
        expected.sort_unstable();
        let (mut start, mut entries) = (Vec::new(), Vec::new());
        index_by_vertex(items.iter().copied(), vertices, &mut start, &mut entries);
        let found: Vec<(u32, u32)> = (0..vertices)
            .flat_map(|v| {
                entries[start[v] as usize..start[v + 1] as usize]
                    .iter()
                    .map(move |&k| (v as u32, k))
            })
            .collect();
        assert_eq!(found, expected);
        assert_eq!(
            start[4100], start[vertices],
            "no item holds a vertex past 4050"
        );
    }
}
