//! `peridyn._core.contact`: the contact kernels, batched over numpy arrays, for tests and
//! inspection (the solver calls them internally).

use nalgebra::Vector3;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;

use crate::contact::ccd::{edge_edge_ccd, point_triangle_ccd, AdditiveCcd};
use crate::contact::{
    closest_primitive_distance, default_parallel_angle, BroadPhase, ContactMesh, ContactParams,
    D_HAT_PER_THICKNESS,
};
use crate::error::check_param;
use crate::geometry::distance::{edge_edge_closest, point_triangle_closest, Closest};

use super::arrays::{self, to_numpy, to_numpy_1d, vec3s};
use super::errors::IntoPyResult;
use super::options::{DESCENT_STEP, PROXIMAL_METRIC};
use super::scalars::{Flag, Int, Real, Text};

/// Four (n, 3) arrays as n quadruples of points.
fn quadruples(args: [(&Bound<'_, PyAny>, &str); 4]) -> PyResult<Vec<[Vector3<f64>; 4]>> {
    let first = vec3s(args[0].0, args[0].1, None)?;
    let n = first.len();
    let rest = [1, 2, 3].map(|k| vec3s(args[k].0, args[k].1, Some(n)));
    let [b, c, d] = rest;
    let (b, c, d) = (b?, c?, d?);
    Ok((0..n).map(|i| [first[i], b[i], c[i], d[i]]).collect())
}

/// An (n, 4, 3) array as n quadruples of points.
fn stacked(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<[Vector3<f64>; 4]>> {
    let arr = arrays::real_array(obj, name)?;
    let shape: Vec<usize> = arr.getattr("shape")?.extract()?;
    if !(shape.len() == 3 && shape[1] == 4 && shape[2] == 3) {
        return Err(PyValueError::new_err(format!(
            "{name} must have shape (N, 4, 3), got {shape:?}"
        )));
    }
    let flat = vec3s(&arr.call_method1("reshape", (-1, 3))?, name, None)?;
    Ok(flat
        .chunks_exact(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect())
}

/// A closest-points query over four vertices.
type Query = fn(&Vector3<f64>, &Vector3<f64>, &Vector3<f64>, &Vector3<f64>) -> Closest;

/// Squared distances (n,) and their gradients (n, 12).
fn distances<'py>(
    py: Python<'py>,
    points: Vec<[Vector3<f64>; 4]>,
    closest: Query,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let found: Vec<Closest> = py.detach(|| {
        points
            .iter()
            .map(|x| closest(&x[0], &x[1], &x[2], &x[3]))
            .collect()
    });
    let d2 = found.iter().map(Closest::distance_squared).collect();
    let flat: Vec<Vector3<f64>> = found.iter().flat_map(|c| c.gradient_squared()).collect();
    let grads = to_numpy(py, flat.into_iter())?.call_method1("reshape", (found.len(), 12))?;
    Ok((to_numpy_1d(py, d2), grads))
}

/// Squared point-triangle distances (m^2) of n queries and their gradients with respect to
/// `(p, t0, t1, t2)`, shape (n, 12).
#[pyfunction]
fn point_triangle_distance<'py>(
    p: &Bound<'py, PyAny>,
    t0: &Bound<'py, PyAny>,
    t1: &Bound<'py, PyAny>,
    t2: &Bound<'py, PyAny>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let x = quadruples([(p, "p"), (t0, "t0"), (t1, "t1"), (t2, "t2")])?;
    distances(p.py(), x, point_triangle_closest)
}

/// Squared edge-edge distances (m^2) of n queries and their gradients with respect to
/// `(a0, a1, b0, b1)`, shape (n, 12).
#[pyfunction]
fn edge_edge_distance<'py>(
    a0: &Bound<'py, PyAny>,
    a1: &Bound<'py, PyAny>,
    b0: &Bound<'py, PyAny>,
    b1: &Bound<'py, PyAny>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let x = quadruples([(a0, "a0"), (a1, "a1"), (b0, "b0"), (b1, "b1")])?;
    distances(a0.py(), x, edge_edge_closest)
}

/// Triangle pairs for geometric checks: the pairs of triangles sharing no vertex whose
/// bounding boxes at `positions` ((n, 3), m), inflated by `reach / 2` (m) on each side,
/// overlap (the solver's broad phase; every pair closer than `reach` is among them), and per
/// pair the smallest of its 15 primitive distances (eq. 48; m), which is the triangles'
/// distance unless they cross. Returns `(pairs, distances)`, shapes (m, 2) int64 (`a < b`,
/// sorted) and (m,).
#[pyfunction]
fn near_triangle_pairs<'py>(
    positions: &Bound<'py, PyAny>,
    triangles: &Bound<'py, PyAny>,
    reach: Real,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let reach = reach.get("reach")?;
    if !(reach > 0.0 && reach.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "reach must be a finite distance > 0 m, got {reach}"
        )));
    }
    let x = vec3s(positions, "positions", None)?;
    if let Some(bad) = x.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(PyValueError::new_err(format!(
            "positions must be finite, row {bad} is {:?}",
            x[bad].as_slice()
        )));
    }
    let n = x.len() as i64;
    let tris = triangles_in(triangles, "triangles", n)?;
    let py = positions.py();
    let (pairs, distances): (Vec<(u32, u32)>, Vec<f64>) = py.detach(|| {
        let body = vec![0; tris.len()];
        let mesh = ContactMesh {
            triangles: &tris,
            body: &body,
            self_contact: &[true],
        };
        let mut grid = BroadPhase::default();
        let padding = vec![0.5 * reach; tris.len()];
        let mut pairs = grid.candidate_pairs(&x, &x, &mesh, &padding).to_vec();
        pairs.par_sort_unstable();
        let distances = pairs
            .par_iter()
            .map(|&(a, b)| closest_primitive_distance(&x, &tris[a as usize], &tris[b as usize]))
            .collect();
        (pairs, distances)
    });
    let flat: Vec<i64> = pairs
        .iter()
        .flat_map(|&(a, b)| [a.into(), b.into()])
        .collect();
    let m = pairs.len();
    let pairs = to_numpy_1d(py, flat).call_method1("reshape", (m, 2))?;
    Ok((pairs, to_numpy_1d(py, distances)))
}

