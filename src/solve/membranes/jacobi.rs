//! The per-vertex move of SISSM: eq. 25 in residual form, optional inner Jacobi sweeps
//! (Fig. 6), the step length of eq. 31-33, colliders in the system metric, and Chebyshev
//! extrapolation.

use nalgebra::{SimdValue, Vector3};
use rayon::prelude::*;

use crate::collider::{push_out_with_friction, ColliderModel};
use crate::isa;
use crate::membrane::{internal_force, GatheredResponse};
use crate::parallel::GRAIN;
use crate::real::{Lanes, Real};
use crate::symmetric::SymmetricMatrix3;

use super::system::MembraneSystem;
use crate::solve::point_system::PointSystem;
use crate::solve::points::Points;
use crate::solve::update::{MoveOptions, Update};

/// What vertex `k`'s system is assembled from, read from the responses of the last evaluation.
#[derive(Clone, Copy, Default)]
struct Gathered<T: Real> {
    mass: T,
    /// `y*_k - y_k` (m).
    to_prediction: Vector3<T>,
    /// `h^2 f_k` (N s^2), the bond gradients of `k` and of its neighbours towards it.
    force_h2: Vector3<T>,
    /// `n_k C_k + sum_j C_j` (N/m) and `E_k + sum_j E_j` (J).
    responses: GatheredResponse<T>,
}

impl<T: Real> Gathered<T> {
    #[inline(always)]
    fn of(sys: &MembraneSystem<T>, k: usize, h2: T) -> Self {
        Self {
            mass: sys.rest.vertices[k].mass,
            to_prediction: sys.points.y_star[k] - sys.points.y[k],
            force_h2: internal_force(k, &sys.nb, &sys.bond_grad) * h2,
            responses: gathered_response(sys, k),
        }
    }
}

/// Vertex `k`'s `n_k C_k + sum_j C_j` (N/m) and `E_k + sum_j E_j` (J) from the responses of
/// the last evaluation, one record at a time.
#[inline(always)]
fn gathered_response<T: Real>(sys: &MembraneSystem<T>, k: usize) -> GatheredResponse<T> {
    let neighbors = sys.nb.of(k);
    let response = &sys.response;
    let own = &response[k];
    let mut responses =
        GatheredResponse::new(own.precond() * T::of(neighbors.len() as f64), own.energy());
    for &j in neighbors {
        responses += response[j as usize];
    }
    responses
}

/// Vertex `k`'s Jacobi block `D_k = m_k I + h^2 (n_k C_k + sum_j C_j)` (kg) of eq. 25 from
/// the responses of the last evaluation: the `system` of [`PointSystem::of`] without its
/// residual, for the metric of the contact local step's proximal term
/// ([`crate::contact::ProximalMetric::Jacobi`]).
pub(crate) fn jacobi_block<T: Real>(
    sys: &MembraneSystem<T>,
    k: usize,
    h2: T,
) -> SymmetricMatrix3<T> {
    (gathered_response(sys, k).precond() * h2).plus_identity(sys.rest.vertices[k].mass)
}

impl<T: Real> PointSystem<T> {
    /// Assembles vertex `k`'s system from the responses of the last evaluation.
    #[inline(always)]
    pub fn of(sys: &MembraneSystem<T>, k: usize, h2: T) -> Self {
        let g = Gathered::of(sys, k, h2);
        Self::assemble(
            g.mass,
            g.to_prediction,
            g.force_h2,
            g.responses.precond(),
            g.responses.energy(),
            h2,
        )
    }
}

