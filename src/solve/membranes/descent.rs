//! The baseline of the paper's Fig. 13: Jacobi-preconditioned gradient descent on the
//! variational energy with an adaptive step length (Wang and Yang 2016, "Descent methods for
//! elastic body simulation on the GPU"), optionally Chebyshev-accelerated. Their paper is not
//! in `/work/shared/papers`; this follows its abstract (Jacobi preconditioning, Chebyshev
//! acceleration, no dot products) and Lu et al. 2023's account of its line search (section 1:
//! the Armijo condition with `lambda = 0`, values of `alpha` reused across iterations).
//!
//! Implicit Euler minimises `E(y) = sum_k m_k |y_k - y*_k|^2 / (2 h^2) + U(y)` (J). Scaled by
//! `h^2`, its gradient is `-r` with `r_k = m_k (y*_k - y_k) + h^2 f_k(y)` (kg m) and its Hessian
//! is `M + h^2 d^2U/dy^2`. One iteration moves every free vertex by
//!
//! `y_k <- y_k + alpha P_k^-1 r_k`, `P_k = diag(m_k + h^2 max(H_kk,aa, 0))` (kg),
//!
//! with `H_kk` the exact diagonal 3x3 block of the elastic Hessian at `y`
//! ([`crate::membrane::vertex_hessian_blocks`], N/m) and `a` the three axes: the Jacobi
//! preconditioner, i.e. the diagonal entries of the Hessian of `h^2 E`. A diagonal entry of the
//! elastic Hessian is negative only where the energy is non-convex along that axis (a
//! compressed or buckling neighbourhood); it is floored at zero, so `P_k >= m_k I > 0` and the
//! move is a descent direction of `E` wherever `r != 0`. (SISSM's `D` of
//! [`crate::solve::point_system::PointSystem`] bounds the energy's curvature, the coupling to the
//! neighbours included; this diagonal does not, so a unit step can overshoot, and the line
//! search is what keeps the iteration stable.)
//!
//! Step length (dot-product free: a trial is accepted when the energy does not rise, Armijo
//! with `lambda = 0`): `alpha` starts at 1 each time step and is kept across
//! iterations; when a trial raises `E` (beyond round-off) it is rejected, `alpha` halves, the
//! Chebyshev sequence restarts ([`LineSearch::restarted`]) and the trial is redone from the same
//! iterate without extrapolation. `alpha` never grows back within the step. Every trial costs a
//! kernel evaluation and an energy reduction, and every accepted iterate a Hessian diagonal.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::collider::{push_out_of_colliders, MoveStart};
use crate::error::Result;
use crate::membrane::{
    hessian_diagonal_block, internal_force, vertex_hessian_blocks, Membrane, Preconditioner,
    RestData,
};
use crate::real::Real;
use crate::symmetric::SymmetricMatrix3;

use super::evaluate::{evaluate, total_energy};
use super::jacobi::{free_residual, whole_move_reaction};
use super::system::MembraneSystem;
use crate::collider::push_out_with_friction;
use crate::solve::point_system::PointSystem;
use crate::solve::update::{MoveOptions, Update};

/// Halvings of the step length tried before the iterate is kept unchanged (`2^-40`: far below
/// any step that can still lower an f64 energy).
const MAX_HALVINGS: usize = 40;

/// Relative energy change treated as round-off (at least): near the minimum the energy cannot
/// resolve smaller decreases, and insisting on them would halve the step to nothing. Scaled up
/// to 16 epsilons of the working precision (f32 energies are summed from f32 vertex terms).
const ENERGY_ROUND_OFF: f64 = 1e-12;

/// State of the line search within a time step.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LineSearch {
    /// Current step length (starts at 1 each time step, only halves).
    pub alpha: f64,
    /// Variational energy of the current iterate (J).
    pub energy: f64,
    /// Set when the last iteration rejected a trial: the caller restarts Chebyshev.
    pub restarted: bool,
}

impl LineSearch {
    /// The search at the start of a time step, from the energy of the initial iterate (J).
    pub fn new(energy: f64) -> Self {
        Self {
            alpha: 1.0,
            energy,
            restarted: false,
        }
    }
}

