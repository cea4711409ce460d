//! Deterministic data parallelism over vertices.

use rayon::prelude::*;

/// Vertices handled by one task; large enough to amortise scheduling, small enough to balance.
pub const GRAIN: usize = 512;

/// Calls `f(i, bonds_of_i)` for every vertex `i` in parallel and stores its result in `out[i]`.
///
/// `bonds` is split along the CSR `offsets` (vertex `i` owns `offsets[i]..offsets[i + 1]`), so
/// every call writes only its own bonds: safe, allocation-free, and the result does not depend
/// on the number of threads.
pub fn for_each_vertex<B, R, F>(offsets: &[u32], bonds: &mut [B], out: &mut [R], f: &F)
where
    B: Send,
    R: Send,
    F: Fn(usize, &mut [B]) -> R + Sync,
{
    let n = out.len();
    split(
        offsets,
        &|b| b,
        0..n,
        bonds,
        out,
        &|_, first, bonds, out: &mut [R]| {
            let base = offsets[first] as usize;
            for (k, slot) in out.iter_mut().enumerate() {
                let i = first + k;
                let range = offsets[i] as usize - base..offsets[i + 1] as usize - base;
                *slot = f(i, &mut bonds[range]);
            }
        },
    );
}

/// Calls `f(blocks, first, bonds, out)` in parallel on disjoint runs of consecutive blocks of
/// vertices: block `b` is vertices `starts[b]..starts[b + 1]` (`starts` ascending from 0 to
/// `out.len()`); the run `blocks` starts at vertex `first` and gets its vertices' `out`
/// entries and bonds (CSR `offsets`). Blocks are never split; the runs do not depend on the
/// number of threads.
pub fn for_each_block<B, R, F>(
    offsets: &[u32],
    starts: &[u32],
    bonds: &mut [B],
    out: &mut [R],
    f: &F,
) where
    B: Send,
    R: Send,
    F: Fn(std::ops::Range<usize>, usize, &mut [B], &mut [R]) + Sync,
{
    assert_eq!(
        starts.last().map(|&s| s as usize),
        Some(out.len()),
        "blocks must cover the vertices"
    );
    split(
        offsets,
        &|b| starts[b] as usize,
        0..starts.len() - 1,
        bonds,
        out,
        f,
    );
}

/// Splits the blocks `blocks` (block `b` starts at vertex `start(b)`; the run's first vertex is
/// `start(blocks.start)`) in halves until a run holds at most [`GRAIN`] vertices or one block.
fn split<B, R, S, F>(
    offsets: &[u32],
    start: &S,
    blocks: std::ops::Range<usize>,
    bonds: &mut [B],
    out: &mut [R],
    f: &F,
) where
    B: Send,
    R: Send,
    S: Fn(usize) -> usize + Sync,
    F: Fn(std::ops::Range<usize>, usize, &mut [B], &mut [R]) + Sync,
{
    let first = start(blocks.start);
    if out.len() <= GRAIN || blocks.len() <= 1 {
        f(blocks, first, bonds, out);
        return;
    }
    let mid_block = blocks.start + blocks.len() / 2;
    let mid = start(mid_block) - first;
    let base = offsets[first] as usize;
    let (bonds_lo, bonds_hi) = bonds.split_at_mut(offsets[first + mid] as usize - base);
    let (out_lo, out_hi) = out.split_at_mut(mid);
    rayon::join(
        || split(offsets, start, blocks.start..mid_block, bonds_lo, out_lo, f),
        || split(offsets, start, mid_block..blocks.end, bonds_hi, out_hi, f),
    );
}

/// Terms per partial sum of [`chunked_sum`]: fixed, so that the sums do not depend on the
/// number of threads.
const SUM_CHUNK: usize = 4096;

/// `sum_i term(i)` for `i < n`, summed in fixed chunks combined in order, whose partial sums
/// go to the reused `scratch`: the same sum for any thread count (a rayon `reduce` groups its
/// additions as the work happens to be split, which varies with the thread count and with
/// work stealing).
pub(crate) fn chunked_sum(
    n: usize,
    scratch: &mut Vec<f64>,
    term: impl Fn(usize) -> f64 + Sync,
) -> f64 {
    (0..n.div_ceil(SUM_CHUNK))
        .into_par_iter()
        .map(|c| {
            (c * SUM_CHUNK..((c + 1) * SUM_CHUNK).min(n))
                .map(&term)
                .sum::<f64>()
        })
        .collect_into_vec(scratch);
    scratch.iter().sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_vertex_writes_exactly_its_own_bonds() {
        let n = 3000;
        let offsets: Vec<u32> = (0..=n as u32)
            .scan(0, |acc, i| {
                let start = *acc;
                *acc += i % 4;
                Some(start)
            })
            .collect();
        let mut bonds = vec![usize::MAX; *offsets.last().unwrap() as usize];
        let mut out = vec![0usize; n];
        for_each_vertex(&offsets, &mut bonds, &mut out, &|i, b: &mut [usize]| {
            b.iter_mut().for_each(|x| *x = i);
            b.len()
        });
        for i in 0..n {
            let r = offsets[i] as usize..offsets[i + 1] as usize;
            assert_eq!(out[i], r.len());
            assert!(bonds[r].iter().all(|&x| x == i));
        }
    }
}
