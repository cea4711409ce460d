//! A stable counting sort by small integer keys, run in parallel by key ranges: each task owns
//! a range of keys and their places in the output, reads every item and counts (then writes)
//! only its own. Reading is cheap next to the scattered writes, which the ranges share out, and
//! the result does not depend on the number of tasks. The contact pair cache indexes its millions
//! of pairs by vertex with it (see [`crate::geometry::vertex_index`]) and groups them by
//! distance; a serial sort would keep one core busy while the others wait.

use rayon::prelude::*;

/// Writes into `sorted` the values of `items`, `(key, value)` with every key below `keys`, by
/// increasing key and in the order of `items` within a key, and into `start` where each key's
/// values begin: those of key `k` are `sorted[start[k]..start[k + 1]]` (`keys + 1` entries).
pub(crate) fn counting_sort<T: Copy + Send + Sync>(
    items: impl Iterator<Item = (usize, T)> + Clone + Sync,
    keys: usize,
    start: &mut Vec<u32>,
    sorted: &mut Vec<T>,
) {
    let tasks = rayon::current_num_threads().min(keys).max(1);
    // Counts into `start[key + 1]`, by equal key ranges.
    start.clear();
    start.resize(keys + 1, 0);
    let width = keys.div_ceil(tasks).max(1);
    start[1..]
        .par_chunks_mut(width)
        .enumerate()
        .for_each(|(task, counts)| {
            let first = task * width;
            for (key, _) in items.clone() {
                debug_assert!(key < keys, "key {key} of {keys}");
                if let Some(count) = key.checked_sub(first).and_then(|i| counts.get_mut(i)) {
                    *count += 1;
                }
            }
        });
    for key in 0..keys {
        start[key + 1] += start[key];
    }
    // Writes the values, by key ranges of about equal counts.
    sorted.clear();
    let Some((_, fill)) = items.clone().next() else {
        return;
    };
    let total = start[keys];
    sorted.resize(total as usize, fill);
    let bounds = (1..tasks)
        .map(|task| {
            let wanted = (u64::from(total) * task as u64 / tasks as u64) as u32;
            start[..keys].partition_point(|&s| s < wanted)
        })
        .chain([keys]);
    let mut ranges = Vec::with_capacity(tasks);
    let (mut rest, mut from) = (sorted.as_mut_slice(), 0);
    for to in bounds {
        let (values, tail) = rest.split_at_mut((start[to] - start[from]) as usize);
        ranges.push((from..to, values));
        (rest, from) = (tail, to);
    }
    let start = &*start;
    ranges.into_par_iter().for_each(|(range, values)| {
        if range.is_empty() {
            return;
        }
        let base = start[range.start];
        let mut next: Vec<u32> = start[range.clone()].iter().map(|&s| s - base).collect();
        for (key, value) in items.clone() {
            if range.contains(&key) {
                let slot = &mut next[key - range.start];
                values[*slot as usize] = value;
                *slot += 1;
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::Rng;

    /// The result is a stable sort by key, whatever the number of threads: compared with the
    /// standard library's stable sort, on keys crowded into a few (as a pair cache's distances
    /// crowd into a few buckets and live pairs into the vertices where sheets touch), spread
    /// over the rest, with the last keys holding no item.
    #[test]
    fn a_stable_sort_by_key_for_any_thread_count() {
        let mut rng = Rng::new(7);
        let keys = 20_000;
        let items: Vec<(usize, u32)> = (0..240_000)
            .map(|value| {
                let span = if value % 3 == 0 { 40.0 } else { 19_000.0 };
                ((rng.uniform() * span) as usize, value)
            })
            .collect();
        let mut expected = items.clone();
        expected.sort_by_key(|&(key, _)| key);
        for threads in [1, 2, 3, 8] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let (mut start, mut sorted) = (Vec::new(), Vec::new());
            pool.install(|| counting_sort(items.iter().copied(), keys, &mut start, &mut sorted));
            assert_eq!(start.len(), keys + 1);
            let found: Vec<(usize, u32)> = (0..keys)
                .flat_map(|key| {
                    sorted[start[key] as usize..start[key + 1] as usize]
                        .iter()
                        .map(move |&value| (key, value))
                })
                .collect();
            assert_eq!(found, expected, "{threads} threads");
        }
    }

    #[test]
    fn no_items_give_empty_ranges() {
        let (mut start, mut sorted) = (vec![5], vec![1u32, 2]);
        counting_sort(std::iter::empty(), 9000, &mut start, &mut sorted);
        assert_eq!(start, vec![0; 9001]);
        assert!(sorted.is_empty());
    }
}