/// Working set of the descent method, built only when `method = descent`: the rest data in
/// f64 with its bonds (the Hessian is differenced in f64 whatever the solver's precision), the
/// iterate in f64, and the per-vertex Hessian blocks.
pub(crate) struct DescentState {
    rest: RestData<f64>,
    y: Vec<Vector3<f64>>,
    bond_blocks: Vec<Matrix3<f64>>,
    self_blocks: Vec<Matrix3<f64>>,
}

impl DescentState {
    /// Concatenates the bodies' rest data (in the vertex and bond order of [`MembraneSystem::build`]).
    pub fn new(bodies: &[&mut Membrane]) -> Result<Self> {
        let mut rest = RestData::empty();
        for body in bodies {
            rest.extend_from(&body.rest_source()?, true)?;
        }
        let (n, bonds) = (rest.vertices.len(), rest.bonds.len());
        Ok(Self {
            rest,
            y: vec![Vector3::zeros(); n],
            bond_blocks: vec![Matrix3::zeros(); bonds],
            self_blocks: vec![Matrix3::zeros(); n],
        })
    }
}

/// One descent iteration from the responses evaluated at `y`: direction `d_k = P_k^-1 r_k`,
/// trial `y + alpha d` (kept out of colliders, Chebyshev-extrapolated unless restarted),
/// accepted when `E` does not rise beyond round-off, else `alpha` halves and the trial is
/// redone without extrapolation. Leaves the accepted trial in `y_next` (or `y` itself when no
/// step length lowers the energy), the responses evaluated there, and its energy in `search`.
pub(crate) fn descent_iteration<T: Real>(
    sys: &mut MembraneSystem<T>,
    state: &mut DescentState,
    h: T,
    mode: Preconditioner,
    options: &MoveOptions<'_, T>,
    search: &mut LineSearch,
) -> Update {
    let h2 = h * h;
    let n = sys.points.y.len();
    for (wide, y) in state.y.iter_mut().zip(&sys.points.y) {
        *wide = y.map(|c| c.to_f64());
    }
    vertex_hessian_blocks(
        &sys.nb,
        &state.rest,
        &state.y,
        &mut state.bond_blocks,
        &mut state.self_blocks,
    );
    if sys.point_systems.len() != n {
        let zero = PointSystem::unit();
        sys.point_systems = vec![zero; n];
        sys.delta = vec![Vector3::zeros(); n];
    }
    let mut point_systems = std::mem::take(&mut sys.point_systems);
    let mut direction = std::mem::take(&mut sys.delta);
    let state_ref = &*state;
    let residual = jacobi_moves(
        sys,
        &mut point_systems,
        &mut direction,
        options,
        |sys, k| jacobi_system(sys, state_ref, k, h2),
    );

    let (update, _) = search_along(sys, &point_systems, &direction, h, mode, options, search);
    sys.point_systems = point_systems;
    sys.delta = direction;
    Update { residual, ..update }
}

/// Every free vertex's Jacobi system `metric[k] = system_of(sys, k)` and move
/// `moves[k] = metric[k]^-1 r_k` (pinned vertices: zero), from the responses evaluated at `y`;
/// returns the convergence measure at `y`, the largest [`free_residual`] (m) with the
/// colliders' reaction to that move.
pub(crate) fn jacobi_moves<T: Real>(
    sys: &MembraneSystem<T>,
    metric: &mut [PointSystem<T>],
    moves: &mut [Vector3<T>],
    options: &MoveOptions<'_, T>,
    system_of: impl Fn(&MembraneSystem<T>, usize) -> PointSystem<T> + Sync,
) -> f64 {
    metric
        .par_iter_mut()
        .zip(moves.par_iter_mut())
        .enumerate()
        .map(|(k, (local, d))| {
            if sys.points.pinned[k] {
                *d = Vector3::zeros();
                return 0.0;
            }
            *local = system_of(sys, k);
            *d = local.solve();
            let collider_reaction = whole_move_reaction(sys, k, local, d, options.colliders);
            free_residual(k, local, &collider_reaction, options)
                .norm_squared()
                .to_f64()
                .sqrt()
        })
        .reduce(|| 0.0, f64::max)
}

