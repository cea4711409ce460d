//! Horizon neighbourhoods of a point set in compressed rows (CSR): for every point `i` the
//! points `j != i` with `|x_j - x_i| < delta`, the family of a peridynamic particle (He, Wang
//! and Wu 2017, section 3: the horizon `H_i`).
//!
//! Method: cell lists with a Z-order sort. Every point gets the integer coordinates of its
//! cubic cell (side just above `delta`, [`cells::CellGrid`]); the points are sorted by the
//! Morton code of their cell (ties by index), so each cell's points are contiguous and cells
//! near in space are mostly near in memory; each point's candidates are the points of the 27
//! cells around its own (found in a dense table of the box's cells when it has at most about
//! four per point, else by binary search among the occupied cells' codes, so empty space
//! costs nothing). Runs of whole cells are processed in parallel (rayon), each point's list
//! computed alone, so the result is the same on any number of threads and for any input order.
//!
//! Cost: `O(N log N)` for the sort and `O(N k)` for the tests with `k` candidates per point
//! (`k ~ 27 / (4 pi / 3) ~ 6.4` times the neighbours in a uniform cloud; `O(N)` expected
//! for a bounded density, `O(N^2)` at worst when everything sits in one cell). Memory: the
//! result's `4 (N + 1)` bytes of offsets, `4 B` bytes of indices (`B` bonds) and `4 N` of
//! order; transiently about `60 N` bytes (f64 positions, sort keys, the cell table) and
//! another `8 B` (the lists in sorted order, per run and joined, before they are put back in
//! input order).

mod cells;

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::error::{invalid, Result};
use crate::parallel::{for_each_vertex, GRAIN};
use crate::real::Real;

use cells::{morton, within, CellGrid, MAX_COORD};

/// Horizon neighbourhoods in compressed rows, indexed like the input points.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Horizons {
    /// Where each point's neighbours start in `indices` (`N + 1` entries, from 0).
    pub offsets: Vec<u32>,
    /// The neighbours of point `i`, `indices[offsets[i]..offsets[i + 1]]`, in increasing order.
    pub indices: Vec<u32>,
    /// The points in Z-order of their cells (ties by index): `order[k]` is the `k`-th point. A
    /// caller may store its particles in this order (and renumber the neighbours by its
    /// inverse) so that neighbours sit close in memory.
    pub order: Vec<u32>,
}

impl Horizons {
    /// Largest number of bonds (ordered pairs) a neighbourhood may hold (`u32` offsets).
    pub const MAX_BONDS: u64 = u32::MAX as u64;

