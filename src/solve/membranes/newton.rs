//! Newton's method on the implicit Euler energy: the global solver for fine, stiff membranes
//! (issue 44), beside SISSM.
//!
//! Implicit Euler minimises `E(y) = sum_k m_k |y_k - y*_k|^2 / (2 h^2) + U(y)` (J; Lu et al.
//! 2023, eq. 2 without the barrier). Scaled by `h^2`, its gradient is `-r` with
//! `r_k = m_k (y*_k - y_k) + h^2 f_k(y)` (kg m) and its Hessian `H = M + h^2 d^2U/dy^2` (kg).
//! One iteration:
//!
//! 1. measures the residual at `y` exactly as SISSM does (its Jacobi system `D_k` of eq. 25,
//!    the colliders' reaction to the Jacobi move, the contact reactions; see
//!    [`super::jacobi::free_residual`]), so the convergence test is the same;
//! 2. builds the projected Hessian model of every vertex energy
//!    ([`super::hessian_model`]), positive semi-definite, so `K = M + h^2 sum_i G_i^T H_i G_i`
//!    (with `G_i` the map from vertex displacements to vertex `i`'s bond vectors) is symmetric
//!    positive definite on the free vertices;
//!    A vertex that a collider or a membrane contact holds (the colliders push its Jacobi move
//!    back, or the last local step pushed it) takes its Jacobi move `D_k^-1 r_k`, as in SISSM,
//!    and is fixed in the solve below: the Newton system knows nothing of the contacts. So does
//!    a free vertex whose Newton move the colliders would push back;
//! 3. solves `K d = r` on the other free vertices approximately by conjugate gradients,
//!    matrix-free (the product gathers per-bond products as the force does), from `d = 0`,
//!    until the preconditioned residual falls by [`FORCING`] or after [`MAX_LINEAR_ITERS`]
//!    products, preconditioned by two levels ([`precondition`]): SISSM's blocks `D_k^-1`
//!    (block Jacobi) for the error that varies from vertex to vertex, plus a Galerkin coarse
//!    correction on aggregates of vertices ([`CoarseLevel`]) for the smooth error that block
//!    Jacobi leaves to hundreds of CG steps on fine, stiff cloth. The coarse factor is kept
//!    across iterations and steps until the CG's products grow ([`Refactor`]): a stale
//!    preconditioner is still symmetric positive definite;
//! 4. takes the step along `d` by the energy line search shared with the descent baseline
//!    ([`search_along`]: `alpha` from 1, halved while `E` rises, colliders projected in each
//!    trial), so no iteration increases the energy beyond round-off.
//!
//! `d` is a descent direction: CG from zero on a symmetric positive definite system gives
//! `r . d > 0` after any number of steps. The contact local step (Algorithm 2) follows the
//! global step in the solver as for every method; its move changes the energy, so an iteration
//! after it starts by re-evaluating. Its proximal metric is taken from SISSM's blocks at `y`
//! ([`NewtonState::metric`]), not from the responses the line search left at its trial, so the
//! two methods' fixed points under contact are the same (docs/model.md, "Membrane contact").
//!
//! Every reduction (the CG's dot products) sums in f64 in fixed chunks, and every other pass
//! writes per vertex: results do not depend on the thread count.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::error::Result;
use crate::membrane::{bond_vectors, internal_force, Membrane, Preconditioner, RestData};
use crate::parallel::{chunked_sum, for_each_vertex};
use crate::real::Real;
use crate::solve::NewtonTimings;
use crate::timing::millis;
use std::time::Instant;

use super::coarse::CoarseLevel;
use super::descent::{jacobi_moves, search_along, LineSearch};
use super::evaluate::{evaluate, total_energy};
use super::hessian_model::VertexModel;
use super::jacobi::whole_move_reaction;
use super::system::MembraneSystem;
use crate::solve::point_system::PointSystem;
use crate::solve::update::{MoveOptions, Update};

/// Relative fall of the preconditioned residual `sqrt(z . r)` at which the CG stops (the
/// forcing term of an inexact Newton method).
const FORCING: f64 = 0.05;

/// Most Hessian products per Newton iteration.
const MAX_LINEAR_ITERS: usize = 400;

/// A coarse factor is kept (across the iterations of a step and across steps) until a CG
/// with it takes more than this many times the products of the first CG after its
/// factorisation.
const REFACTOR_GROWTH: usize = 2;