/// The line search of the descent and Newton methods along `direction` (m per vertex) from
/// the responses evaluated at `y`: trial `y + alpha d` (kept out of colliders in the metric
/// `metric[k].inverse`, Chebyshev-extrapolated by `options.omega` unless restarted), accepted
/// when `E` does not rise beyond round-off, else `alpha` halves and the trial is redone
/// without extrapolation. Leaves the accepted trial in `y_next` (or `y` itself when no step
/// length lowers the energy), the responses evaluated there, and its energy in `search`;
/// returns the move's measures (without the residual) and the number of trials evaluated.
pub(crate) fn search_along<T: Real>(
    sys: &mut MembraneSystem<T>,
    metric: &[PointSystem<T>],
    direction: &[Vector3<T>],
    h: T,
    mode: Preconditioner,
    options: &MoveOptions<'_, T>,
    search: &mut LineSearch,
) -> (Update, usize) {
    let round_off = ENERGY_ROUND_OFF.max(16.0 * T::default_epsilon().to_f64());
    let mut omega = options.omega;
    search.restarted = false;
    let mut update = Update::NONE;
    let mut settled = false;
    let mut trials = 0;
    for _ in 0..=MAX_HALVINGS {
        let alpha = T::of(search.alpha);
        let (y, y_prev, y_start, pinned, rest) = (
            &sys.points.y,
            &sys.points.y_prev,
            &sys.points.y_start,
            &sys.points.pinned,
            &sys.rest,
        );
        update = sys
            .points
            .y_next
            .par_iter_mut()
            .enumerate()
            .map(|(k, next)| {
                if pinned[k] {
                    *next = y[k];
                    return Update::NONE;
                }
                let margin = rest.vertices[k].half_thickness;
                *next = push_out_with_friction(
                    &y[k],
                    y[k] + direction[k] * alpha,
                    &y_start[k],
                    &metric[k].inverse,
                    margin,
                    options.colliders,
                );
                if let Some(w) = omega {
                    *next = (*next - y_prev[k]) * w + y_prev[k];
                }
                *next = push_out_of_colliders(
                    options.colliders,
                    MoveStart::Now(y[k]),
                    *next,
                    margin,
                    None,
                );
                Update::of(k, &y[k], next)
            })
            .reduce(|| Update::NONE, Update::merge);
        if update.first_bad.is_some() {
            settled = true;
            break;
        }
        std::mem::swap(&mut sys.points.y, &mut sys.points.y_next);
        evaluate(sys, mode);
        trials += 1;
        let energy = total_energy(sys, h);
        std::mem::swap(&mut sys.points.y, &mut sys.points.y_next);
        if energy <= search.energy + round_off * search.energy.abs() {
            search.energy = energy;
            settled = true;
            break;
        }
        search.alpha *= 0.5;
        search.restarted = true;
        omega = None;
    }
    if !settled {
        // No step length lowers the energy: the iterate is a minimum to round-off. Stay.
        sys.points.y_next.copy_from_slice(&sys.points.y);
        evaluate(sys, mode);
        update = Update::NONE;
    }
    (update, trials)
}

/// Vertex `k`'s Jacobi system `P_k d = r_k` (see the module docs), with the residual and
/// force of the last evaluation.
#[inline]
fn jacobi_system<T: Real>(
    sys: &MembraneSystem<T>,
    state: &DescentState,
    k: usize,
    h2: T,
) -> PointSystem<T> {
    let mass = sys.rest.vertices[k].mass;
    let force_h2 = internal_force(k, &sys.nb, &sys.bond_grad) * h2;
    let residual = (sys.points.y_star[k] - sys.points.y[k]) * mass + force_h2;
    let block = hessian_diagonal_block(k, &sys.nb, &state.bond_blocks, &state.self_blocks);
    let stiffness =
        SymmetricMatrix3::from_diagonal(&block.diagonal().map(|x| T::of(x.max(0.0)))) * h2;
    PointSystem::new(mass, stiffness, residual, force_h2, T::zero())
}
