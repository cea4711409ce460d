//! Deterministic data parallelism over vertices.

/// Vertices handled by one task; large enough to amortise scheduling, small enough to balance.
const GRAIN: usize = 512;

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
    for_each_range(offsets, 1, bonds, out, &|first, bonds, out: &mut [R]| {
        let base = offsets[first] as usize;
        for (k, slot) in out.iter_mut().enumerate() {
            let i = first + k;
            let range = offsets[i] as usize - base..offsets[i + 1] as usize - base;
            *slot = f(i, &mut bonds[range]);
        }
    });
}

/// Calls `f(first, bonds, out)` in parallel on disjoint ranges of consecutive vertices that
/// together cover `out`: the range starting at vertex `first` gets its own `out` entries and
/// its vertices' bonds (CSR `offsets`, as in [`for_each_vertex`]). Every range but the last
/// starts at a multiple of `align` (> 0) and holds a multiple of `align` vertices, so aligned
/// groups of `align` vertices are never split; the ranges do not depend on the number of
/// threads.
pub fn for_each_range<B, R, F>(offsets: &[u32], align: usize, bonds: &mut [B], out: &mut [R], f: &F)
where
    B: Send,
    R: Send,
    F: Fn(usize, &mut [B], &mut [R]) + Sync,
{
    assert!(align > 0, "ranges must be aligned to at least one vertex");
    split(offsets, align, 0, bonds, out, f);
}

fn split<B, R, F>(
    offsets: &[u32],
    align: usize,
    first: usize,
    bonds: &mut [B],
    out: &mut [R],
    f: &F,
) where
    B: Send,
    R: Send,
    F: Fn(usize, &mut [B], &mut [R]) + Sync,
{
    let mid = (out.len() / 2) / align * align;
    if out.len() <= GRAIN || mid == 0 {
        f(first, bonds, out);
        return;
    }
    let base = offsets[first] as usize;
    let (bonds_lo, bonds_hi) = bonds.split_at_mut(offsets[first + mid] as usize - base);
    let (out_lo, out_hi) = out.split_at_mut(mid);
    rayon::join(
        || split(offsets, align, first, bonds_lo, out_lo, f),
        || split(offsets, align, first + mid, bonds_hi, out_hi, f),
    );
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
