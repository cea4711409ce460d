//! Counter-based random numbers: each value a hash of the seed and the index of what it is for
//! (a lattice site, a candidate), so the draws do not depend on the order or the thread in which
//! they are made.

use nalgebra::Vector3;

/// The SplitMix64 finaliser: a bijective 64-bit mix.
#[inline]
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A 64-bit hash of a seed and a sequence of counters.
#[inline]
pub(super) fn hash(seed: u64, counters: &[u64]) -> u64 {
    counters
        .iter()
        .fold(mix(seed.wrapping_add(0x9e37_79b9_7f4a_7c15)), |h, &c| {
            mix(h ^ mix(c.wrapping_add(0x632b_e59b_d9b4_e019)))
        })
}

/// Uniform in `[-1, 1)` from the top 53 bits of a hash.
#[inline]
fn symmetric_unit(h: u64) -> f64 {
    (h >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// A point uniform in the unit ball, from the seed and a site's counters (rejection from the
/// cube, each attempt a new hash: about 1.9 attempts on average).
pub(super) fn in_unit_ball(seed: u64, site: [u64; 3]) -> Vector3<f64> {
    for attempt in 0u64.. {
        let h = |axis: u64| symmetric_unit(hash(seed, &[site[0], site[1], site[2], attempt, axis]));
        let v = Vector3::new(h(0), h(1), h(2));
        if v.norm_squared() <= 1.0 {
            return v;
        }
    }
    unreachable!("the cube's points fall in the ball with probability pi / 6")
}
