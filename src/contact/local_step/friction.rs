//! Coulomb friction between membranes in the contact local step (issue 41, item 6; the paper
//! has none): static and kinetic, with a coefficient per body, in the spirit of the colliders'
//! friction ([`crate::collider::push_out_with_friction`], whose rule [`coulomb_share`] it
//! shares).
//!
//! After the descent, each vertex `i` the barrier pushes (push `p_i`, m, in the local step's
//! metric `W_i`, see [`super::ProximalMetric`]) is compared with the primitives across its
//! pairs. Its slip over the time step is its displacement since the step's start `x_i` minus
//! the other side's, `s_i = (z_i - x_i) - sum_c l_c o_c / sum_c l_c`, where `o_c` is the
//! displacement of pair `c`'s closest point on the other primitive (its vertices' displacements
//! weighted by their barycentric weights) and `l_c = s_c |alpha_c^i|` the pair's push on `i`
//! (`s_c` its barrier slope, see `barrier_push.rs`). Its tangential part
//! `t = s_i - n (n . s_i)`, `n = p_i / |p_i|`, is removed where the reaction that takes is
//! within the Coulomb cone `mu_i |p_i|` (sticking), and shortened by the cone's reach otherwise
//! (sliding): the reaction to remove a relative slip `t` is `|t| / c`, with `c` the relative
//! compliance along it. The pair's coefficient is the geometric mean of its two bodies'
//! (`mu_i` the mean over the vertex's pairs weighted by `l_c`): a frictionless body is
//! frictionless against any other, as with a zero coefficient on either side of Coulomb's law
//! for two surfaces, and equal coefficients stay themselves.
//!
//! The relative slip is shared between the two sides: vertex `i` takes all of it where every
//! vertex across its pairs is fixed (`c = t . W_i^-1 t / |t|^2`), and half of it otherwise
//! (`c` twice that: the other side taken as compliant as `i`, exact for two like sheets and
//! for the other side's own friction move, which removes the other half). Within the
//! iteration of global and local steps this is a Jacobi sweep on the sticking condition: at a
//! fixed point the sticking pairs move together and the sliding ones slide against the
//! cone's force, and the friction move is part of the contact reaction that balances the
//! global step's residual (see `solve::membranes::contact_step`).

use nalgebra::Vector3;
use rayon::prelude::*;

use super::super::barrier_push::BarrierPush;
use crate::collider::coulomb_share;
use crate::symmetric::SymmetricMatrix3;

/// The bodies' friction and where the vertices started the time step.
pub(super) struct Friction<'a> {
    /// Per vertex, its body's coefficient (dimensionless, >= 0).
    pub coefficient: &'a [f64],
    /// Per vertex, its position at the start of the time step (m).
    pub start: &'a [Vector3<f64>],
}

/// Writes into `moves` each vertex's friction move (m; zero where nothing holds it) at the
/// positions `z` (m) with the barrier's push `push` (m) and terms `terms` of the last
/// evaluation, the metric `weights` (`None`: the identity) and the `fixed` vertices (never
/// moved, and fully stiff across a pair). Returns whether any vertex moves.
pub(super) fn friction_moves(
    friction: &Friction,
    terms: &BarrierPush,
    (z, push): (&[Vector3<f64>], &[Vector3<f64>]),
    weights: Option<&[SymmetricMatrix3<f64>]>,
    fixed: &[bool],
    moves: &mut Vec<Vector3<f64>>,
) -> bool {
    let Friction { coefficient, start } = *friction;
    moves.resize(z.len(), Vector3::zeros());
    moves
        .par_iter_mut()
        .enumerate()
        .map(|(i, out)| {
            *out = Vector3::zeros();
            let normal_force = push[i].norm();
            if fixed[i] || coefficient[i] == 0.0 || normal_force == 0.0 {
                return false;
            }
            // Sums over the vertex's pairs of `l_c`, `l_c o_c` and `l_c mu_c`.
            let (mut load, mut other, mut mu) = (0.0, Vector3::zeros(), 0.0);
            let mut other_side_fixed = true;
            for (term, slot) in terms.felt_terms(i) {
                let own = term.weights[slot];
                let l = term.slope * own.abs();
                if l <= 0.0 {
                    continue;
                }
                let (mut weight, mut moved, mut coefficient_c) = (0.0, Vector3::zeros(), 0.0);
                for (j, &w) in term.weights.iter().enumerate() {
                    if w * own >= 0.0 {
                        continue;
                    }
                    let v = term.pair.v[j] as usize;
                    weight += w.abs();
                    moved += (z[v] - start[v]) * w.abs();
                    coefficient_c = coefficient[v];
                    other_side_fixed &= fixed[v];
                }
                if weight == 0.0 {
                    continue;
                }
                load += l;
                other += moved * (l / weight);
                mu += l * (coefficient[i] * coefficient_c).sqrt();
            }
            if load == 0.0 || mu == 0.0 {
                return false;
            }
            let n = push[i] / normal_force;
            let slip = (z[i] - start[i]) - other / load;
            let slip_t = slip - n * n.dot(&slip);
            let share = if other_side_fixed { 1.0 } else { 0.5 };
            let own_compliance = match weights {
                None => slip_t.norm_squared(),
                Some(w) => w[i]
                    .try_inverse()
                    .map_or(0.0, |c| slip_t.dot(&c.mul_vector(&slip_t))),
            };
            let removed = coulomb_share(&slip_t, own_compliance / share, mu / load * normal_force);
            *out = -slip_t * (share * removed);
            *out != Vector3::zeros()
        })
        .reduce(|| false, |a, b| a || b)
}