/// When the coarse matrix is assembled and factored. It is only a preconditioner: a factor
/// from earlier models (and an earlier free set; `P` and `P^T` act on the current free
/// vertices only) keeps `M^-1` symmetric positive definite and the CG correct, only slower.
/// So it is refactored when the CG's products have grown since its last factorisation.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Refactor {
    /// Before the next CG (no usable factor).
    Now,
    /// Once a CG takes more than `REFACTOR_GROWTH` times `fresh` products, `fresh` being
    /// the products of the first CG after the last factorisation (`None` until it ran).
    After { fresh: Option<usize> },
}
/// What of the preconditioner a step started with, for [`NewtonState::roll_back`]: when the
/// coarse level is factored again, whether it was built, and its factor's values, copied
/// before the step's first factorisation (`None` while the step took none).
struct StepStart {
    refactor: Refactor,
    coarse_built: bool,
    factor: Option<Vec<f64>>,
}

/// The Newton method's working set: the rest data with its bonds (the model needs the
/// stencils, which the packed host kernel keeps only in SIMD packs), the Hessian models, and
/// the CG's vectors.
pub(crate) struct NewtonState<T: Real> {
    rest: RestData<T>,
    models: Vec<VertexModel<T>>,
    /// Per-bond scratch of the Hessian product.
    bonds: Vec<Vector3<T>>,
    /// SISSM's Jacobi systems at `y` (the preconditioner and the colliders' metric).
    metric: Vec<PointSystem<T>>,
    /// CG: solution (the Newton direction), residual, preconditioned residual, search
    /// direction and its product.
    d: Vec<Vector3<T>>,
    r: Vec<Vector3<T>>,
    z: Vec<Vector3<T>>,
    p: Vec<Vector3<T>>,
    q: Vec<Vector3<T>>,
    sums: Vec<f64>,
    /// The vertices the CG moves: not pinned, and not held by a collider or a membrane
    /// contact (those take their Jacobi move, kept in `held` for every vertex, see
    /// [`newton_iteration`]).
    free: Vec<bool>,
    held: Vec<Vector3<T>>,
    /// The coarse level of the CG's preconditioner (built on the first iteration; `None`
    /// after a failed set-up, when the CG runs on block Jacobi alone).
    coarse: Option<CoarseLevel>,
    coarse_built: bool,
    /// When the coarse matrix is factored again (see [`Refactor`]).
    refactor: Refactor,
    /// The preconditioner as the current step found it ([`Self::begin_step`]).
    step_start: StepStart,
    /// Hessian products of the CG in the current time step.
    pub products: usize,
    /// Milliseconds per phase since the caller last took them.
    pub timings: NewtonTimings,
}

impl<T: Real> NewtonState<T> {
    /// Concatenates the bodies' rest data (in the vertex and bond order of
    /// [`MembraneSystem::build`]).
    pub fn new(bodies: &[&mut Membrane]) -> Result<Self> {
        let mut rest = RestData::empty();
        for body in bodies {
            rest.extend_from(&body.rest_source()?, true)?;
        }
        let (n, bonds) = (rest.vertices.len(), rest.bonds.len());
        let zero = PointSystem::unit();
        let vectors = vec![Vector3::zeros(); n];
        Ok(Self {
            rest,
            models: vec![VertexModel::default(); n],
            bonds: vec![Vector3::zeros(); bonds],
            metric: vec![zero; n],
            d: vectors.clone(),
            r: vectors.clone(),
            z: vectors.clone(),
            p: vectors.clone(),
            q: vectors.clone(),
            sums: Vec::new(),
            free: vec![true; n],
            held: vectors,
            coarse: None,
            coarse_built: false,
            refactor: Refactor::Now,
            step_start: StepStart {
                refactor: Refactor::Now,
                coarse_built: false,
                factor: None,
            },
            products: 0,
            timings: NewtonTimings::default(),
        })
    }

    /// Marks the start of a step: [`Self::roll_back`] returns the preconditioner here.
    pub fn begin_step(&mut self) {
        self.step_start = StepStart {
            refactor: self.refactor,
            coarse_built: self.coarse_built,
            factor: None,
        };
    }

