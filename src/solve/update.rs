//! What one global move of any body family reports, and what it is asked to do.

use nalgebra::Vector3;

use crate::collider::ColliderModel;
use crate::real::Real;

use super::GlobalSolver;

/// Per-vertex outcome of an update, reduced over vertices.
#[derive(Clone, Copy)]
pub(crate) struct Update {
    /// Largest move `|y_i^{k+1} - y_i^k|` (m).
    pub moved: f64,
    /// Largest `|r_i| / m_i` at `y^k` (m), contact reactions removed: the convergence measure.
    pub residual: f64,
    /// Lowest vertex that became non-finite.
    pub first_bad: Option<usize>,
}

impl Update {
    pub fn of<T: Real>(vertex: usize, before: &Vector3<T>, after: &Vector3<T>) -> Self {
        let finite = after.x.is_finite() & after.y.is_finite() & after.z.is_finite();
        // The square root in f64, as the per-chunk maxima of the move take it.
        let moved = (after - before).norm_squared().to_f64().sqrt();
        Self {
            moved: if finite { moved } else { 0.0 },
            residual: 0.0,
            first_bad: (!finite).then_some(vertex),
        }
    }

    /// Associative and commutative, so the reduction is the same for any thread count.
    pub fn merge(a: Self, b: Self) -> Self {
        let first_bad = match (a.first_bad, b.first_bad) {
            (Some(x), Some(y)) => Some(x.min(y)),
            (x, y) => x.or(y),
        };
        Self {
            moved: a.moved.max(b.moved),
            residual: a.residual.max(b.residual),
            first_bad,
        }
    }

    /// The largest move and residual from the largest of their squares (m^2), square roots in
    /// f64 (`sqrt` is monotonic, so this is the largest norm).
    pub fn from_squares<T: Real>(moved_sq: T, residual_sq: T) -> Self {
        Self {
            moved: moved_sq.to_f64().sqrt(),
            residual: residual_sq.to_f64().sqrt(),
            first_bad: None,
        }
    }

    pub const NONE: Self = Self {
        moved: 0.0,
        residual: 0.0,
        first_bad: None,
    };
}

/// What the move of one global iteration is asked to do.
#[derive(Clone, Copy)]
pub(crate) struct MoveOptions<'a, T: Real> {
    /// Apply the step length of eq. 31-33.
    pub step_length: bool,
    /// Jacobi sweeps on the linear system of eq. 25 (1: the paper's default).
    pub inner_iters: usize,
    /// Chebyshev extrapolation weight of this iteration, if any.
    pub omega: Option<T>,
    pub colliders: &'a [ColliderModel<T>],
    /// Per vertex: the contact reaction the last local step realised at the current iterate
    /// (m; see [`super::membranes::jacobi::free_residual`]), or empty when contact is off or no local step ran yet this
    /// step.
    pub contact_reaction: &'a [Vector3<T>],
    /// How particle bodies solve their global step (membranes ignore it).
    pub global_solver: GlobalSolver,
}