/// An (m, 3) integer array of vertex indices in `[0, n)`.
fn triangles_in(obj: &Bound<'_, PyAny>, name: &str, n: i64) -> PyResult<Vec<[u32; 3]>> {
    arrays::triangles(obj, name)?
        .into_iter()
        .enumerate()
        .map(|(t, tri)| {
            if tri.iter().all(|&v| (0..n).contains(&v)) {
                Ok(tri.map(|v| v as u32))
            } else {
                Err(PyValueError::new_err(format!(
                    "{name}[{t}] = {tri:?} has an index outside [0, {n})"
                )))
            }
        })
        .collect()
}

type Ccd = fn(&[Vector3<f64>; 4], &[Vector3<f64>; 4], f64, &AdditiveCcd) -> Option<f64>;

fn ccd<'py>(
    start: &Bound<'py, PyAny>,
    end: &Bound<'py, PyAny>,
    min_distance: Real,
    s: Real,
    t_c: Real,
    query: Ccd,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let (min_distance, s, t_c) = (
        min_distance.get("min_distance")?,
        s.get("s")?,
        t_c.get("t_c")?,
    );
    if !(min_distance >= 0.0 && min_distance.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "min_distance must be a finite distance >= 0 m, got {min_distance}"
        )));
    }
    if !(s > 0.0 && s < 1.0 && t_c > 0.0 && t_c <= 1.0) {
        return Err(PyValueError::new_err(format!(
            "need 0 < s < 1 and 0 < t_c <= 1, got s = {s}, t_c = {t_c}"
        )));
    }
    let (a, b) = (stacked(start, "start")?, stacked(end, "end")?);
    if a.len() != b.len() {
        return Err(PyValueError::new_err(format!(
            "start and end hold {} and {} queries",
            a.len(),
            b.len()
        )));
    }
    let params = AdditiveCcd {
        s,
        t_c,
        ..AdditiveCcd::default()
    };
    let py = start.py();
    let toi: Vec<Option<f64>> = py.detach(|| {
        a.iter()
            .zip(&b)
            .map(|(x0, x1)| query(x0, x1, min_distance, &params))
            .collect()
    });
    let hit = toi.iter().map(Option::is_some).collect();
    let times = toi.iter().map(|t| t.unwrap_or(1.0)).collect();
    Ok((to_numpy_1d(py, hit), to_numpy_1d(py, times)))
}

