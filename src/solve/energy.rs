//! Sums over points that are the same for any thread count (fixed chunks, combined in order:
//! a rayon `reduce` groups its additions as the work happens to be split, which varies with
//! the thread count and with work stealing), and the inertial term of the variational energy
//! (Lu et al. 2023, eq. 2).

use rayon::prelude::*;

use crate::real::Real;

use super::points::Points;

/// Points per partial sum: fixed, so that the sums do not depend on the number of threads.
const ENERGY_CHUNK: usize = 4096;

/// `sum_i term(i)` for `i < n`, summed in fixed chunks (the same for any thread count) whose
/// partial sums go to the reused `scratch`.
pub(crate) fn chunked_sum(
    n: usize,
    scratch: &mut Vec<f64>,
    term: impl Fn(usize) -> f64 + Sync,
) -> f64 {
    (0..n.div_ceil(ENERGY_CHUNK))
        .into_par_iter()
        .map(|c| {
            (c * ENERGY_CHUNK..((c + 1) * ENERGY_CHUNK).min(n))
                .map(&term)
                .sum::<f64>()
        })
        .collect_into_vec(scratch);
    scratch.iter().sum()
}

/// `sum_i m_i |x_i - y*_i|^2 / (2 h^2)` (J) over free points, for `x` = `y_start` when
/// `at_start`, else `y`.
pub(crate) fn inertial_energy<T: Real>(points: &mut Points<T>, h: T, at_start: bool) -> f64 {
    let inv_2h2 = 0.5 / (h.to_f64() * h.to_f64());
    let Points {
        y,
        y_start,
        y_star,
        pinned,
        mass,
        energy_chunks,
        ..
    } = points;
    let x = if at_start { &*y_start } else { &*y };
    chunked_sum(x.len(), energy_chunks, |i| {
        if pinned[i] {
            0.0
        } else {
            (x[i] - y_star[i]).norm_squared().to_f64() * mass[i].to_f64() * inv_2h2
        }
    })
}
