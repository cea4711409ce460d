//! The round-off floor of a particle's residual per unit mass (docs/particles/solids.md,
//! "Convergence measure"): the step's convergence measure and its merit's floor ([`super::step`]),
//! and the two-level correction's test of a body at round-off ([`super::two_level`]).

use nalgebra::Vector3;

use crate::real::Real;

/// The round-off floor of a particle's residual per unit mass, in units of
/// `eps |y_i| D_i / m_i` (m; [`residual_floor`]). Where an f32 iteration stalls it can leave
/// more (about 3 on a 12^3 cube after an impact: the extrapolation rounds every position
/// again at each iteration, and a particle's residual sums its neighbours' errors): such a
/// step reports not converged. A larger factor would let it stop, but lets f32 stop further
/// from f64 (a clamped beam at tol 1e-7 m: 2e-5 m apart with 4, within 1e-5 m with 1).
pub const ROUNDOFF_FACTOR: f64 = 1.0;

/// The round-off floor (m) of particle `i`'s residual per unit mass `|r_i| / m_i` at `y_i`,
/// with the Jacobi diagonal `d = D_i` and mass `m = m_i` (kg): `c eps |y_i| D_i / m_i`
/// (`c` = [`ROUNDOFF_FACTOR`], `eps` the precision's machine epsilon). A position is stored to
/// `eps |y_i|`, and the residual changes by `D_i` per metre a particle moves, so no stored
/// iterate brings `|r_i| / m_i` much lower, whatever the iteration (docs/particles/solids.md,
/// "Convergence measure"): 25K particles of E 2e5 Pa in a 0.1 m cube at h = 1/30 s have
/// `D_i / m_i` about 5e4, a floor near 5e-4 m in f32 (1e-12 m in f64).
#[inline(always)]
pub(crate) fn residual_floor<T: Real>(y: &Vector3<T>, d: T, m: T) -> f64 {
    ROUNDOFF_FACTOR * T::default_epsilon().to_f64() * y.norm().to_f64() * (d / m).to_f64()
}

/// Where a step's convergence measure stands against the round-off floor, reduced over the
/// particles ([`crate::solve::ParticleTimings::roundoff_floor`] and `worst_particle`): the
/// largest floor `nu_i` (m, [`residual_floor`]), and the particle holding the largest measure
/// `|r_i| / m_i - nu_i` (m) when it is above zero.
#[derive(Clone, Copy)]
pub(crate) struct MeasureReport {
    /// The largest `|r_i| / m_i - nu_i` (m), 0 when every particle is within its floor.
    pub measure: f64,
    /// The particle (family index) holding `measure`, the lowest on a tie; `None` at 0.
    pub particle: Option<usize>,
    /// The largest round-off floor `nu_i` (m).
    pub floor: f64,
}

impl MeasureReport {
    pub const NONE: Self = Self {
        measure: 0.0,
        particle: None,
        floor: 0.0,
    };

    /// Particle `i`'s measure `measure` (m) above its floor `floor` (m).
    pub fn of(i: usize, measure: f64, floor: f64) -> Self {
        Self {
            measure,
            particle: (measure > 0.0).then_some(i),
            floor,
        }
    }

    /// Associative and commutative (ties go to the lower index), so the reduction is the
    /// same for any thread count.
    pub fn merge(a: Self, b: Self) -> Self {
        let floor = a.floor.max(b.floor);
        let (measure, particle) = if a.measure > b.measure {
            (a.measure, a.particle)
        } else if b.measure > a.measure {
            (b.measure, b.particle)
        } else {
            let particle = match (a.particle, b.particle) {
                (Some(x), Some(y)) => Some(x.min(y)),
                (x, y) => x.or(y),
            };
            (a.measure, particle)
        };
        Self {
            measure,
            particle,
            floor,
        }
    }
}