    /// Number of points.
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The neighbours of point `i`, increasing.
    pub fn of(&self, i: usize) -> &[u32] {
        &self.indices[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }

    /// Per entry `(i, j)` of `indices` (`j` in `i`'s list), the index in `indices` of its
    /// mirror `(j, i)`, into `out` (resized to the bonds). The lists are symmetric (see
    /// [`find_horizons`]), so every entry has its mirror; a missing one is a broken invariant
    /// of the search and panics naming the pair.
    pub fn mirrors_into(&self, out: &mut Vec<u32>) {
        out.resize(self.indices.len(), 0);
        let mut unit = vec![(); self.len()];
        let (offsets, indices) = (&self.offsets, &self.indices);
        for_each_vertex(offsets, out, &mut unit, &|i, row| {
            let start = offsets[i] as usize;
            for (m, &j) in row.iter_mut().zip(&indices[start..]) {
                let Ok(at) = self.of(j as usize).binary_search(&(i as u32)) else {
                    panic!("neighbour lists not symmetric: {j} in {i}'s list, not {i} in {j}'s");
                };
                *m = offsets[j as usize] + at as u32;
            }
        });
    }
}

/// The horizon neighbourhoods of `positions` (m) for the horizon radius `delta` (m): for every
/// point `i`, every `j != i` with `|x_j - x_i| < delta`, strictly (a pair exactly `delta`
/// apart is not a bond), the distance evaluated in `f64` by [`within`] (symmetric: `j` is a
/// neighbour of `i` exactly when `i` is one of `j`). Coincident points are neighbours.
///
/// Errors (naming the culprit): `delta` not finite or not above `1.5e-154` m, or with `delta^2`
/// overflowing (above `1.3e154` m); a non-finite position (the first such point); more than
/// `u32::MAX - 1` points or more than [`Horizons::MAX_BONDS`] bonds.
pub fn find_horizons<T: Real>(positions: &[Vector3<T>], delta: f64) -> Result<Horizons> {
    let delta2 = delta * delta;
    if !(delta.is_finite() && delta > 0.0 && delta2.is_normal()) {
        return Err(invalid!(
            "the horizon delta must be a finite length with a finite, normal square (1.5e-154 to 1.3e154 m), got {delta}"
        ));
    }
    let n = positions.len();
    if n >= u32::MAX as usize {
        return Err(invalid!("too many points for a neighbourhood: {n}"));
    }
    let x: Vec<[f64; 3]> = positions
        .par_iter()
        .map(|p| [p.x.to_f64(), p.y.to_f64(), p.z.to_f64()])
        .collect();
    if let Some(i) = x
        .par_iter()
        .position_first(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(invalid!("point {i} has a non-finite position {:?}", x[i]));
    }
    if n == 0 {
        return Ok(Horizons {
            offsets: vec![0],
            indices: Vec::new(),
            order: Vec::new(),
        });
    }
    let grid = CellGrid::new(&x, delta);
    let mut keys: Vec<(u128, u32)> = x
        .par_iter()
        .enumerate()
        .map(|(i, p)| (morton(grid.coords(p)), i as u32))
        .collect();
    keys.par_sort_unstable();
    let order: Vec<u32> = keys.iter().map(|k| k.1).collect();
    let sorted: Vec<[f64; 3]> = order.par_iter().map(|&i| x[i as usize]).collect();
    drop(x);
    // The occupied cells: their codes and where their points start in the sorted order.
    let mut codes = Vec::new();
    let mut starts = Vec::new();
    for (k, key) in keys.iter().enumerate() {
        if codes.last() != Some(&key.0) {
            codes.push(key.0);
            starts.push(k as u32);
        }
    }
    starts.push(n as u32);
    drop(keys);
    // Occupied cells by coordinates: a dense table when the box has few cells per point,
    // else binary search among the codes.
    let [dx, dy, dz] = grid.dims;
    let box_cells = dx.saturating_mul(dy).saturating_mul(dz);
    let table = if box_cells <= 4 * n as u64 + 4096 {
        let mut table = vec![u32::MAX; box_cells as usize];
        for (c, &s) in starts[..codes.len()].iter().enumerate() {
            let [x, y, z] = grid.coords(&sorted[s as usize]);
            table[(x + dx * (y + dy * z)) as usize] = c as u32;
        }
        table
    } else {
        Vec::new()
    };
    let cells = Cells {
        grid,
        codes: &codes,
        table: &table,
        starts: &starts,
        sorted: &sorted,
        delta2,
    };

    // One pass over runs of whole cells of about `GRAIN` points (fixed by the cells, not by
    // the threads): each run's counts and lists (input indices, increasing), in sorted order.
    let mut runs = vec![0usize];
    for c in 1..codes.len() {
        if (starts[c] - starts[*runs.last().expect("one run")]) as usize >= GRAIN {
            runs.push(c);
        }
    }
    runs.push(codes.len());
    let parts: Vec<(Vec<u32>, Vec<u32>)> = runs
        .par_windows(2)
        .map(|w| {
            let (mut counts, mut lists) = (Vec::new(), Vec::new());
            for cell in w[0]..w[1] {
                let around = cells.around(cell);
                for r in cells.points(cell) {
                    let first = lists.len();
                    cells.each_neighbour(r, &around, |s| lists.push(order[s]));
                    lists[first..].sort_unstable();
                    counts.push((lists.len() - first) as u32);
                }
            }
            (counts, lists)
        })
        .collect();
    let counts: Vec<u32> = parts.iter().flat_map(|p| p.0.iter().copied()).collect();
    let sorted_offsets = prefix_sum(counts.iter().copied())?;
    let mut sorted_indices = Vec::with_capacity(*sorted_offsets.last().expect("n + 1") as usize);
    for (_, lists) in parts {
        sorted_indices.extend_from_slice(&lists);
    }
    let mut done = vec![(); n];

    // Back to input order.
    let mut rank = vec![0u32; n];
    for (k, &i) in order.iter().enumerate() {
        rank[i as usize] = k as u32;
    }
    let offsets = prefix_sum(rank.iter().map(|&r| counts[r as usize]))?;
    let mut indices = vec![0u32; sorted_indices.len()];
    for_each_vertex(&offsets, &mut indices, &mut done, &|i, list: &mut [u32]| {
        let r = rank[i] as usize;
        list.copy_from_slice(&sorted_indices[sorted_offsets[r] as usize..][..list.len()]);
    });
    Ok(Horizons {
        offsets,
        indices,
        order,
    })
}

/// Offsets from counts, refusing more than [`Horizons::MAX_BONDS`] in all.
fn prefix_sum(counts: impl Iterator<Item = u32>) -> Result<Vec<u32>> {
    let mut offsets = Vec::with_capacity(counts.size_hint().0 + 1);
    let mut total = 0u64;
    offsets.push(0);
    for c in counts {
        total += u64::from(c);
        if total > Horizons::MAX_BONDS {
            return Err(invalid!(
                "the horizons hold more than {} bonds (point pairs within delta): use a smaller delta",
                Horizons::MAX_BONDS
            ));
        }
        offsets.push(total as u32);
    }
    Ok(offsets)
}

/// The occupied cells of a sorted point set.
struct Cells<'a> {
    grid: CellGrid,
    /// Morton codes of the occupied cells, increasing.
    codes: &'a [u128],
    /// Cell index by `x + nx (y + ny z)` (`u32::MAX` where empty), or empty: search `codes`.
    table: &'a [u32],
    /// Cell `c` holds the sorted points `starts[c]..starts[c + 1]`.
    starts: &'a [u32],
    /// Positions in sorted order (m).
    sorted: &'a [[f64; 3]],
    /// `delta^2` (m^2).
    delta2: f64,
}

