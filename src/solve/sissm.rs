//! The SISSM time step (Lu et al. 2023, Algorithm 1 without the contact local step).
//!
//! Implicit Euler asks for `m_i (y_i - y*_i) = h^2 f_i(y)` with `y* = y_t + h v_t + h^2 g`.
//! Each global iteration takes, per vertex and independently (one Jacobi sweep of eq. 25),
//!
//! `delta_i = (m_i I + h^2 sum_j (C_i + C_j))^-1 (m_i (y*_i - y_i) + h^2 f_i(y))`
//!
//! which is eq. 25-26 written in residual form: `A_ij = h^2 (C_i + C_j)` are the implicit
//! (positive) blocks and every other part of the exact force is explicit. The fixed point is
//! therefore the exact implicit Euler solution for any `C`. The step is scaled by the
//! per-vertex step length of eq. 31-33, `alpha_i = min(E_i / (f_i . delta_i), 1)`, where `E_i`
//! is the elastic energy of the vertices whose neighbourhood holds `i` (zero elastic energy is a
//! lower bound the linearised energy may not cross). Colliders project the result.
//!
//! The iteration starts from the lower-energy of `y*` and `y_t` ([`initial_guess`]) and stops
//! when `max_i |r_i| / m_i < tol` for the residual `r = m (y* - y) + h^2 f` (without the push
//! into colliders the vertex touches). Where the energy is convex its Hessian `H` satisfies
//! `H >= M`, so the error `e = H^-1 r` obeys `|e|_M <= |r|_(M^-1)`: the test bounds the
//! mass-weighted RMS distance to the exact implicit Euler solution. Algorithm 1 tests the last
//! move `max_i |y_i^{k+1} - y_i^k|` instead, which declares slowly converging (stiff, fine)
//! problems solved far from their solution; that move is still reported as the residual history.

use std::time::Instant;

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::contact::{Collider, ColliderModel};
use crate::error::{Error, Result};
use crate::membrane::{internal_force, vertex_kernel, Membrane, Preconditioner};
use crate::parallel::for_each_vertex;
use crate::real::Real;

use super::system::System;
use super::{Acceleration, SolverParams, StepStats, Timings};

/// Steps a set of membranes in time.
pub struct Solver<T: Real> {
    params: SolverParams,
    colliders: Vec<Collider>,
    pool: Option<rayon::ThreadPool>,
    system: Option<System<T>>,
    time: f64,
    steps: u64,
}

/// Per-vertex outcome of an update: how far it moved, and whether it became non-finite.
#[derive(Clone, Copy)]
struct Update {
    /// Largest move `|y_i^{k+1} - y_i^k|` (m).
    moved: f64,
    /// Largest `|r_i| / m_i` at `y^k` (m), contact reactions removed: see [`Solver`].
    residual: f64,
    first_bad: Option<usize>,
}

impl Update {
    fn of<T: Real>(vertex: usize, before: &Vector3<T>, after: &Vector3<T>) -> Self {
        let finite = after.iter().all(|c| c.is_finite());
        let moved = (after - before).norm().to_f64();
        Self {
            moved: if finite { moved } else { 0.0 },
            residual: 0.0,
            first_bad: (!finite).then_some(vertex),
        }
    }