    /// Returns the preconditioner to where the step began ([`Self::begin_step`]) after the
    /// step failed: the coarse factor (none if the step built the coarse level), whether it
    /// was built and when it is factored again. The step that replaces the failed one then
    /// computes what a run that never took it computes, bit for bit (the rest of this working
    /// set is written by every iteration before it is read).
    pub fn roll_back(&mut self) {
        let (refactor, coarse_built) = (self.step_start.refactor, self.step_start.coarse_built);
        let factor = self.step_start.factor.take();
        if !coarse_built {
            self.coarse = None;
        } else if let (Some(coarse), Some(values)) = (&mut self.coarse, &factor) {
            coarse.restore_factor(values);
        }
        self.coarse_built = coarse_built;
        self.refactor = refactor;
    }

    /// SISSM's Jacobi systems `D_k` at the last iteration's iterate `y` (before its move),
    /// for the contact local step's metric.
    pub fn metric(&self) -> &[PointSystem<T>] {
        &self.metric
    }

    /// Every vertex's Hessian model at the positions `y` (m).
    pub fn build_models(&mut self, sys: &MembraneSystem<T>, y: &[Vector3<T>]) {
        let (nb, rest) = (&sys.nb, &self.rest);
        for_each_vertex(
            &nb.offsets,
            &mut self.bonds,
            &mut self.models,
            &|i, edges| {
                bond_vectors(i, y, nb.of(i), edges);
                VertexModel::of(&rest.stencil(nb, i), edges)
            },
        );
    }
}

#[cfg(test)]
impl<T: Real> NewtonState<T> {
    /// The CG of a Newton iteration on `K d = r` at the evaluated state of `sys` (every
    /// unpinned vertex free, SISSM's blocks as the metric), with or without the coarse level:
    /// the Hessian products it took and `d`.
    pub fn linear_solve(
        &mut self,
        sys: &MembraneSystem<T>,
        h2: T,
        r: &[Vector3<T>],
        coarse: bool,
    ) -> (usize, Vec<Vector3<T>>) {
        self.free = sys.points.pinned.iter().map(|p| !p).collect();
        self.metric = (0..r.len()).map(|k| PointSystem::of(sys, k, h2)).collect();
        for (k, out) in self.r.iter_mut().enumerate() {
            *out = if self.free[k] { r[k] } else { Vector3::zeros() };
        }
        self.build_models(sys, &sys.points.y);
        self.coarse_built = true;
        self.refactor = Refactor::Now;
        self.coarse = coarse.then(|| CoarseLevel::new(&sys.nb).unwrap());
        let before = self.products;
        solve_newton_system(sys, self, h2);
        (self.products - before, self.d.clone())
    }

    /// The coarse level factored for the models at `sys`'s positions, every unpinned vertex
    /// free.
    pub fn coarse_level(&mut self, sys: &MembraneSystem<T>, h2: T) -> CoarseLevel {
        self.free = sys.points.pinned.iter().map(|p| !p).collect();
        self.build_models(sys, &sys.points.y);
        let mut coarse = CoarseLevel::new(&sys.nb).unwrap();
        coarse
            .factor(
                &sys.nb,
                &self.rest,
                &self.models,
                &self.free,
                h2,
                &mut self.timings,
            )
            .unwrap();
        coarse
    }

    /// `M^-1 r` ([`precondition`]) at the evaluated state of `sys`, every unpinned vertex
    /// free.
    pub fn preconditioned(
        &mut self,
        sys: &MembraneSystem<T>,
        h2: T,
        r: &[Vector3<T>],
    ) -> Vec<Vector3<T>> {
        self.free = sys.points.pinned.iter().map(|p| !p).collect();
        self.metric = (0..r.len()).map(|k| PointSystem::of(sys, k, h2)).collect();
        let mut coarse = self.coarse_level(sys, h2);
        let mut z = vec![Vector3::zeros(); r.len()];
        precondition(&self.metric, Some(&mut coarse), &self.free, r, &mut z);
        z
    }

    /// [`hessian_product`] with the models of the last [`Self::build_models`].
    pub fn product(
        &mut self,
        sys: &MembraneSystem<T>,
        h2: T,
        x: &[Vector3<T>],
        out: &mut [Vector3<T>],
    ) {
        self.free = sys.points.pinned.iter().map(|p| !p).collect();
        hessian_product(
            sys,
            &self.rest,
            &self.models,
            &self.free,
            h2,
            x,
            &mut self.bonds,
            out,
        );
    }
}