/// The move of one SISSM iteration from the responses of the last evaluation, written to
/// `y_next`.
pub(crate) fn jacobi_update<T: Real>(
    sys: &mut MembraneSystem<T>,
    h: T,
    options: &MoveOptions<'_, T>,
) -> Update {
    let h2 = h * h;
    let inner = options.inner_iters > 1;
    if inner {
        inner_sweeps(sys, h2, options.inner_iters);
    }
    // Without inner sweeps the systems are assembled and solved a SIMD pack at a time.
    let packed = !inner;
    let mut y_next = std::mem::take(&mut sys.points.y_next);
    // The Jacobi blocks are kept for the contact local step once it asked for them.
    let mut blocks = std::mem::take(&mut sys.blocks);
    let keep = blocks.len() == y_next.len();
    let sys_ref = &*sys;
    let chunk = |c: usize, next: &mut [Vector3<T>], blocks: &mut [SymmetricMatrix3<T>]| {
        isa::run(
            #[inline(always)]
            || {
                if packed {
                    move_packs(sys_ref, c * GRAIN, next, blocks, h2, options)
                } else {
                    move_vertices(sys_ref, c * GRAIN, next, blocks, h2, options)
                }
            },
        )
    };
    let update = if keep {
        y_next
            .par_chunks_mut(GRAIN)
            .zip(blocks.par_chunks_mut(GRAIN))
            .enumerate()
            .map(|(c, (next, blocks))| chunk(c, next, blocks))
            .reduce(|| Update::NONE, Update::merge)
    } else {
        y_next
            .par_chunks_mut(GRAIN)
            .enumerate()
            .map(|(c, next)| chunk(c, next, &mut []))
            .reduce(|| Update::NONE, Update::merge)
    };
    sys.points.y_next = y_next;
    sys.blocks = blocks;
    sys.blocks_fresh = keep;
    update
}

/// A chunk's running measures: the largest squared move and squared free residual in the
/// working precision (square roots in f64 once, at the end: `sqrt` is monotonic, so that is the
/// largest norm), and the first non-finite vertex. A move whose square is not finite (a
/// non-finite position, or beyond about 1e19 m in f32) goes through [`Update::of`], which names
/// the vertex if its position is non-finite.
struct Measures<T: Real> {
    moved_sq: T,
    residual_sq: T,
    update: Update,
}

impl<T: Real> Measures<T> {
    fn new() -> Self {
        Self {
            moved_sq: T::zero(),
            residual_sq: T::zero(),
            update: Update::NONE,
        }
    }

    /// Vertex `k` moved from `y` to `next` with the squared free residual `free_sq` (m^2).
    #[inline(always)]
    fn add(&mut self, k: usize, y: &Vector3<T>, next: &Vector3<T>, move_sq: T, free_sq: T) {
        if move_sq.is_finite() {
            self.moved_sq = self.moved_sq.max(move_sq);
        } else {
            self.update = Update::merge(self.update, Update::of(k, y, next));
        }
        self.residual_sq = self.residual_sq.max(free_sq);
    }

    fn update(self) -> Update {
        Update::merge(
            self.update,
            Update::from_squares(self.moved_sq, self.residual_sq),
        )
    }
}

/// Most lanes of a [`Real::Pack`].
const MAX_LANES: usize = 8;

/// The pack whose lane `l` is `entry(&gathered[l])`.
#[inline(always)]
fn lanes_of<T: Real>(gathered: &[Gathered<T>], entry: impl Fn(&Gathered<T>) -> T) -> T::Pack {
    T::Pack::gather(|l| entry(&gathered[l]))
}

/// The pack whose lane `l` is `v(k + l)`.
#[inline(always)]
fn vector_lanes<T: Real>(v: &[Vector3<T>], k: usize) -> Vector3<T::Pack> {
    let at = |c: usize| T::Pack::gather(|l| v[k + l][c]);
    Vector3::new(at(0), at(1), at(2))
}

