//! The per-vertex move of SISSM: eq. 25 in residual form, optional inner Jacobi sweeps
//! (Fig. 6), the step length of eq. 31-33, colliders in the system metric, and Chebyshev
//! extrapolation.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::contact::ColliderModel;
use crate::isa;
use crate::membrane::{internal_force, GatheredResponse};
use crate::parallel::GRAIN;
use crate::real::Real;
use crate::symmetric::SymmetricMatrix3;

use super::system::System;

/// Per-vertex outcome of an update, reduced over vertices.
#[derive(Clone, Copy)]
pub(super) struct Update {
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
        let moved = (after - before).norm().to_f64();
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

    pub const NONE: Self = Self {
        moved: 0.0,
        residual: 0.0,
        first_bad: None,
    };
}

/// What the move of one global iteration is asked to do.
#[derive(Clone, Copy)]
pub(super) struct MoveOptions<'a, T: Real> {
    /// Apply the step length of eq. 31-33.
    pub step_length: bool,
    /// Jacobi sweeps on the linear system of eq. 25 (1: the paper's default).
    pub inner_iters: usize,
    /// Chebyshev extrapolation weight of this iteration, if any.
    pub omega: Option<T>,
    pub colliders: &'a [ColliderModel<T>],
    /// Per vertex: the contact reaction the last local step realised at the current iterate
    /// (m; see [`free_residual`]), or empty when contact is off or no local step ran yet this
    /// step.
    pub contact_reaction: &'a [Vector3<T>],
}

/// The linear system of vertex `k` at the current iterate: `D delta = r` with
/// `D = m I + h^2 (n_k C_k + sum_j C_j)` and `r = m (y* - y) + h^2 f`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LocalSystem<T: Real> {
    pub mass: T,
    pub residual: Vector3<T>,
    /// `D` (kg).
    pub system: SymmetricMatrix3<T>,
    /// `D^-1` (1/kg), or `I / m` where `D` is singular (see [`LocalSystem::new`]).
    pub inverse: SymmetricMatrix3<T>,
    /// `h^2 f`.
    pub force_h2: Vector3<T>,
    /// `h^2` times the elastic energy of the vertices whose neighbourhood holds `k`.
    pub energy_h2: T,
}

impl<T: Real> LocalSystem<T> {
    /// Assembles vertex `k`'s system from the responses of the last evaluation.
    #[inline(always)]
    pub fn of(sys: &System<T>, k: usize, h2: T) -> Self {
        let mass = sys.rest.vertices[k].mass;
        let force_h2 = internal_force(k, &sys.nb, &sys.bond_grad) * h2;
        let residual = (sys.y_star[k] - sys.y[k]) * mass + force_h2;
        let neighbors = sys.nb.of(k);
        let response = &sys.response;
        let own = &response[k];
        // `n_k C_k + sum_j C_j` and `E_k + sum_j E_j`, one record at a time.
        let mut sum =
            GatheredResponse::new(own.precond() * T::of(neighbors.len() as f64), own.energy());
        for &j in neighbors {
            sum += response[j as usize];
        }
        Self::new(
            mass,
            sum.precond() * h2,
            residual,
            force_h2,
            sum.energy() * h2,
        )
    }

    /// `D = m I + stiffness` and its inverse. `D` is symmetric positive definite for a mass
    /// `m > 0` and a positive semi-definite `stiffness` (kg); should round-off or a non-finite
    /// stiffness still make it exactly singular, the inverse falls back to `I / m`, the
    /// explicit move `r / m` (a non-finite result is then caught as divergence).
    #[inline]
    pub fn new(
        mass: T,
        stiffness: SymmetricMatrix3<T>,
        residual: Vector3<T>,
        force_h2: Vector3<T>,
        energy_h2: T,
    ) -> Self {
        let system = stiffness.plus_identity(mass);
        let inverse = system
            .try_inverse()
            .unwrap_or_else(|| SymmetricMatrix3::from_diagonal(&Vector3::repeat(T::one() / mass)));
        Self {
            mass,
            residual,
            system,
            inverse,
            force_h2,
            energy_h2,
        }
    }

    /// One Jacobi solve, `D^-1 r`.
    #[inline]
    pub fn solve(&self) -> Vector3<T> {
        self.inverse.mul_vector(&self.residual)
    }

