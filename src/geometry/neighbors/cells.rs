//! The cell grid behind [`super::find_horizons`]: cubic cells of side slightly above the horizon
//! `delta`, identified by integer coordinates and ordered by their Z-order (Morton) code.
//!
//! Cell coordinates are computed in `f64` as `floor((x / 2 - lo / 2) / (c / 2))` with `lo` the
//! lowest corner of the points' box and `c` the cell side: halving first keeps every
//! intermediate finite even for coordinates near `f64::MAX`. The side `c = delta (1 + eta)`
//! exceeds `delta` by a margin `eta` that covers the round-off of that computation, so two
//! points that the horizon test ([`within`]) accepts always lie in the same or adjacent cells,
//! and searching the 27 cells around a point's own is exact (see [`CellGrid::new`]).
//!
//! Coordinates have at most [`AXIS_BITS`] bits per axis; a box more than `2^41` horizons wide
//! gets cells wider than `delta` (still exact, fewer cells, more candidates per cell) instead of
//! overflowing.

use rayon::prelude::*;

/// Bits of a cell coordinate along one axis: Morton codes take `3 * 42 = 126` bits.
pub(super) const AXIS_BITS: u32 = 42;

/// The largest cell coordinate along an axis.
pub(super) const MAX_COORD: u64 = (1 << AXIS_BITS) - 1;

/// Whether `|a - b| < sqrt(delta2)`, evaluated as `dx^2 + dy^2 + dz^2 < delta2` in this exact
/// order (so the relation is symmetric and the same in every caller, including the tests'
/// brute force).
#[inline]
pub(crate) fn within(a: &[f64; 3], b: &[f64; 3], delta2: f64) -> bool {
    let (dx, dy, dz) = (a[0] - b[0], a[1] - b[1], a[2] - b[2]);
    dx * dx + dy * dy + dz * dz < delta2
}

/// Cubic cells over a point set's bounding box.
#[derive(Debug, Clone, Copy)]
pub(super) struct CellGrid {
    /// Half the lowest corner of the points' box (m).
    lo_half: [f64; 3],
    /// Half the cell side (m).
    cell_half: f64,
    /// Cells along each axis (the highest point's coordinates plus one).
    pub dims: [u64; 3],
}

impl CellGrid {
    /// Cells for the finite points `x` and a horizon `delta` (m, finite, > 0).
    ///
    /// Round-off: with `u = (x/2 - lo/2) / (c/2)` and `U = max u <= min(E / delta, 2^41)`
    /// (`E` the box's largest side), the computed `u` is within `U eps` of the exact one
    /// (`eps = 2^-52`), so differences of computed `u` are within `2 U eps` of exact ones. A pair
    /// accepted by [`within`] is at most `delta (1 + 2 eps)` apart along each axis, i.e. at most
    /// `(1 + 2 eps) / (1 + eta)` cells exactly; with `eta = 1e-9 + 8 eps (U + 1)` the computed
    /// difference stays below 1, so the floors differ by at most 1.
    pub(super) fn new(x: &[[f64; 3]], delta: f64) -> Self {
        let (lo, hi) = x
            .par_iter()
            .fold(
                || ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
                |(lo, hi), p| {
                    (
                        [0, 1, 2].map(|k| lo[k].min(p[k])),
                        [0, 1, 2].map(|k| hi[k].max(p[k])),
                    )
                },
            )
            .reduce(
                || ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
                |(a, b), (c, d)| {
                    (
                        [0, 1, 2].map(|k| a[k].min(c[k])),
                        [0, 1, 2].map(|k| b[k].max(d[k])),
                    )
                },
            );
        let lo_half = lo.map(|v| 0.5 * v);
        let half_extent = (0..3)
            .map(|k| 0.5 * hi[k] - lo_half[k])
            .fold(0.0f64, f64::max);
        // Cells of `delta` across the box (the half extent over the half horizon), capped
        // where the cells get widened anyway.
        let across = (half_extent / (0.5 * delta)).min((1u64 << (AXIS_BITS + 1)) as f64);
        let eta = 1e-9 + 8.0 * f64::EPSILON * (across + 1.0);
        let widest = half_extent / (1u64 << (AXIS_BITS - 1)) as f64;
        let mut grid = Self {
            lo_half,
            cell_half: (0.5 * delta * (1.0 + eta)).max(widest),
            dims: [0; 3],
        };
        // Cell coordinates grow with the position, so the highest corner has the highest.
        grid.dims = grid.coords(&hi).map(|c| c + 1);
        grid
    }

    /// Cell coordinates of the point `p` of the set, each in `0..=MAX_COORD`.
    #[inline]
    pub(super) fn coords(&self, p: &[f64; 3]) -> [u64; 3] {
        // `as u64` saturates; the clamp keeps round-off at the far end in range.
        [0, 1, 2].map(|k| {
            (((0.5 * p[k] - self.lo_half[k]) / self.cell_half).floor() as u64).min(MAX_COORD)
        })
    }
}

/// The low 21 bits of `v` spread to every third bit.
#[inline]
fn spread21(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// The Z-order (Morton) code of cell coordinates below `2^42`: bits interleaved x, y, z from
/// the lowest, so cells close in space are mostly close in code order.
#[inline]
pub(super) fn morton(c: [u64; 3]) -> u128 {
    let part = |shift: u32| {
        let [x, y, z] = c.map(|v| spread21(v >> shift));
        u128::from(x | y << 1 | z << 2)
    };
    part(21) << 63 | part(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_interleaves_the_bits_of_each_axis() {
        assert_eq!(morton([1, 0, 0]), 1);
        assert_eq!(morton([0, 1, 0]), 2);
        assert_eq!(morton([0, 0, 1]), 4);
        assert_eq!(morton([3, 0, 0]), 0b1001);
        assert_eq!(morton([1 << 21, 0, 0]), 1 << 63);
        assert_eq!(morton([0, 0, 1 << 41]), 1 << 125);
        let all = morton([MAX_COORD; 3]);
        assert_eq!(all, (1u128 << 126) - 1);
        // A naive interleave agrees on arbitrary coordinates.
        let c = [0x0021_2345_6789_u64, 0x003f_fff0_0001, 0x0010_f0f0_f0f0];
        let mut naive = 0u128;
        for bit in 0..AXIS_BITS {
            for (k, v) in c.iter().enumerate() {
                naive |= u128::from((v >> bit) & 1) << (3 * bit + k as u32);
            }
        }
        assert_eq!(morton(c), naive);
    }

    #[test]
    fn coordinates_stay_in_range_for_extreme_boxes() {
        let x = [[-f64::MAX, 0.0, 1.0], [f64::MAX, 1e-300, -1.0]];
        let grid = CellGrid::new(&x, 1e-6);
        assert!(grid.cell_half.is_finite() && grid.cell_half > 0.0);
        for p in &x {
            assert!(grid.coords(p).iter().all(|&c| c <= MAX_COORD));
        }
        assert_eq!(grid.coords(&x[0])[0], 0);
    }
}