/// [`move_vertices`] without inner sweeps, a SIMD pack of consecutive vertices at a time: each
/// lane gathers its vertex's sums, and the system, its inverse and its solve run in the pack's
/// lanes (bit-identical to [`move_vertices`], see [`Lanes`]). Without colliders or membrane
/// contact the step length, the move and its measures run in the lanes too; with them, each lane
/// finishes from its lane of the system as [`move_vertices`] does (keeping out of colliders,
/// friction, contact reactions in the residual). The chunk's last vertices, short of a whole
/// pack, go through [`move_vertices`].
#[inline(always)]
fn move_packs<T: Real>(
    sys: &MembraneSystem<T>,
    first: usize,
    next: &mut [Vector3<T>],
    blocks: &mut [SymmetricMatrix3<T>],
    h2: T,
    options: &MoveOptions<'_, T>,
) -> Update {
    const { assert!(T::Pack::LANES <= MAX_LANES) };
    let lanes = T::Pack::LANES;
    let whole = next.len() / lanes * lanes;
    let (packs, tail) = next.split_at_mut(whole);
    let mut gathered = [Gathered::<T>::default(); MAX_LANES];
    let gathered = &mut gathered[..lanes];
    // Without colliders or membrane contact the whole move runs in the lanes; with them, each
    // lane finishes as [`move_vertices`] does, from its lane of the system.
    let plain = options.colliders.is_empty() && options.contact_reaction.is_empty();
    let mut measures = Measures::new();
    for (p, out) in packs.chunks_exact_mut(lanes).enumerate() {
        let base = first + p * lanes;
        for (l, g) in gathered.iter_mut().enumerate() {
            *g = Gathered::of(sys, base + l, h2);
        }
        let vector = |v: fn(&Gathered<T>) -> Vector3<T>| {
            Vector3::new(
                lanes_of(gathered, |g| v(g).x),
                lanes_of(gathered, |g| v(g).y),
                lanes_of(gathered, |g| v(g).z),
            )
        };
        let precond = |e: usize| lanes_of(gathered, |g| g.responses.precond().entry(e));
        let local = PointSystem::assemble(
            lanes_of(gathered, |g| g.mass),
            vector(|g| g.to_prediction),
            vector(|g| g.force_h2),
            SymmetricMatrix3 {
                diagonal: [precond(0), precond(1), precond(2)],
                upper: [precond(3), precond(4), precond(5)],
            },
            lanes_of(gathered, |g| g.responses.energy()),
            T::Pack::splat(h2),
        );
        if !blocks.is_empty() {
            let system = &local.system;
            for l in 0..lanes {
                blocks[p * lanes + l] = SymmetricMatrix3 {
                    diagonal: system.diagonal.map(|d| d.extract(l)),
                    upper: system.upper.map(|u| u.extract(l)),
                };
            }
        }
        let delta = local.solve();
        if !plain {
            for (l, out) in out.iter_mut().enumerate() {
                let k = base + l;
                if sys.points.pinned[k] {
                    *out = sys.points.y[k];
                    continue;
                }
                let delta =
                    Vector3::new(delta.x.extract(l), delta.y.extract(l), delta.z.extract(l));
                finish_vertex(sys, k, &local.lane(l), delta, options, out, &mut measures);
            }
            continue;
        }
        let alpha = if options.step_length {
            local.step_length(&delta)
        } else {
            T::Pack::lit(1.0)
        };
        let y = vector_lanes(&sys.points.y, base);
        let mut moved_to = y + delta * alpha;
        if let Some(w) = options.omega {
            let previous = vector_lanes(&sys.points.y_prev, base);
            moved_to = (moved_to - previous) * T::Pack::splat(w) + previous;
        }
        let move_sq = (moved_to - y).norm_squared();
        let free_sq = local.residual_per_mass().norm_squared();
        for (l, out) in out.iter_mut().enumerate() {
            let k = base + l;
            if sys.points.pinned[k] {
                *out = sys.points.y[k];
                continue;
            }
            *out = Vector3::new(
                moved_to.x.extract(l),
                moved_to.y.extract(l),
                moved_to.z.extract(l),
            );
            measures.add(
                k,
                &sys.points.y[k],
                out,
                move_sq.extract(l),
                free_sq.extract(l),
            );
        }
    }
    let tail_blocks = if blocks.is_empty() {
        &mut []
    } else {
        &mut blocks[whole..]
    };
    let tail = move_vertices(sys, first + whole, tail, tail_blocks, h2, options);
    Update::merge(measures.update(), tail)
}