/// `out = K x` with `K = M + h^2 sum_i G_i^T H_i G_i` on the `free` vertices (the other rows
/// and columns dropped: `x` is zero there and so is `out`), kg m.
#[allow(clippy::too_many_arguments)]
pub(crate) fn hessian_product<T: Real>(
    sys: &MembraneSystem<T>,
    rest: &RestData<T>,
    models: &[VertexModel<T>],
    free: &[bool],
    h2: T,
    x: &[Vector3<T>],
    bonds: &mut [Vector3<T>],
    out: &mut [Vector3<T>],
) {
    let nb = &sys.nb;
    let mut done = vec![(); x.len()];
    for_each_vertex(&nb.offsets, bonds, &mut done, &|i, slots| {
        bond_vectors(i, x, nb.of(i), slots);
        models[i].apply(&rest.stencil(nb, i), slots);
    });
    let bonds = &*bonds;
    out.par_iter_mut().enumerate().for_each(|(k, o)| {
        *o = if free[k] {
            x[k] * sys.rest.vertices[k].mass - internal_force(k, nb, bonds) * h2
        } else {
            Vector3::zeros()
        };
    });
}

/// `sum_k a_k . b_k` in f64, the same for any thread count.
fn dot<T: Real>(a: &[Vector3<T>], b: &[Vector3<T>], sums: &mut Vec<f64>) -> f64 {
    chunked_sum(a.len(), sums, |k| a[k].dot(&b[k]).to_f64())
}

/// The CG's preconditioner, `z = M^-1 r` with `M^-1 = D^-1 + P A_c^-1 P^T` on the `free`
/// vertices (zero elsewhere): SISSM's blocks `D_k^-1 = metric[k].inverse` (block Jacobi) plus
/// the coarse level's correction when there is one. Symmetric positive definite on the free
/// vertices (see [`CoarseLevel`]); m for `r` in kg m.
pub(crate) fn precondition<T: Real>(
    metric: &[PointSystem<T>],
    coarse: Option<&mut CoarseLevel>,
    free: &[bool],
    r: &[Vector3<T>],
    z: &mut [Vector3<T>],
) {
    z.par_iter_mut().enumerate().for_each(|(k, z)| {
        *z = if free[k] {
            metric[k].inverse.mul_vector(&r[k])
        } else {
            Vector3::zeros()
        };
    });
    if let Some(c) = coarse {
        c.correct(free, r, z);
    }
}

/// Solves `K d = r` by conjugate gradients preconditioned by [`precondition`] (the coarse
/// level assembled and factored here for the current models and free set when [`Refactor`]
/// asks, else the last factor; block Jacobi alone if the factorisation fails), from `d = 0`.
fn solve_newton_system<T: Real>(sys: &MembraneSystem<T>, state: &mut NewtonState<T>, h2: T) {
    if !state.coarse_built {
        state.coarse_built = true;
        state.coarse = CoarseLevel::new(&sys.nb).ok();
    }
    let NewtonState {
        rest,
        models,
        bonds,
        metric,
        d,
        r,
        z,
        p,
        q,
        sums,
        free,
        coarse,
        refactor,
        step_start,
        products,
        timings,
        ..
    } = state;
    let mut coarse = coarse.as_mut().and_then(|c| {
        if *refactor == Refactor::Now {
            if step_start.factor.is_none() {
                step_start.factor = Some(c.factor_values().to_vec());
            }
            c.factor(&sys.nb, rest, models, free, h2, timings).ok()?;
            *refactor = Refactor::After { fresh: None };
        }
        Some(c)
    });
    let t = Instant::now();
    precondition(metric, coarse.as_deref_mut(), free, r, z);
    d.par_iter_mut().for_each(|v| *v = Vector3::zeros());
    p.copy_from_slice(z);
    let mut rz = dot(r, z, sums);
    let stop = rz * FORCING * FORCING;
    let mut count = 0;
    while rz > stop && rz > 0.0 && count < MAX_LINEAR_ITERS {
        hessian_product(sys, rest, models, free, h2, p, bonds, q);
        count += 1;
        let pq = dot(p, q, sums);
        if pq.is_nan() || pq <= 0.0 {
            break;
        }
        let a = T::of(rz / pq);
        let (p_ref, q_ref) = (&*p, &*q);
        d.par_iter_mut()
            .zip(r.par_iter_mut())
            .enumerate()
            .for_each(|(k, (d, r))| {
                *d += p_ref[k] * a;
                *r -= q_ref[k] * a;
            });
        precondition(metric, coarse.as_deref_mut(), free, r, z);
        let rz_next = dot(r, z, sums);
        let beta = T::of(rz_next / rz);
        rz = rz_next;
        let z_ref = &*z;
        p.par_iter_mut()
            .enumerate()
            .for_each(|(k, p)| *p = z_ref[k] + *p * beta);
    }
    *products += count;
    timings.cg += millis(t);
    *refactor = match *refactor {
        Refactor::After { fresh: None } => Refactor::After { fresh: Some(count) },
        Refactor::After { fresh: Some(fresh) } if count > REFACTOR_GROWTH * fresh.max(1) => {
            Refactor::Now
        }
        other => other,
    };
}

