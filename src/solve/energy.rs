//! The inertial term of the variational energy (Lu et al. 2023, eq. 2), summed the same for
//! any thread count ([`chunked_sum`]).

use crate::parallel::chunked_sum;
use crate::real::Real;

use super::points::Points;

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