/// The moves of the vertices `first..first + next.len()` into `next` (see [`jacobi_update`]),
/// merged (see [`Measures`]). Inlined into each copy [`isa::run`] chooses from.
#[inline(always)]
fn move_vertices<T: Real>(
    sys: &MembraneSystem<T>,
    first: usize,
    next: &mut [Vector3<T>],
    blocks: &mut [SymmetricMatrix3<T>],
    h2: T,
    options: &MoveOptions<'_, T>,
) -> Update {
    let inner = options.inner_iters > 1;
    let mut measures = Measures::new();
    for (i, (k, next)) in (first..).zip(next).enumerate() {
        if sys.points.pinned[k] {
            *next = sys.points.y[k];
            if let Some(block) = blocks.get_mut(i) {
                *block = jacobi_block(sys, k, h2);
            }
            continue;
        }
        let (local, delta) = if inner {
            (sys.point_systems[k], sys.delta[k])
        } else {
            let local = PointSystem::of(sys, k, h2);
            (local, local.solve())
        };
        if let Some(block) = blocks.get_mut(i) {
            *block = local.system;
        }
        finish_vertex(sys, k, &local, delta, options, next, &mut measures);
    }
    measures.update()
}

/// Finishes vertex `k`'s move from its system and step: scales `delta` by the step length,
/// keeps it out of colliders in the system metric and extrapolates (Chebyshev), into `next`,
/// and adds the move and its free residual to the measures.
#[inline(always)]
fn finish_vertex<T: Real>(
    sys: &MembraneSystem<T>,
    k: usize,
    local: &PointSystem<T>,
    delta: Vector3<T>,
    options: &MoveOptions<'_, T>,
    next: &mut Vector3<T>,
    measures: &mut Measures<T>,
) {
    // The step length is not applied where the last local step realised a contact reaction
    // (see `free_residual`): there the local step takes the move back, and its reaction
    // balances only the move it was given. A cut move `alpha D^-1 r` would leave `(1 - alpha) r`
    // in the measure at the fixed point, which no motion of the vertex releases: a cloth resting
    // on another, held slightly strained by the barrier (its linearised elastic energy crosses
    // zero along the move), would never converge (issue 41, item 3).
    let held = options
        .contact_reaction
        .get(k)
        .is_some_and(|q| *q != Vector3::zeros());
    let alpha = if options.step_length && !held {
        local.step_length(&delta)
    } else {
        T::one()
    };
    let margin = sys.rest.vertices[k].half_thickness;
    // The colliders this vertex meets: the same set the clearance was measured over.
    let colliders = Points::colliders_of(&sys.points.collides, k, options.colliders);
    let free_move = sys.points.y[k] + delta * alpha;
    // A move that surely stays clear of every collider is left as it is, as the push would.
    let clear = sys
        .points
        .clearance
        .clears(k, &sys.points.y[k], &free_move, margin);
    *next = if clear {
        free_move
    } else {
        push_out_with_friction(
            &sys.points.y[k],
            free_move,
            &sys.points.y_start[k],
            &local.inverse,
            margin,
            colliders,
        )
    };
    // The colliders' reaction to the whole Jacobi move (see `free_residual`): the one just
    // computed unless the step length cut the move.
    let collider_reaction = if alpha == T::one() {
        *next - free_move
    } else {
        whole_move_reaction(sys, k, local, &delta, colliders)
    };
    // Chebyshev extrapolates the unconstrained iteration only: a vertex a collider holds keeps
    // its projected position, else the extrapolation would push it along the contact past
    // what its friction cone allows (a resting cloth would creep).
    if let Some(w) = options.omega.filter(|_| *next == free_move) {
        *next = (*next - sys.points.y_prev[k]) * w + sys.points.y_prev[k];
    }
    let free_sq = free_residual(k, local, &collider_reaction, options).norm_squared();
    measures.add(
        k,
        &sys.points.y[k],
        next,
        (*next - sys.points.y[k]).norm_squared(),
        free_sq,
    );
}

