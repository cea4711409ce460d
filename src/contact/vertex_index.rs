//! Per-vertex indices of lists of vertices (triangles, primitive pairs, patch halos): for each
//! vertex, the lists it belongs to, in increasing order, as compressed rows.
//!
//! A counting sort, run in parallel by vertex ranges: each task owns a range of vertices and
//! their rows, reads every incidence and counts (then writes) only its own. Reading is cheap
//! next to the scattered writes, which the ranges share out; the result does not depend on
//! the number of tasks. (Serial, the index of a pair cache, four entries for each of 20M
//! pairs, kept one core busy while the other waited.)

use rayon::prelude::*;

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
/// `v` (of `vertices`, every `v` below it) are `entries[start[v]..start[v + 1]]`, in the order
/// of `incidences` (increasing when the items come in increasing order, each incidence once).
pub(super) fn index_incidences(
    incidences: impl Iterator<Item = (u32, u32)> + Clone + Sync,
    vertices: usize,
    start: &mut Vec<u32>,
    entries: &mut Vec<u32>,
) {
    let tasks = rayon::current_num_threads()
        .min(vertices.div_ceil(MIN_RANGE))
        .max(1);
    // Counts into `start[v + 1]`, by equal vertex ranges (each task reads every incidence).
    start.clear();
    start.resize(vertices + 1, 0);
    let width = vertices.div_ceil(tasks).max(1);
    start[1..]
        .par_chunks_mut(width)
        .enumerate()
        .for_each(|(task, counts)| {
            let first = task * width;
            for (_, v) in incidences.clone() {
                debug_assert!((v as usize) < vertices, "vertex {v} of {vertices}");
                if let Some(count) = (v as usize).checked_sub(first).and_then(|i| counts.get_mut(i))
                {
                    *count += 1;
                }
            }
        });
    for v in 0..vertices {
        start[v + 1] += start[v];
    }
    // Writes the rows, by vertex ranges of about equal entry counts.
    let total = start[vertices];
    entries.clear();
    entries.resize(total as usize, 0);
    let bounds: Vec<usize> = (1..tasks)
        .map(|task| {
            let wanted = (u64::from(total) * task as u64 / tasks as u64) as u32;
            start[..vertices].partition_point(|&s| s < wanted)
        })
        .chain([vertices])
        .collect();
    let mut ranges = Vec::with_capacity(tasks);
    let (mut rest, mut from) = (entries.as_mut_slice(), 0);
    for &to in &bounds {
        let (rows, tail) = rest.split_at_mut((start[to] - start[from]) as usize);
        ranges.push((from..to, rows));
        (rest, from) = (tail, to);
    }
    let start = &*start;
    ranges.into_par_iter().for_each(|(range, rows)| {
        if range.is_empty() {
            return;
        }
        let base = start[range.start];
        let mut next: Vec<u32> = start[range.clone()].iter().map(|&s| s - base).collect();
        for (k, v) in incidences.clone() {
            let v = v as usize;
            if range.contains(&v) {
                let slot = &mut next[v - range.start];
                rows[*slot as usize] = k;
                *slot += 1;
            }
        }
    });
}

/// The fewest vertices a task of [`index_incidences`] owns: below it the extra reads of every
/// incidence by every task cost more than sharing the writes saves.
const MIN_RANGE: usize = 4096;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::Rng;

    /// The rows hold, for every vertex, exactly the items that hold it, in increasing order,
    /// whatever the number of threads: compared with a sort of the incidences.
    #[test]
    fn rows_hold_each_vertexs_items_in_order_for_any_thread_count() {
        let mut rng = Rng::new(7);
        let mut below = |n: u32| (rng.uniform() * f64::from(n)) as u32;
        let vertices = 20_000;
        // Items of four distinct increasing vertices, a third of them crowded into the first
        // 300 vertices (as live pairs crowd where sheets touch), the rest spread up to vertex
        // 19204; the vertices after it hold none.
        let items: Vec<[u32; 4]> = (0..60_000)
            .map(|k| {
                let first = below(if k % 3 == 0 { 300 } else { 19_000 });
                [first, first + 1 + below(3), first + 4, first + 5 + below(200)]
            })
            .collect();
        let mut expected: Vec<(u32, u32)> = items
            .iter()
            .enumerate()
            .flat_map(|(k, item)| item.map(|v| (v, k as u32)))
            .collect();
        expected.sort_unstable();
        for threads in [1, 2, 3, 8] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let (mut start, mut entries) = (Vec::new(), Vec::new());
            pool.install(|| {
                index_by_vertex(items.iter().copied(), vertices, &mut start, &mut entries)
            });
            assert_eq!(start.len(), vertices + 1);
            let found: Vec<(u32, u32)> = (0..vertices)
                .flat_map(|v| {
                    entries[start[v] as usize..start[v + 1] as usize]
                        .iter()
                        .map(move |&k| (v as u32, k))
                })
                .collect();
            assert_eq!(found, expected, "{threads} threads");
        }
    }

    #[test]
    fn no_items_give_empty_rows() {
        let (mut start, mut entries) = (vec![5], vec![1, 2]);
        index_by_vertex(std::iter::empty::<[u32; 3]>(), 9000, &mut start, &mut entries);
        assert_eq!(start, vec![0; 9001]);
        assert!(entries.is_empty());
    }
}