/// Additive CCD of n point-triangle pairs moving linearly from `start` to `end` (each (n, 4, 3):
/// point, then the triangle's vertices). Returns `(hit, toi)`: whether the distance reaches
/// `min_distance` (m) within the step, and a lower bound of that time (1 where no hit).
#[pyfunction]
#[pyo3(signature = (start, end, min_distance = Real::of(0.0), *, s = Real::of(0.1),
                    t_c = Real::of(0.95)))]
fn point_triangle_ccd_additive<'py>(
    start: &Bound<'py, PyAny>,
    end: &Bound<'py, PyAny>,
    min_distance: Real,
    s: Real,
    t_c: Real,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    ccd(start, end, min_distance, s, t_c, point_triangle_ccd)
}

/// Additive CCD of n edge-edge pairs (each (n, 4, 3): `a0, a1, b0, b1`); see
/// `point_triangle_ccd_additive`.
#[pyfunction]
#[pyo3(signature = (start, end, min_distance = Real::of(0.0), *, s = Real::of(0.1),
                    t_c = Real::of(0.95)))]
fn edge_edge_ccd_additive<'py>(
    start: &Bound<'py, PyAny>,
    end: &Bound<'py, PyAny>,
    min_distance: Real,
    s: Real,
    t_c: Real,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    ccd(start, end, min_distance, s, t_c, edge_edge_ccd)
}

/// Contact between and within membranes: the local step of Algorithm 2 (Lu et al. 2023).
///
/// `thickness` xi (m): primitives keep their mid-surfaces about xi apart, never closer than
/// `eps * xi`; `d_hat` (m, default xi / 2; the paper's Table 1 has 4 xi): barrier range on the
/// gap `f(d) - xi`, and layers at rest on one another lie about `xi + d_hat` apart (see
/// `D_HAT_PER_THICKNESS`);
/// `eps` (default 0.1): minimal separation multiplier of eq. 51, also the largest descent move
/// per iteration in units of xi; `weight` mu (default 1): barrier weight of eq. 47;
/// `max_iters` (default 32): descent iterations per local step, which stops earlier once its
/// largest move is below `eps * xi / 100`, or `tol / 5` with a smaller solver `tol` (see
/// `ContactParams::stop_distance`); `step` ("curvature", default,
/// or "uniform"): the descent's step rule, per vertex scaled by the barrier's curvature, or
/// eq. 53's one step for all vertices (see `DescentStep`); `toi_threshold` (default 0.1):
/// times of impact above it clamp inside the descent; `ccd_s`, `ccd_t_c` (0.1, 0.95): the
/// additive CCD's parameters; `warm_start` (default True): start each local step's descent
/// from the global step's result plus the move the last local step made where the barrier
/// pushed, instead of the result alone (Algorithm 2, line 2), see `ContactParams::warm_start`;
/// `parallel_angle` (radians, default asin(sqrt(1e-3)), 1.8 degrees, as in IPC): edge-edge
/// pairs closer to parallel than this fade out of the barrier (0 for parallel edges, where the
/// point-triangle pairs hold the contact), so that stacked layers converge at tight
/// tolerances; 0 turns the fade off (the paper's barrier), see `ContactParams::parallel_angle`;
/// `proximal` ("jacobi", default, or "identity"): the metric of eq. 47's proximal term, the
/// global step's Jacobi blocks `D_i` over their mean `d` (both steps in one metric: contact
/// conserves momentum, the barrier's weight is effectively `d * weight`) or the paper's
/// identity, see `ProximalMetric`.
#[pyclass(module = "peridyn._core", name = "Contact", frozen)]
#[derive(Clone)]
pub struct PyContact {
    pub inner: ContactParams,
}

