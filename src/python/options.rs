//! The one place where the Python edge maps option strings to core values, and core values
//! back to strings for the getters: one table per option. A string no table holds is a
//! ValueError naming the option, the accepted strings and the value given. The stub
//! `python/peridyn/_core/_options.pyi` spells each table as a `Literal` type.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::contact::{DescentStep, ProximalMetric};
use crate::membrane::Preconditioner;
use crate::solve::{GlobalSolver, Method};

/// An option's accepted strings, each with the value it stands for.
pub struct Choices<T: 'static> {
    /// The option's name in error messages.
    what: &'static str,
    /// The value Python's None stands for, where None is accepted; strings naming that value
    /// are quiet synonyms of None (accepted, not offered in messages, not returned).
    none: Option<T>,
    /// Every accepted string and its value; a value's first string is the one getters return.
    names: &'static [(&'static str, T)],
}

impl<T: Copy + PartialEq> Choices<T> {
    /// The value named `name`, or a ValueError naming the option and the accepted strings.
    pub fn parse(&self, name: &str) -> PyResult<T> {
        self.names
            .iter()
            .find(|(n, _)| *n == name)
            .map(|&(_, value)| value)
            .ok_or_else(|| {
                PyValueError::new_err(format!(
                    "{} must be {}, got {name:?}",
                    self.what,
                    self.accepted()
                ))
            })
    }

    /// The value of an optional string: None stands for the table's `none` value.
    pub fn parse_optional(&self, name: Option<&str>) -> PyResult<T> {
        match (name, self.none) {
            (None, Some(value)) => Ok(value),
            (None, None) => Err(PyValueError::new_err(format!(
                "{} must be {}, got None",
                self.what,
                self.accepted()
            ))),
            (Some(name), _) => self.parse(name),
        }
    }

    /// The string of `value` (the first one the table gives it).
    pub fn name(&self, value: T) -> &'static str {
        self.names
            .iter()
            .find(|(_, v)| *v == value)
            .map(|&(n, _)| n)
            .expect("every value of an option has a string in its table")
    }

    /// The string of `value`, or None for the value None stands for.
    pub fn name_optional(&self, value: T) -> Option<&'static str> {
        (self.none != Some(value)).then(|| self.name(value))
    }

    /// "'a' or 'b'", "'a', 'b' or 'c'", with "None" first where it is accepted.
    fn accepted(&self) -> String {
        let mut shown: Vec<String> = Vec::new();
        if self.none.is_some() {
            shown.push("None".to_owned());
        }
        for &(name, value) in self.names {
            if self.none != Some(value) && self.name(value) == name {
                shown.push(format!("'{name}'"));
            }
        }
        match shown.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
            _ => shown.concat(),
        }
    }
}

/// `Solver(method=...)`: the paper's SISSM, the descent baseline of Fig. 13 or Newton (issue 44).
pub const METHOD: Choices<Method> = Choices {
    what: "method",
    none: None,
    names: &[
        ("sissm", Method::Sissm),
        ("descent", Method::Descent),
        ("newton", Method::Newton),
        ("auto", Method::Auto),
    ],
};

/// `Solver(global_solver=...)`: how particle bodies solve their global step (Fig. 7 of He
/// et al. 2017).
pub const GLOBAL_SOLVER: Choices<GlobalSolver> = Choices {
    what: "global_solver",
    none: None,
    names: &[
        ("direct", GlobalSolver::Direct),
        ("jacobi", GlobalSolver::Jacobi),
        ("chebyshev", GlobalSolver::Chebyshev),
        ("position", GlobalSolver::Position),
    ],
};

/// `Solver(preconditioner=...)`.
pub const PRECONDITIONER: Choices<Preconditioner> = Choices {
    what: "preconditioner",
    none: None,
    names: &[
        ("tangent", Preconditioner::Tangent),
        ("paper", Preconditioner::Paper),
    ],
};

/// The kind of `Solver(acceleration=...)`; its parameters come from their own arguments.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AccelerationKind {
    /// Plain iterations (None, or "none").
    Plain,
    /// Chebyshev semi-iterative acceleration.
    Chebyshev,
}

/// `Solver(acceleration=...)`: None (or the quiet synonym "none") or "chebyshev".
pub const ACCELERATION: Choices<AccelerationKind> = Choices {
    what: "acceleration",
    none: Some(AccelerationKind::Plain),
    names: &[
        ("none", AccelerationKind::Plain),
        ("chebyshev", AccelerationKind::Chebyshev),
    ],
};

/// Where a solver runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Backend {
    /// The CPU solver, on worker threads.
    Cpu,
    /// The wgpu compute-shader solver.
    Gpu,
}

/// `Solver(backend=...)`.
pub const BACKEND: Choices<Backend> = Choices {
    what: "backend",
    none: None,
    names: &[("cpu", Backend::Cpu), ("gpu", Backend::Gpu)],
};

/// The floating-point type a solver computes in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Float {
    /// Single precision (the GPU's default).
    F32,
    /// Double precision (the CPU's default).
    F64,
}

/// `Solver(precision=...)` (None: the backend's default).
pub const PRECISION: Choices<Float> = Choices {
    what: "precision",
    none: None,
    names: &[("f32", Float::F32), ("f64", Float::F64)],
};

/// `Contact(step=...)`: the descent's step rule.
pub const DESCENT_STEP: Choices<DescentStep> = Choices {
    what: "contact step",
    none: None,
    names: &[
        ("curvature", DescentStep::Curvature),
        ("uniform", DescentStep::Uniform),
    ],
};

/// `Contact(proximal=...)`: the metric of eq. 47's proximal term.
pub const PROXIMAL_METRIC: Choices<ProximalMetric> = Choices {
    what: "contact proximal",
    none: None,
    names: &[
        ("jacobi", ProximalMetric::Jacobi),
        ("identity", ProximalMetric::Identity),
    ],
};