/// `inner` Jacobi sweeps on the linear system of eq. 25, `(M + h^2 L) delta = r` with `L` the
/// bond Laplacian of weights `C_i + C_j`: `delta_k <- D_k^-1 (r_k + h^2 sum_j (C_k + C_j) delta_j)`.
/// Leaves each vertex's system in `point_systems` and the result in `delta`.
fn inner_sweeps<T: Real>(sys: &mut MembraneSystem<T>, h2: T, inner: usize) {
    let n = sys.points.y.len();
    let mut point_systems = std::mem::take(&mut sys.point_systems);
    let mut delta = std::mem::take(&mut sys.delta);
    let mut scratch = std::mem::take(&mut sys.delta_next);
    if point_systems.len() != n {
        let zero = PointSystem::unit();
        point_systems = vec![zero; n];
        delta = vec![Vector3::zeros(); n];
        scratch = vec![Vector3::zeros(); n];
    }
    let sys_ref = &*sys;
    point_systems
        .par_iter_mut()
        .zip(delta.par_iter_mut())
        .enumerate()
        .for_each(|(k, (local, d))| {
            *local = PointSystem::of(sys_ref, k, h2);
            *d = if sys_ref.points.pinned[k] {
                Vector3::zeros()
            } else {
                local.solve()
            };
        });
    for _ in 1..inner {
        let (nb, response, pinned) = (&sys.nb, &sys.response, &sys.points.pinned);
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
            *out = point_systems[k]
                .inverse
                .mul_vector(&(point_systems[k].residual + coupling));
        });
        std::mem::swap(&mut delta, &mut scratch);
    }
    sys.point_systems = point_systems;
    sys.delta = delta;
    sys.delta_next = scratch;
}

/// The convergence measure of vertex `k`, `r_free / m` (m; its norm is compared with `tol`): its
/// residual `r` at the current iterate `y` with the reactions of the contacts it is in added.
///
/// Membrane contact: the global step sends `y` to `y^k = y + D^-1 r`, and the local step
/// (Algorithm 2) moves that to `z`. At a fixed point `z = y`, so `r = -D (z - y^k)`: the local
/// step's move, weighted by `D`, is the reaction that balances the residual. Only its part
/// that is a non-negative combination of the barrier's push `p_i` and the outward normals of
/// the colliders the vertex touches, each taken through the local step's proximal metric
/// (`W_i^-1 p_i`, see [`crate::contact::ProximalMetric`]), counts as reaction (`q`, see
/// [`super::reaction::realised_reaction`]), with the `q` of the local step that produced
/// `y`. So a vertex out of the barrier's reach and off the colliders (in free flight) keeps its
/// whole residual, and a tangential imbalance (sliding not yet resolved, or held back by a CCD
/// clamp) stays in the measure; and the measure vanishes only where the local step's push and
/// the global step's pull balance, not merely where a pair is close. The first iteration of a
/// step, before any local step, has no `q` and measures the whole residual (and cannot decide
/// convergence, see [`crate::solve::sissm`]).
///
/// Colliders in the global step: their reaction to the whole Jacobi move,
/// `c = push_out_with_friction(y + D^-1 r) - (y + D^-1 r)` (m; [`push_out_with_friction`] gives it its normal and Coulomb
/// friction parts, within the cone by construction), counts the same way. (The whole move,
/// not the one the step length cuts: where a collider takes all of it, a cut move leaves
/// `(1 - alpha) r` that no motion of the vertex can release.) What is
/// measured is `r + D (q + c)`. A vertex resting on a collider has `c` cancel its push into it
/// and the tangential part friction holds; one the collider stops short of where its residual
/// would take it (falling onto it, or sliding against kinetic friction) keeps the part of its
/// move the collider let through. This needs no test of touching or of sticking at `y`: the
/// local step's push can hold a vertex micrometres off a collider that carries it, and a slip
/// of micrometres since the step's start has no reliable direction.
#[inline]
pub(crate) fn free_residual<T: Real>(
    k: usize,
    local: &PointSystem<T>,
    collider_reaction: &Vector3<T>,
    options: &MoveOptions<'_, T>,
) -> Vector3<T> {
    let mut reaction = *collider_reaction;
    if let Some(contact) = options.contact_reaction.get(k) {
        reaction += contact;
    }
    (local.residual + local.system.mul_vector(&reaction)) * (T::one() / local.mass)
}