    /// The step length of eq. 31-33 for the move `delta`: `alpha = E / (h^2 f . delta)` where
    /// the linearised elastic energy would drop below zero, else 1. The cut applies only when
    /// that elastic release is a sizeable part of the move's inertial cost,
    /// `h^2 f . delta > STEP_LENGTH_SIGNIFICANCE m |delta|^2`: below it the release is either
    /// harmless or round-off (a vertex at rest has `E` and `f` at round-off level, and cutting
    /// there would freeze it).
    #[inline]
    pub fn step_length(&self, delta: &Vector3<T>) -> T {
        let descent = self.force_h2.dot(delta);
        let significant =
            descent > T::of(STEP_LENGTH_SIGNIFICANCE) * self.mass * delta.norm_squared();
        if descent > self.energy_h2 && significant {
            self.energy_h2.max(T::zero()) / descent
        } else {
            T::one()
        }
    }
}

/// See [`LocalSystem::step_length`].
const STEP_LENGTH_SIGNIFICANCE: f64 = 0.1;

/// The move of one SISSM iteration from the responses of the last evaluation, written to
/// `y_next`.
pub(super) fn jacobi_update<T: Real>(
    sys: &mut System<T>,
    h: T,
    options: &MoveOptions<'_, T>,
) -> Update {
    let h2 = h * h;
    let inner = options.inner_iters > 1;
    if inner {
        inner_sweeps(sys, h2, options.inner_iters);
    }
    let mut y_next = std::mem::take(&mut sys.y_next);
    let sys_ref = &*sys;
    let update = y_next
        .par_chunks_mut(GRAIN)
        .enumerate()
        .map(|(c, next)| {
            isa::run(
                #[inline(always)]
                || move_vertices(sys_ref, c * GRAIN, next, h2, options),
            )
        })
        .reduce(|| Update::NONE, Update::merge);
    sys.y_next = y_next;
    update
}

/// The moves of the vertices `first..first + next.len()` into `next` (see [`jacobi_update`]),
/// merged. Inlined into each copy [`isa::run`] chooses from.
#[inline(always)]
fn move_vertices<T: Real>(
    sys: &System<T>,
    first: usize,
    next: &mut [Vector3<T>],
    h2: T,
    options: &MoveOptions<'_, T>,
) -> Update {
    let inner = options.inner_iters > 1;
    let mut update = Update::NONE;
    for (k, next) in (first..).zip(next) {
        if sys.pinned[k] {
            *next = sys.y[k];
            continue;
        }
        let (local, delta) = if inner {
            (sys.locals[k], sys.delta[k])
        } else {
            let local = LocalSystem::of(sys, k, h2);
            (local, local.solve())
        };
        update = Update::merge(update, finish_move(sys, k, &local, delta, options, next));
    }
    update
}

/// Scales `delta` by the step length, keeps it out of colliders in the system metric,
/// extrapolates (Chebyshev) and reports the vertex's move and residual.
#[inline(always)]
fn finish_move<T: Real>(
    sys: &System<T>,
    k: usize,
    local: &LocalSystem<T>,
    delta: Vector3<T>,
    options: &MoveOptions<'_, T>,
    next: &mut Vector3<T>,
) -> Update {
    let alpha = if options.step_length {
        local.step_length(&delta)
    } else {
        T::one()
    };
    let margin = sys.rest.vertices[k].half_thickness;
    let y = sys.y[k];
    let free_move = y + delta * alpha;
    *next = keep_out(
        free_move,
        &sys.y_start[k],
        &local.inverse,
        margin,
        options.colliders,
    );
    // Chebyshev extrapolates the unconstrained iteration only: a vertex a collider holds keeps
    // its projected position, else the extrapolation would push it along the contact past
    // what its friction cone allows (a resting cloth would creep).
    if let Some(w) = options.omega.filter(|_| *next == free_move) {
        *next = (*next - sys.y_prev[k]) * w + sys.y_prev[k];
    }
    Update {
        residual: free_residual(sys, k, local, options),
        ..Update::of(k, &y, next)
    }
}