/// The point ranges (sorted order) of the occupied cells among the 27 around one cell.
struct Around {
    ranges: [(u32, u32); 27],
    count: usize,
}

impl Cells<'_> {
    fn points(&self, cell: usize) -> std::ops::Range<usize> {
        self.starts[cell] as usize..self.starts[cell + 1] as usize
    }

    /// The occupied cells among the 27 around `cell` (itself included).
    fn around(&self, cell: usize) -> Around {
        let c = self.grid.coords(&self.sorted[self.starts[cell] as usize]);
        let mut out = Around {
            ranges: [(0, 0); 27],
            count: 0,
        };
        let near = |v: u64| v.saturating_sub(1)..=(v + 1).min(MAX_COORD);
        for z in near(c[2]) {
            for y in near(c[1]) {
                for x in near(c[0]) {
                    if let Some(k) = self.find([x, y, z]) {
                        out.ranges[out.count] = (self.starts[k], self.starts[k + 1]);
                        out.count += 1;
                    }
                }
            }
        }
        out
    }

    /// The occupied cell at coordinates `c`.
    #[inline]
    fn find(&self, c: [u64; 3]) -> Option<usize> {
        if self.table.is_empty() {
            return self.codes.binary_search(&morton(c)).ok();
        }
        let [nx, ny, nz] = self.grid.dims;
        if c[0] >= nx || c[1] >= ny || c[2] >= nz {
            return None;
        }
        let k = self.table[(c[0] + nx * (c[1] + ny * c[2])) as usize];
        (k != u32::MAX).then_some(k as usize)
    }

    /// Calls `f(s)` for every sorted point `s != r` within the horizon of the sorted point `r`.
    #[inline]
    fn each_neighbour(&self, r: usize, around: &Around, mut f: impl FnMut(usize)) {
        let p = &self.sorted[r];
        for &(a, b) in &around.ranges[..around.count] {
            for s in a as usize..b as usize {
                if s != r && within(p, &self.sorted[s], self.delta2) {
                    f(s);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests;
