//! Items grouped by a distance (m) into [`BUCKETS`] buckets, NaN first, so that every item
//! closer than a horizon lies among the leading ones: a counting sort where a full sort is
//! not needed. (The broad phase's cache orders its primitive pairs so that a filter looks only
//! at those near enough; a full sort of millions of pairs by distance would cost a good part
//! of a build.)
//!
//! A bucket is the distance's `f32` sign, exponent and first seven mantissa bits: 128 buckets
//! to a factor of two, from 2^-24 m (and everything below) to 2^8 m (and everything above),
//! so a horizon's bucket holds items up to 1/128 beyond it, however far the largest distance
//! lies. Rounding to `f32` is
//! monotone, so an item closer than the horizon is in its bucket or an earlier one.

use crate::geometry::counting_sort::counting_sort;

/// Buckets of an order: the NaN bucket, then 32 factors of two from 2^-24 m.
pub(super) const BUCKETS: usize = 1 + 32 * 128;

/// The bucket key (the top 16 bits of an `f32`) of 2^-24, the first past the NaN bucket.
const LOWEST_KEY: u32 = (127 - 24) << 7;

/// Where the buckets of the last [`DistanceOrder::arrange`] begin and end.
#[derive(Default)]
pub(super) struct DistanceOrder {
    /// Per bucket `b`: its items are `start[b]..start[b + 1]` (`BUCKETS + 1` entries).
    start: Vec<u32>,
}

impl DistanceOrder {
    /// Writes into `items` the items of `chunks` (in order) by the bucket of
    /// `distance(item)` (m), keeping their order within a bucket (reusing its allocation),
    /// and records where the buckets begin and end.
    pub fn arrange<T: Copy + Send + Sync>(
        &mut self,
        chunks: &[Vec<T>],
        distance: impl Fn(&T) -> f64 + Sync,
        items: &mut Vec<T>,
    ) {
        counting_sort(
            chunks
                .iter()
                .flatten()
                .map(|item| (bucket(distance(item)), *item)),
            BUCKETS,
            &mut self.start,
            items,
        );
    }

    /// How many of the leading items hold every item closer than `horizon` (m) or NaN
    /// (all of them for an infinite or NaN horizon): the ends of whole buckets.
    pub fn within(&self, horizon: f64) -> usize {
        match self.start.last() {
            None => 0,
            Some(&all) if !horizon.is_finite() => all as usize,
            Some(_) => self.start[bucket(horizon) + 1] as usize,
        }
    }
}

/// The bucket of the distance `d` (m): NaN first, then by the `f32` bits of `d` (module doc).
fn bucket(d: f64) -> usize {
    if d.is_nan() {
        0
    } else {
        let key = (d.max(0.0) as f32).to_bits() >> 16;
        1 + (key.saturating_sub(LOWEST_KEY) as usize).min(BUCKETS - 2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::distance::tests::Rng;

    /// Random distances (some NaN, some far beyond the rest): the arranged items are the same
    /// items, each bucket keeps their order, and for any horizon the leading
    /// [`DistanceOrder::within`] hold every item closer than it or NaN, and few others.
    #[test]
    fn the_leading_items_hold_every_item_closer_than_the_horizon() {
        let mut rng = Rng::new(4);
        let n = 200_000;
        let mut items: Vec<(u32, f64)> = (0..n)
            .map(|k| {
                let d = match k % 97 {
                    0 => f64::NAN,
                    1 => 1e3,
                    _ => rng.uniform().abs() * 0.02,
                };
                (k, d)
            })
            .collect();
        let before = items.clone();
        // Uneven chunks, one of them empty.
        let chunks: Vec<Vec<(u32, f64)>> = [0, 7, 7, 5000, 123_456, n as usize]
            .windows(2)
            .map(|w| items[w[0]..w[1]].to_vec())
            .collect();
        let mut order = DistanceOrder::default();
        order.arrange(&chunks, |&(_, d)| d, &mut items);
        let mut ids: Vec<u32> = items.iter().map(|&(k, _)| k).collect();
        ids.sort_unstable();
        assert!(ids.iter().copied().eq(0..n));
        for pair in items.windows(2) {
            let ((a, da), (b, db)) = (pair[0], pair[1]);
            if bucket(da) == bucket(db) {
                assert!(a < b, "{a} before {b} in one bucket");
            } else {
                assert!(bucket(da) < bucket(db));
            }
        }
        for horizon in [0.0, 1e-6, 0.001, 0.0137, 0.02, 200.0, 2e3] {
            let k = order.within(horizon);
            let closer = |&(_, d): &(u32, f64)| d < horizon || d.is_nan();
            assert!(items[k..].iter().all(|i| !closer(i)), "horizon {horizon}");
            let extra = items[..k].iter().filter(|i| !closer(i)).count();
            // Uniform distances: a bucket's 1/128 beyond the horizon holds under 1 %.
            assert!(
                extra < n as usize / 100,
                "horizon {horizon}: {extra} beyond it"
            );
        }
        assert_eq!(order.within(f64::INFINITY), n as usize);
        assert_eq!(order.within(f64::NAN), n as usize);
        let nan = before.iter().filter(|(_, d)| d.is_nan()).count();
        assert!(items[..nan].iter().all(|(_, d)| d.is_nan()));

        order.arrange(&[Vec::new()], |&(_, d): &(u32, f64)| d, &mut items);
        assert!(items.is_empty());
        assert_eq!(order.within(1.0), 0);
    }
}