/// The colliders' reaction to vertex `k`'s whole Jacobi move `delta` (m):
/// `push_out_with_friction(y + delta) - (y + delta)`, the `c` of [`free_residual`].
#[inline]
pub(crate) fn whole_move_reaction<T: Real>(
    sys: &MembraneSystem<T>,
    k: usize,
    local: &PointSystem<T>,
    delta: &Vector3<T>,
    colliders: &[ColliderModel<T>],
) -> Vector3<T> {
    let whole = sys.points.y[k] + delta;
    push_out_with_friction(
        &sys.points.y[k],
        whole,
        &sys.points.y_start[k],
        &local.inverse,
        sys.rest.vertices[k].half_thickness,
        colliders,
    ) - whole
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collider::{Collider, MovingCollider, Shape};
    use crate::membrane::{Membrane, Preconditioner};
    use crate::mesh::TriangleMesh;
    use crate::solve::membranes::evaluate::evaluate;
    use crate::solve::tests::stiff_params;

    /// [`move_packs`] and [`move_vertices`] on the same state give the same positions, the
    /// same Jacobi blocks as [`jacobi_block`] (kept for the contact local step) and the
    /// same `Update` (largest move and residual, first non-finite vertex) bit for bit, in both
    /// precisions, plain and extrapolated, without and with a collider (with friction) and
    /// membrane contact reactions: a stiff sheet with vertices pulled out of it and
    /// targets far past rest (the step length cuts their moves), 143 vertices (a tail of 7 in
    /// f32, 3 in f64), pinned vertices inside a pack and in the tail, and one vertex whose target
    /// is NaN.
    #[test]
    fn packed_and_per_vertex_moves_agree_bit_for_bit() {
        fn check<T: Real>() {
            let mesh = TriangleMesh::grid(13, 11, 0.5, 0.4).unwrap();
            let mut body = Membrane::new(mesh, stiff_params()).unwrap();
            let rest: Vec<Vector3<T>> = body.positions().iter().map(|p| p.map(T::of)).collect();
            // Isolated vertices pulled out of the sheet (in a pack and in the tail).
            let bumped = body
                .positions()
                .iter()
                .enumerate()
                .map(|(k, p)| match k {
                    20 | 50 | 91 | 139 => p + Vector3::new(0.01, -0.005, 0.03),
                    _ => *p,
                })
                .collect();
            body.set_positions(bumped).unwrap();
            body.pin(&[3, 140], None).unwrap();
            let mut sys = MembraneSystem::<T>::build(&[&mut body], true).unwrap();
            sys.points.load(&[&mut body]);
            let n = sys.points.y_start.len();
            sys.points.y = sys.points.y_start.clone();
            // Targets far past the rest positions: at a bump the inertial pull and the
            // elastic force agree, and the full move would release more than the elastic
            // energy there is, so the step length cuts.
            for (k, star) in sys.points.y_star.iter_mut().enumerate() {
                if !sys.points.pinned[k] {
                    *star = rest[k] + (rest[k] - sys.points.y_start[k]) * T::of(1000.0);
                }
            }
            sys.points.y_star[77] = Vector3::repeat(T::of(f64::NAN));
            let last_move = Vector3::new(0.0, 0.0, -1e-5).map(T::of);
            sys.points.y_prev = sys.points.y.iter().map(|y| y - last_move).collect();
            evaluate(&mut sys, Preconditioner::Paper);
            let h2 = T::of(1e-6);
            let cut = (0..n)
                .filter(|&k| {
                    let local = PointSystem::of(&sys, k, h2);
                    local.step_length(&local.solve()) < T::one()
                })
                .count();
            assert!(cut >= 4, "the step length cuts the bumps' moves: {cut} cut");
            // A plane with friction through the sheet (every vertex with z < 2 mm is inside
            // it), and small contact reactions on every vertex.
            let plane = Shape::plane([0.0, 0.0, 0.002], [0.0, 0.3, 1.0]).unwrap();
            let plane = MovingCollider::new(Collider::new(plane, 0.4, [0.0; 3]).unwrap());
            let colliders = [plane.during_step::<T>(0.0, 1e-3)];
            let reaction: Vec<Vector3<T>> = (0..n)
                .map(|k| Vector3::new(0.0, 0.0, 1e-6 * (k % 5) as f64).map(T::of))
                .collect();
            let cases = [
                (&colliders[..0], &reaction[..0]),
                (&colliders[..], &reaction[..0]),
                (&colliders[..0], &reaction[..]),
                (&colliders[..], &reaction[..]),
            ];
            for (omega, (colliders, contact_reaction)) in [None, Some(T::of(1.3))]
                .into_iter()
                .flat_map(|w| cases.map(|c| (w, c)))
            {
                let options = MoveOptions {
                    step_length: true,
                    inner_iters: 1,
                    omega,
                    colliders,
                    contact_reaction,
                    global_solver: Default::default(),
                };
                let mut packed = vec![Vector3::zeros(); n];
                let mut per_vertex = vec![Vector3::zeros(); n];
                let (mut packed_blocks, mut vertex_blocks) = (
                    vec![SymmetricMatrix3::zeros(); n],
                    vec![SymmetricMatrix3::zeros(); n],
                );
                let a = move_packs(&sys, 0, &mut packed, &mut packed_blocks, h2, &options);
                let b = move_vertices(&sys, 0, &mut per_vertex, &mut vertex_blocks, h2, &options);
                // The blocks kept for the contact local step's metric are its own, to the bit
                // (pinned vertices included).
                for k in 0..n {
                    let block = jacobi_block(&sys, k, h2);
                    assert_eq!(packed_blocks[k], block, "{}: packed block {k}", T::NAME);
                    assert_eq!(vertex_blocks[k], block, "{}: block {k}", T::NAME);
                }
                // Without a buffer, the same moves.
                let mut unkept = vec![Vector3::zeros(); n];
                let c = move_packs(&sys, 0, &mut unkept, &mut [], h2, &options);
                assert_eq!(c.first_bad, a.first_bad);
                assert_eq!(
                    (c.moved.to_bits(), c.residual.to_bits()),
                    (a.moved.to_bits(), a.residual.to_bits())
                );
                let same = |x: T, y: T| x == y || (x != x && y != y);
                for (k, (p, q)) in packed.iter().zip(&per_vertex).enumerate() {
                    assert!(
                        (0..3).all(|c| same(p[c], q[c])),
                        "{}: vertex {k}: {p:?} against {q:?}",
                        T::NAME
                    );
                }
                assert_eq!(packed[3], sys.points.y[3], "a pinned vertex stays");
                assert_eq!(a.first_bad, Some(77));
                assert_eq!(
                    (a.moved.to_bits(), a.residual.to_bits(), a.first_bad),
                    (b.moved.to_bits(), b.residual.to_bits(), b.first_bad),
                    "{}",
                    T::NAME
                );
                assert!(a.moved > 0.0 && a.residual > 0.0);
            }
        }
        check::<f32>();
        check::<f64>();
    }

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
                let local = PointSystem::new(
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
            |force, energy| PointSystem::new(1.0, SymmetricMatrix3::zeros(), r, force, energy);
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
