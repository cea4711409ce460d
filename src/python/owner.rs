//! The solver a Python body belongs to: the one it was last added to.

use std::sync::{Arc, Mutex, Weak};

/// The identity of one Python `Solver`, which holds it; the bodies it steps hold it weakly
/// ([`Owner`]).
pub struct SolverMark;

/// The solver a body belongs to, if any: the last one it was added to. A body is stepped by one
/// solver: a solver keeps its own record of its bodies from step to step (their working set
/// and evaluation, the contact warm start, the friction at the grains' contacts), so a body
/// stepped by two solvers in turn would start each one's steps from that solver's record of
/// other positions, and be the run of neither. Adding a body to a solver hands it over (a body
/// settled by one solver goes on in another, built with other settings); the solver it was
/// taken from refuses to step it (`Solver.step`'s `ValueError`) until it is added there again,
/// which takes it back and counts its positions as replaced, as `set_positions` does (a
/// particle body's grain friction starts from 0, its stiffness from its positions).
#[derive(Default)]
pub struct Owner(Mutex<Weak<SolverMark>>);

impl Owner {
    /// Hands the body to the solver of `mark`.
    pub fn claim(&self, mark: &Arc<SolverMark>) {
        *self.0.lock().unwrap_or_else(|p| p.into_inner()) = Arc::downgrade(mark);
    }

    /// Whether the solver of `mark` holds the body.
    pub fn held_by(&self, mark: &Arc<SolverMark>) -> bool {
        let held = self.0.lock().unwrap_or_else(|p| p.into_inner());
        std::ptr::eq(held.as_ptr(), Arc::as_ptr(mark))
    }
}