    /// Associative and commutative, so the reduction is the same for any thread count.
    fn merge(a: Self, b: Self) -> Self {
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

    const NONE: Self = Self {
        moved: 0.0,
        residual: 0.0,
        first_bad: None,
    };
}

fn millis(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

impl<T: Real> Solver<T> {
    /// A solver with `threads` workers (`None`: rayon's global pool, one per core).
    pub fn new(params: SolverParams, threads: Option<usize>) -> Result<Self> {
        params.validate()?;
        let pool = match threads {
            None => None,
            Some(0) => return Err(crate::error::invalid!("threads must be >= 1, got 0")),
            Some(n) => Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .map_err(|e| crate::error::invalid!("cannot start {n} threads: {e}"))?,
            ),
        };
        Ok(Self {
            params,
            colliders: Vec::new(),
            pool,
            system: None,
            time: 0.0,
            steps: 0,
        })
    }

    pub fn params(&self) -> &SolverParams {
        &self.params
    }

    /// Replaces the parameters (validated).
    pub fn set_params(&mut self, params: SolverParams) -> Result<()> {
        params.validate()?;
        self.params = params;
        Ok(())
    }

    /// Number of worker threads used by `step`.
    pub fn threads(&self) -> usize {
        self.pool
            .as_ref()
            .map_or_else(rayon::current_num_threads, |p| p.current_num_threads())
    }

    pub fn add_collider(&mut self, collider: Collider) {
        self.colliders.push(collider);
    }

    pub fn colliders(&self) -> &[Collider] {
        &self.colliders
    }

    /// Simulation time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Steps taken so far.
    pub fn steps_taken(&self) -> u64 {
        self.steps
    }

    /// Advances `bodies` by one time step. On divergence the bodies keep their state and an
    /// [`Error::Diverged`] names the first non-finite vertex.
    pub fn step(&mut self, bodies: &mut [&mut Membrane]) -> Result<StepStats> {
        match self.pool.take() {
            Some(pool) => {
                let out = pool.install(|| self.step_in_pool(bodies));
                self.pool = Some(pool);
                out
            }
            None => self.step_in_pool(bodies),
        }
    }

    fn step_in_pool(&mut self, bodies: &mut [&mut Membrane]) -> Result<StepStats> {
        let started = Instant::now();
        let params = self.params;
        if !self.system.as_ref().is_some_and(|s| s.matches(bodies)) {
            self.system = Some(System::build(bodies));
        }
        let colliders: Vec<ColliderModel<T>> = self.colliders.iter().map(|c| c.to_real()).collect();
        let sys = self.system.as_mut().expect("built above");
        let h = T::of(params.dt);
        let gravity = Vector3::from(params.gravity).map(T::of);

        sys.load(bodies);
        predict(sys, h, gravity);
        let mut energy = initial_guess(sys, h, params.preconditioner);
        let mut timings = Timings {
            predict: millis(started),
            ..Timings::default()
        };

        let mut stats = StepStats {
            step: self.steps,
            residuals: Vec::with_capacity(params.max_iters.min(4096)),
            energies: Vec::with_capacity(if params.record_energy {
                params.max_iters.min(4096) + 1
            } else {
                0
            }),
            ..StepStats::default()
        };
        let accelerated = params.acceleration != Acceleration::None;
        if accelerated && sys.y_prev.len() != sys.y.len() {
            sys.y_prev = sys.y.clone();
        }
        let mut omega = 1.0;
        for iteration in 0..params.max_iters {
            let t = Instant::now();
            if iteration > 0 {
                evaluate(sys, params.preconditioner);
                if params.record_energy {
                    energy = total_energy(sys, h);
                }
            }
            if params.record_energy {
                stats.energies.push(energy);
            }
            let extrapolation = params.acceleration.omega(iteration, omega);
            omega = extrapolation.unwrap_or(1.0);
            let mut update = jacobi_update(
                sys,
                h,
                params.step_length,
                extrapolation.map(T::of),
                &colliders,
            );
            timings.global += millis(t);
            if !colliders.is_empty() {
                let t = Instant::now();
                let projected = project_colliders(sys, &colliders);
                update = Update {
                    residual: update.residual,
                    ..Update::merge(update, projected)
                };
                update.moved = projected.moved;
                timings.colliders += millis(t);
            }
            if let Some(vertex) = update.first_bad {
                let (body, vertex) = sys.locate(vertex);
                return Err(Error::Diverged {
                    step: self.steps,
                    iteration,
                    body,
                    vertex,
                });
            }
            if accelerated {
                std::mem::swap(&mut sys.y_prev, &mut sys.y);
            }
            std::mem::swap(&mut sys.y, &mut sys.y_next);
            stats.iterations = iteration + 1;
            stats.residual = update.moved;
            stats.residuals.push(update.moved);
            stats.error_estimate = update.residual;
            if params.tol > 0.0 && stats.error_estimate < params.tol {
                stats.converged = true;
                break;
            }
        }

        if params.record_energy {
            let t = Instant::now();
            evaluate(sys, params.preconditioner);
            stats.energies.push(total_energy(sys, h));
            timings.global += millis(t);
        }

        let t = Instant::now();
        finish(sys, h);
        sys.store(bodies);
        timings.finish = millis(t);
        self.time += params.dt;
        self.steps += 1;
        timings.total = millis(started);
        stats.time = self.time;
        stats.timings = timings;
        Ok(stats)
    }
}

/// `y* = y_t + h v_t + h^2 g` for free vertices; the initial iterate is `y*` (Algorithm 1, line 2).
fn predict<T: Real>(sys: &mut System<T>, h: T, gravity: Vector3<T>) {
    let (y_start, velocity, pinned) = (&sys.y_start, &sys.velocity, &sys.pinned);
    let kick = gravity * (h * h);
    sys.y_star.par_iter_mut().enumerate().for_each(|(i, star)| {
        if !pinned[i] {
            *star = y_start[i] + velocity[i] * h + kick;
        }
    });
    sys.y.copy_from_slice(&sys.y_star);
}

/// Starts the iteration from whichever of the inertial prediction `y*` (Algorithm 1, line 2) and
/// the previous positions `y_t` has the lower variational energy, and returns that energy;
/// the responses are left evaluated at the chosen start.
///
/// `y*` is exact in free flight, but for a stiff body it can hold a large elastic energy
/// (a pinned sheet's first row of bonds stretched by `h^2 g`); starting there, a step that runs
/// out of iterations releases that energy as spurious motion. From `y_t` an unfinished step
/// moves too little instead, which dissipates. `E(y*)` is the elastic energy `U(y*)`, and
/// `E(y_t) >= m |y_t - y*|^2 / (2 h^2)`, so `y_t` is evaluated only when `U(y*)` exceeds that
/// inertial term: most dynamic steps cost one kernel pass here, not two.
fn initial_guess<T: Real>(sys: &mut System<T>, h: T, mode: Preconditioner) -> f64 {
    evaluate(sys, mode);
    let at_prediction = total_energy(sys, h);
    let inertia_of_previous = inertial_energy(sys, h, true);
    if at_prediction <= inertia_of_previous {
        return at_prediction;
    }
    let (y_start, y_star, pinned) = (&sys.y_start, &sys.y_star, &sys.pinned);
    sys.y.par_iter_mut().enumerate().for_each(|(i, y)| {
        *y = if pinned[i] { y_star[i] } else { y_start[i] };
    });
    evaluate(sys, mode);
    let at_previous = total_energy(sys, h);
    if at_previous < at_prediction {
        at_previous
    } else {
        sys.y.copy_from_slice(&sys.y_star);
        evaluate(sys, mode);
        at_prediction
    }
}

/// The vertex kernel at every vertex of the current iterate `y`.
fn evaluate<T: Real>(sys: &mut System<T>, mode: Preconditioner) {
    let (nb, rest, y) = (&sys.nb, &sys.rest, &sys.y);
    for_each_vertex(
        &nb.offsets,
        &mut sys.bond_grad,
        &mut sys.response,
        &|i, grads: &mut [Vector3<T>]| vertex_kernel(y[i], y, &rest.stencil(nb, i), mode, grads),
    );
}

/// Vertices per partial sum of the energy reductions: fixed, so that the sums do not depend
/// on the number of threads.
const ENERGY_CHUNK: usize = 4096;

/// `sum_i term(i)` for `i < n`, summed in fixed chunks (the same for any thread count) whose
/// partial sums go to the reused `scratch`.
fn chunked_sum(n: usize, scratch: &mut Vec<f64>, term: impl Fn(usize) -> f64 + Sync) -> f64 {
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

/// `sum_i m_i |x_i - y*_i|^2 / (2 h^2)` (J) over free vertices, for `x` = `y` or `y_start`.
fn inertial_energy<T: Real>(sys: &mut System<T>, h: T, at_start: bool) -> f64 {
    let inv_2h2 = 0.5 / (h.to_f64() * h.to_f64());
    let System {
        y,
        y_start,
        y_star,
        pinned,
        rest,
        energy_chunks,
        ..
    } = sys;
    let x = if at_start { &*y_start } else { &*y };
    chunked_sum(x.len(), energy_chunks, |i| {
        if pinned[i] {
            0.0
        } else {
            (x[i] - y_star[i]).norm_squared().to_f64() * rest.vertices[i].mass.to_f64() * inv_2h2
        }
    })
}

/// `E(y) = sum_i m_i |y_i - y*_i|^2 / (2 h^2) + sum_i E_i(y)` (eq. 2 without the barrier, J), from
/// the responses of the last [`evaluate`].
fn total_energy<T: Real>(sys: &mut System<T>, h: T) -> f64 {
    let elastic = {
        let System {
            response,
            energy_chunks,
            ..
        } = &mut *sys;
        chunked_sum(response.len(), energy_chunks, |i| {
            response[i].energy().to_f64()
        })
    };
    inertial_energy(sys, h, false) + elastic
}

/// The per-vertex Jacobi update with step length (and the Chebyshev extrapolation `omega` when
/// given) from the responses of the last [`evaluate`], written to `y_next`.
fn jacobi_update<T: Real>(
    sys: &mut System<T>,
    h: T,
    step_length: bool,
    omega: Option<T>,
    colliders: &[ColliderModel<T>],
) -> Update {
    let (nb, rest, y, y_prev) = (&sys.nb, &sys.rest, &sys.y, &sys.y_prev);
    let (bond_grad, response, y_star, pinned) =
        (&sys.bond_grad, &sys.response, &sys.y_star, &sys.pinned);
    let h2 = h * h;
    sys.y_next
        .par_iter_mut()
        .enumerate()
        .map(|(k, next)| {
            if pinned[k] {
                *next = y[k];
                return Update::NONE;
            }
            let mass = rest.vertices[k].mass;
            let force = internal_force(k, nb, bond_grad);
            let residual = (y_star[k] - y[k]) * mass + force * h2;
            let neighbors = nb.of(k);
            let mut stiffness = response[k].precond * T::of(neighbors.len() as f64);
            let mut energy = response[k].energy();
            for &j in neighbors {
                stiffness += response[j as usize].precond;
                energy += response[j as usize].energy();
            }
            let (delta, inverse) = jacobi_step(
                mass,
                stiffness * h2,
                residual,
                force * h2,
                step_length.then_some(energy * h2),
            );
            *next = keep_out(
                y[k] + delta,
                &inverse,
                rest.vertices[k].half_thickness,
                colliders,
            );
            if let Some(w) = omega {
                *next = (*next - y_prev[k]) * w + y_prev[k];
            }
            let free = without_contact_reaction(
                residual,
                &y[k],
                rest.vertices[k].half_thickness,
                colliders,
            );
            Update {
                residual: (free.norm() / mass).to_f64(),
                ..Update::of(k, &y[k], next)
            }
        })
        .reduce(|| Update::NONE, Update::merge)
}

/// The residual without the part a collider the vertex touches pushes back: the component
/// into the collider, which the contact reaction balances at the solution.
#[inline]
fn without_contact_reaction<T: Real>(
    mut residual: Vector3<T>,
    y: &Vector3<T>,
    margin: T,
    colliders: &[ColliderModel<T>],
) -> Vector3<T> {
    let slack = T::of(1e-6).max(margin * T::of(1e-3));
    for c in colliders {
        if c.signed_distance(y) <= margin + slack {
            let n = c.normal(y);
            let push = residual.dot(&n);
            if push < T::zero() {
                residual -= n * push;
            }
        }
    }
    residual
}

/// One vertex's SISSM move (eq. 25 in residual form, with the step length of eq. 31-33):
/// `delta = D^-1 r` with `D = m I + A`, `A` the implicit stiffness and `r = m (y* - y) + h^2 f`
/// (all forces already times `h^2`). With `A = 0` this is plain successive substitution.
///
/// Given the vertex's elastic energy `E >= 0` (times `h^2`), the move is scaled by
/// `alpha = E / (h^2 f . delta)` where the linearised elastic energy would drop below zero
/// (eq. 33). The cut applies only when that elastic release is a sizeable part of the move's
/// inertial cost, `h^2 f . delta > STEP_LENGTH_SIGNIFICANCE m |delta|^2`: below it the
/// release is either harmless or rounding noise (a vertex at rest has `E` and `f` at round-off
/// level, and cutting there would freeze it).
///
/// Returns the move and `D^-1`.
#[inline]
pub fn jacobi_step<T: Real>(
    mass: T,
    stiffness: Matrix3<T>,
    residual: Vector3<T>,
    force_h2: Vector3<T>,
    energy_h2: Option<T>,
) -> (Vector3<T>, Matrix3<T>) {
    let system = Matrix3::from_diagonal_element(mass) + stiffness;
    let inverse = system
        .try_inverse()
        .unwrap_or_else(|| Matrix3::from_diagonal_element(T::one() / mass));
    let delta = inverse * residual;
    let Some(energy_h2) = energy_h2 else {
        return (delta, inverse);
    };
    let descent = force_h2.dot(&delta);
    let significant = descent > T::of(STEP_LENGTH_SIGNIFICANCE) * mass * delta.norm_squared();
    if descent > energy_h2 && significant {
        (delta * (energy_h2.max(T::zero()) / descent), inverse)
    } else {
        (delta, inverse)
    }
}

/// Keeps a Jacobi move out of the colliders in the metric of its system matrix `D`: where
/// `y` would end inside (closer than `margin`), it moves along `D^-1 n` instead of `n`, i.e.
/// it solves `min 1/2 d^T D d - r^T d` subject to the tangent plane of the contact. A
/// Euclidean projection with an anisotropic `D` would leave a tangential residual
/// `lambda (D n)_t` at its fixed point: frictionless contact would stick.
#[inline]
fn keep_out<T: Real>(
    mut y: Vector3<T>,
    inverse: &Matrix3<T>,
    margin: T,
    colliders: &[ColliderModel<T>],
) -> Vector3<T> {
    for c in colliders {
        let gap = c.signed_distance(&y) - margin;
        if gap < T::zero() {
            let n = c.normal(&y);
            let along = inverse * n;
            let reach = n.dot(&along);
            if reach > T::zero() {
                y -= along * (gap / reach);
            }
        }
    }
    y
}

/// See [`jacobi_step`].
const STEP_LENGTH_SIGNIFICANCE: f64 = 0.1;

/// Projects the free vertices of `y_next` out of the colliders and measures the move from `y`.
fn project_colliders<T: Real>(sys: &mut System<T>, colliders: &[ColliderModel<T>]) -> Update {
    let (y, pinned, rest) = (&sys.y, &sys.pinned, &sys.rest);
    sys.y_next
        .par_iter_mut()
        .enumerate()
        .map(|(k, next)| {
            if !pinned[k] {
                let margin = rest.vertices[k].half_thickness;
                for c in colliders {
                    *next = c.project(*next, margin);
                }
            }
            Update::of(k, &y[k], next)
        })
        .reduce(|| Update::NONE, Update::merge)
}

/// `v_{t+1} = (y_{t+1} - y_t) / h`, `y_t <- y_{t+1}`.
fn finish<T: Real>(sys: &mut System<T>, h: T) {
    let inv_h = T::one() / h;
    let y = &sys.y;
    sys.velocity
        .par_iter_mut()
        .zip(sys.y_start.par_iter_mut())
        .enumerate()
        .for_each(|(i, (v, start))| {
            *v = (y[i] - *start) * inv_h;
            *start = y[i];
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scalar example of eq. 28-29: `x = (x - 2)^2` from `x = 0.5`. Written as
    /// `m (x - 0) = f(x)` with `m = 1`, `f(x) = x^2 - 4x + 4`, plain substitution (`A = 0`)
    /// wanders off, while treating the `-4x` part implicitly (`A = 4`) converges to the root 1.
    #[test]
    fn semi_implicit_substitution_solves_the_scalar_example_plain_substitution_does_not() {
        // Returns the final x and the largest move over the last 10 of 60 substitutions.
        let iterate = |a: f64| {
            let (mut x, mut late_move) = (0.5f64, 0.0f64);
            for k in 0..60 {
                let r = Vector3::new((x - 2.0) * (x - 2.0) - x, 0.0, 0.0);
                let step = jacobi_step(
                    1.0,
                    Matrix3::from_diagonal_element(a),
                    r,
                    Vector3::zeros(),
                    None,
                )
                .0
                .x;
                x += step;
                if k >= 50 {
                    late_move = late_move.max(step.abs());
                }
            }
            (x, late_move)
        };
        let (root, late_move) = iterate(4.0);
        assert!(
            (root - 1.0).abs() < 1e-12 && late_move < 1e-12,
            "SISSM: {root}, {late_move}"
        );
        let (_, late_move) = iterate(0.0);
        assert!(
            late_move > 0.1,
            "plain substitution settled: last moves {late_move}"
        );
    }

    /// Eq. 33: the step stops where the linearised energy reaches zero.
    #[test]
    fn step_length_stops_the_linearised_energy_at_zero() {
        let f = Vector3::new(2.0f64, 0.0, 0.0);
        let r = Vector3::new(4.0, 0.0, 0.0);
        assert_eq!(jacobi_step(1.0, Matrix3::zeros(), r, f, Some(100.0)).0, r);
        let limited = jacobi_step(1.0, Matrix3::zeros(), r, f, Some(2.0)).0;
        assert!((2.0 - f.dot(&limited)).abs() < 1e-15);
        // A vertex at rest: zero energy and a round-off force must still take its full step.
        let noise = Vector3::new(1e-13, 0.0, 0.0);
        assert_eq!(jacobi_step(1.0, Matrix3::zeros(), r, noise, Some(0.0)).0, r);
    }
}