/// `inner` Jacobi sweeps on the linear system of eq. 25, `(M + h^2 L) delta = r` with `L` the
/// bond Laplacian of weights `C_i + C_j`: `delta_k <- D_k^-1 (r_k + h^2 sum_j (C_k + C_j) delta_j)`.
/// Leaves each vertex's system in `locals` and the result in `delta`.
fn inner_sweeps<T: Real>(sys: &mut System<T>, h2: T, inner: usize) {
    let n = sys.y.len();
    let mut locals = std::mem::take(&mut sys.locals);
    let mut delta = std::mem::take(&mut sys.delta);
    let mut scratch = std::mem::take(&mut sys.delta_next);
    if locals.len() != n {
        let zero = LocalSystem::new(
            T::one(),
            SymmetricMatrix3::zeros(),
            Vector3::zeros(),
            Vector3::zeros(),
            T::zero(),
        );
        locals = vec![zero; n];
        delta = vec![Vector3::zeros(); n];
        scratch = vec![Vector3::zeros(); n];
    }
    let sys_ref = &*sys;
    locals
        .par_iter_mut()
        .zip(delta.par_iter_mut())
        .enumerate()
        .for_each(|(k, (local, d))| {
            *local = LocalSystem::of(sys_ref, k, h2);
            *d = if sys_ref.pinned[k] {
                Vector3::zeros()
            } else {
                local.solve()
            };
        });
    for _ in 1..inner {
        let (nb, response, pinned) = (&sys.nb, &sys.response, &sys.pinned);
        scratch.par_iter_mut().enumerate().for_each(|(k, out)| {
            if pinned[k] {
                *out = Vector3::zeros();
                return;
            }
            let mut sum = Vector3::zeros();
            let mut weighted = Vector3::zeros();
            for &j in nb.of(k) {
                sum += delta[j as usize];
                weighted += response[j as usize]
                    .precond()
                    .mul_vector(&delta[j as usize]);
            }
            let coupling = (response[k].precond().mul_vector(&sum) + weighted) * h2;
            *out = locals[k]
                .inverse
                .mul_vector(&(locals[k].residual + coupling));
        });
        std::mem::swap(&mut delta, &mut scratch);
    }
    sys.locals = locals;
    sys.delta = delta;
    sys.delta_next = scratch;
}

/// Keeps a move out of the colliders in the metric of its system matrix `D`, with Coulomb
/// friction.
///
/// Where `y` would end inside a collider (closer than `margin`), it moves along `D^-1 n`
/// instead of `n`: it solves `min 1/2 d^T D d - r^T d` on the tangent plane of the contact,
/// with the normal reaction `lambda = -gap / (n . D^-1 n)` (N s^2). A Euclidean projection
/// with an anisotropic `D` would leave a tangential residual `lambda (D n)_t` at its fixed
/// point: frictionless contact would stick.
///
/// Friction: the slip `s_t` of the vertex relative to the collider over the whole step
/// (from `start`, the collider's material point under `y` moving by its displacement) is removed when the reaction that
/// takes, `k |s_t|` with `k = |s_t|^2 / (s_t . D^-1 s_t)` the stiffness along it, is within
/// the Coulomb cone `friction * lambda` (sticking), and shortened by `friction * lambda / k`
/// otherwise (sliding).
#[inline]
pub(super) fn keep_out<T: Real>(
    mut y: Vector3<T>,
    start: &Vector3<T>,
    inverse: &SymmetricMatrix3<T>,
    margin: T,
    colliders: &[ColliderModel<T>],
) -> Vector3<T> {
    for c in colliders {
        let gap = c.signed_distance(&y) - margin;
        if gap >= T::zero() {
            continue;
        }
        let n = c.normal(&y);
        let along = inverse.mul_vector(&n);
        let reach = n.dot(&along);
        if reach <= T::zero() {
            continue;
        }
        let reaction = -gap / reach;
        y += along * reaction;
        if c.friction > T::zero() {
            let slip = (y - start) - c.displacement(&y);
            let slip_t = slip - n * n.dot(&slip);
            let compliance = slip_t.dot(&inverse.mul_vector(&slip_t));
            if compliance > T::zero() {
                let needed = slip_t.norm_squared() * slip_t.norm() / compliance;
                let budget = c.friction * reaction;
                y -= slip_t
                    * if needed <= budget {
                        T::one()
                    } else {
                        budget / needed
                    };
            }
        }
    }
    y
}