/// Before an iteration: after a contact local step (`options` carries its reactions) the
/// iterate is not the one the line search evaluated, so its responses and energy are computed
/// again.
pub(crate) fn start_iteration<T: Real>(
    sys: &mut MembraneSystem<T>,
    h: T,
    mode: Preconditioner,
    options: &MoveOptions<'_, T>,
    search: &mut LineSearch,
) {
    if !options.contact_reaction.is_empty() {
        evaluate(sys, mode);
        search.energy = total_energy(sys, h);
    }
}

/// One Newton iteration from the responses evaluated at `y` (see the module docs). Leaves the
/// accepted iterate in `y_next`, the responses evaluated there, and its energy in `search`.
pub(crate) fn newton_iteration<T: Real>(
    sys: &mut MembraneSystem<T>,
    state: &mut NewtonState<T>,
    h: T,
    mode: Preconditioner,
    options: &MoveOptions<'_, T>,
    search: &mut LineSearch,
) -> Update {
    let h2 = h * h;
    let t = Instant::now();
    let residual = jacobi_moves(sys, &mut state.metric, &mut state.z, options, |sys, k| {
        PointSystem::of(sys, k, h2)
    });
    // A vertex a collider or a membrane contact holds (its Jacobi move is pushed back, or the
    // last local step pushed it) takes its Jacobi move, as in SISSM; the CG moves the others
    // with those held fixed. The Newton system knows nothing of the contacts, and a Newton move
    // into a contact, cut by the projection, would not lower the energy.
    let NewtonState {
        metric,
        r,
        z,
        free,
        held,
        ..
    } = &mut *state;
    let metric = &*metric;
    r.par_iter_mut()
        .zip(z.par_iter_mut())
        .zip(free.par_iter_mut().zip(held.par_iter_mut()))
        .enumerate()
        .for_each(|(k, ((r, z), (free, kept)))| {
            let touching = || {
                options
                    .contact_reaction
                    .get(k)
                    .is_some_and(|c| *c != Vector3::zeros())
                    || (!options.colliders.is_empty()
                        && whole_move_reaction(sys, k, &metric[k], z, options.colliders)
                            != Vector3::zeros())
            };
            *free = !sys.points.pinned[k] && !touching();
            *kept = *z;
            if *free {
                *r = metric[k].residual;
            } else {
                *r = Vector3::zeros();
                *z = Vector3::zeros();
            }
        });
    state.timings.jacobi += millis(t);
    let t = Instant::now();
    state.build_models(sys, &sys.points.y);
    state.timings.models += millis(t);
    solve_newton_system(sys, state, h2);
    // Held vertices, and free ones whose Newton move a collider would push back, take their
    // Jacobi move.
    let NewtonState {
        d,
        held: jacobi,
        free,
        metric,
        ..
    } = &mut *state;
    let metric = &*metric;
    d.par_iter_mut()
        .zip(jacobi.par_iter().zip(free.par_iter()))
        .enumerate()
        .for_each(|(k, (d, (jacobi, free)))| {
            let pushed = || {
                !options.colliders.is_empty()
                    && whole_move_reaction(sys, k, &metric[k], d, options.colliders)
                        != Vector3::zeros()
            };
            if !*free || pushed() {
                *d = *jacobi;
            }
        });
    search.alpha = 1.0;
    let t = Instant::now();
    let (update, trials) = search_along(sys, &state.metric, &state.d, h, mode, options, search);
    state.timings.line_search += millis(t);
    state.timings.trials += trials;
    Update { residual, ..update }
}