#[pymethods]
impl PyContact {
    #[new]
    #[pyo3(signature = (*, thickness = Real::of(1.5e-3), d_hat = None, eps = Real::of(0.1),
                        weight = Real::of(1.0), max_iters = Int::of(32), step = Text::of("curvature"),
                        toi_threshold = Real::of(0.1), ccd_s = Real::of(0.1),
                        ccd_t_c = Real::of(0.95), warm_start = Flag::of(true),
                        parallel_angle = None, proximal = Text::of("jacobi")))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        thickness: Real,
        d_hat: Option<Real>,
        eps: Real,
        weight: Real,
        max_iters: Int,
        step: Text,
        toi_threshold: Real,
        ccd_s: Real,
        ccd_t_c: Real,
        warm_start: Flag,
        parallel_angle: Option<Real>,
        proximal: Text,
    ) -> PyResult<Self> {
        let thickness = thickness.get("thickness")?;
        let d_hat = d_hat.map(|d| d.get("d_hat")).transpose()?;
        let (eps, weight) = (eps.get("eps")?, weight.get("weight")?);
        let max_iters = max_iters.get("max_iters")?;
        let toi_threshold = toi_threshold.get("toi_threshold")?;
        let (ccd_s, ccd_t_c) = (ccd_s.get("ccd_s")?, ccd_t_c.get("ccd_t_c")?);
        let parallel_angle = parallel_angle
            .map(|a| a.get("parallel_angle"))
            .transpose()?;
        let inner = ContactParams {
            thickness,
            d_hat: d_hat.unwrap_or(D_HAT_PER_THICKNESS * thickness),
            eps,
            weight,
            max_iters: iteration_cap(max_iters)?,
            step: DESCENT_STEP.parse(step.get("step")?)?,
            toi_threshold,
            ccd: AdditiveCcd {
                s: ccd_s,
                t_c: ccd_t_c,
                ..AdditiveCcd::default()
            },
            warm_start: warm_start.get("warm_start")?,
            parallel_angle: parallel_angle.unwrap_or_else(default_parallel_angle),
            proximal: PROXIMAL_METRIC.parse(proximal.get("proximal")?)?,
        };
        inner.validate().py()?;
        Ok(Self { inner })
    }
    /// Contact thickness xi (m).
    #[getter]
    fn thickness(&self) -> f64 {
        self.inner.thickness
    }
    /// Barrier range d_hat (m).
    #[getter]
    fn d_hat(&self) -> f64 {
        self.inner.d_hat
    }
    #[getter]
    fn eps(&self) -> f64 {
        self.inner.eps
    }
    #[getter]
    fn weight(&self) -> f64 {
        self.inner.weight
    }
    #[getter]
    fn max_iters(&self) -> usize {
        self.inner.max_iters
    }
    /// The descent's step rule: "curvature" or "uniform".
    #[getter]
    fn step(&self) -> &'static str {
        DESCENT_STEP.name(self.inner.step)
    }
    #[getter]
    fn toi_threshold(&self) -> f64 {
        self.inner.toi_threshold
    }
    /// Whether local steps start from the last one's push (see the class doc).
    #[getter]
    fn warm_start(&self) -> bool {
        self.inner.warm_start
    }
    /// The metric of eq. 47's proximal term: "jacobi" or "identity".
    #[getter]
    fn proximal(&self) -> &'static str {
        PROXIMAL_METRIC.name(self.inner.proximal)
    }
    /// Fade angle of nearly parallel edge-edge pairs (radians).
    #[getter]
    fn parallel_angle(&self) -> f64 {
        self.inner.parallel_angle
    }
    /// The additive CCD's `s`.
    #[getter]
    fn ccd_s(&self) -> f64 {
        self.inner.ccd.s
    }
    /// The additive CCD's `t_c`.
    #[getter]
    fn ccd_t_c(&self) -> f64 {
        self.inner.ccd.t_c
    }
    /// The local step's stopping distance (m) under a solver tolerance `tol` (m; 0 for a
    /// fixed iteration count): `eps * xi / 100`, or `tol / 5` where that is smaller (see
    /// `ContactParams::stop_distance`). The local step's result is only this exact.
    fn stop_distance(&self, tol: Real) -> PyResult<f64> {
        let tol = check_param(
            "tol",
            tol.get("tol")?,
            |v| v >= 0.0,
            "a finite distance >= 0 m",
        )
        .py()?;
        Ok(self.inner.stop_distance(tol))
    }
    /// A copy with the parameters named by keyword (the constructor's names) changed and the
    /// rest kept, validated as the constructor validates: `c.replace(parallel_angle=0.0)`.
    /// `d_hat` is kept unless named, also where `thickness` changes.
    #[pyo3(signature = (**changes))]
    fn replace(&self, changes: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let mut p = self.inner;
        for (key, value) in changes.into_iter().flatten() {
            let key: String = key.extract()?;
            let real = |name: &str| value.extract::<Real>()?.get(name);
            match key.as_str() {
                "thickness" => p.thickness = real("thickness")?,
                "d_hat" => p.d_hat = real("d_hat")?,
                "eps" => p.eps = real("eps")?,
                "weight" => p.weight = real("weight")?,
                "max_iters" => {
                    p.max_iters = iteration_cap(value.extract::<Int>()?.get("max_iters")?)?
                }
                "step" => p.step = DESCENT_STEP.parse(&value.extract::<String>()?)?,
                "toi_threshold" => p.toi_threshold = real("toi_threshold")?,
                "ccd_s" => p.ccd.s = real("ccd_s")?,
                "ccd_t_c" => p.ccd.t_c = real("ccd_t_c")?,
                "warm_start" => p.warm_start = value.extract()?,
                "parallel_angle" => p.parallel_angle = real("parallel_angle")?,
                "proximal" => p.proximal = PROXIMAL_METRIC.parse(&value.extract::<String>()?)?,
                other => {
                    return Err(PyTypeError::new_err(format!(
                        "Contact.replace() got an unexpected keyword argument {other:?}"
                    )))
                }
            }
        }
        p.validate().py()?;
        Ok(Self { inner: p })
    }
    fn __repr__(&self) -> String {
        let p = &self.inner;
        format!(
            "Contact(thickness={}, d_hat={}, eps={}, weight={}, max_iters={}, step='{}', \
             toi_threshold={}, ccd_s={}, ccd_t_c={}, warm_start={}, parallel_angle={}, \
             proximal='{}')",
            p.thickness,
            p.d_hat,
            p.eps,
            p.weight,
            p.max_iters,
            self.step(),
            p.toi_threshold,
            p.ccd.s,
            p.ccd.t_c,
            if p.warm_start { "True" } else { "False" },
            p.parallel_angle,
            self.proximal()
        )
    }
}

/// `max_iters` as a count, or a ValueError naming it.
fn iteration_cap(max_iters: i64) -> PyResult<usize> {
    usize::try_from(max_iters)
        .map_err(|_| PyValueError::new_err(format!("max_iters must be >= 1, got {max_iters}")))
}

/// The `contact` submodule.
pub fn module<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyModule>> {
    let m = PyModule::new(py, "contact")?;
    m.add_function(wrap_pyfunction!(point_triangle_distance, &m)?)?;
    m.add_function(wrap_pyfunction!(near_triangle_pairs, &m)?)?;
    m.add_function(wrap_pyfunction!(edge_edge_distance, &m)?)?;
    m.add_function(wrap_pyfunction!(point_triangle_ccd_additive, &m)?)?;
    m.add_function(wrap_pyfunction!(edge_edge_ccd_additive, &m)?)?;
    Ok(m)
}