/// The convergence measure of vertex `k`, `|r_free| / m` (m): its residual `r` at the current
/// iterate `y` without the reactions of the contacts it is in.
///
/// Membrane contact: the global step sends `y` to `y^k = y + D^-1 r`, and the local step
/// (Algorithm 2) moves that to `z`. At a fixed point `z = y`, so `r = -D (z - y^k)`: the local
/// step's move, weighted by `D`, is the reaction that balances the residual. Only its part
/// along the barrier's push `p_i` (the contact normals weighted by the closest-point weights)
/// counts as reaction, `q_i = n_i max(n_i . (z_i - y_i^k), 0)` with `n_i = p_i / |p_i|`, and
/// what is measured is `r + D q` with the `q` of the local step that produced `y`. So a vertex
/// out of the barrier's reach (in free flight) keeps its whole residual, and a tangential
/// imbalance (sliding not yet resolved, or held back by a CCD clamp) stays in the measure;
/// and the measure vanishes only where the local step's push and the global step's pull
/// balance, not merely where a pair is close. The first iteration of a step, before any local
/// step, has no `q` and measures the whole residual (and cannot decide convergence, see
/// [`super::sissm`]).
///
/// Colliders: see [`without_contact_reaction`].
#[inline]
pub(super) fn free_residual<T: Real>(
    sys: &System<T>,
    k: usize,
    local: &LocalSystem<T>,
    options: &MoveOptions<'_, T>,
) -> f64 {
    let mut residual = local.residual;
    if let Some(reaction) = options.contact_reaction.get(k) {
        residual += local.system.mul_vector(reaction);
    }
    let free = without_contact_reaction(
        residual,
        &sys.y[k],
        &sys.y_start[k],
        sys.rest.vertices[k].half_thickness,
        options.colliders,
    );
    (free.norm() / local.mass).to_f64()
}

/// The residual without the part the colliders the vertex touches balance at the solution:
/// the push into the collider, and the Coulomb friction `friction * |push|`: against the slip
/// when the vertex slides relative to the collider (kinetic friction is exactly that), as much
/// of the tangential part as the cone holds when it does not (static friction).
#[inline]
fn without_contact_reaction<T: Real>(
    mut residual: Vector3<T>,
    y: &Vector3<T>,
    start: &Vector3<T>,
    margin: T,
    colliders: &[ColliderModel<T>],
) -> Vector3<T> {
    let slack = T::of(1e-6).max(margin * T::of(1e-3));
    for c in colliders {
        if c.signed_distance(y) > margin + slack {
            continue;
        }
        let n = c.normal(y);
        let push = residual.dot(&n);
        if push >= T::zero() {
            continue;
        }
        residual -= n * push;
        if c.friction > T::zero() {
            let held = c.friction * (-push);
            let slip = (y - start) - c.displacement(y);
            let slip_t = slip - n * n.dot(&slip);
            let sliding = slip_t.norm() > T::of(SLIP) * (T::one() + y.norm());
            let tangential = residual - n * residual.dot(&n);
            if sliding {
                residual -= slip_t.normalize() * held;
            } else if tangential.norm() > T::zero() {
                residual -= tangential * (held / tangential.norm()).min(T::one());
            }
        }
    }
    residual
}

/// Relative slip (per metre of position) below which a vertex counts as sticking.
const SLIP: f64 = 1e-6;

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
                let local = LocalSystem::new(
                    1.0,
                    SymmetricMatrix3::from_diagonal(&Vector3::repeat(a)),
                    r,
                    Vector3::zeros(),
                    0.0,
                );
                let step = local.solve().x;
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

    /// Eq. 33: the step stops where the linearised energy reaches zero, and round-off-sized
    /// releases do not cut the step.
    #[test]
    fn step_length_stops_the_linearised_energy_at_zero() {
        let f = Vector3::new(2.0f64, 0.0, 0.0);
        let r = Vector3::new(4.0, 0.0, 0.0);
        let local =
            |force, energy| LocalSystem::new(1.0, SymmetricMatrix3::zeros(), r, force, energy);
        assert_eq!(local(f, 100.0).step_length(&r), 1.0);
        let limited = r * local(f, 2.0).step_length(&r);
        assert!((2.0 - f.dot(&limited)).abs() < 1e-15);
        // A vertex at rest: zero energy and a round-off force must still take its full step.
        assert_eq!(
            local(Vector3::new(1e-13, 0.0, 0.0), 0.0).step_length(&r),
            1.0
        );
    }
}
