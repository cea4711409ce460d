//! Grains that roll, against a rolling resistance (issue 39; beyond the 2017 paper, whose
//! grains have neither contact friction nor rotation: docs/particles/granular.md, rounds y and
//! ab). The particles carry no rotational degrees of freedom, so with contact friction
//! ([`super::grain_friction`]) every relative tangential move of a touching pair is a slip
//! against the friction: a grain resists rolling without bound, one resting on another off its
//! top stays there, and a heap poured from a stream flows down to 12-18 degrees whatever its
//! friction angle (round x).
//!
//! With a body's rolling resistance `mu_r` (`Granular::rolling_resistance`, dimensionless)
//! each of its free grains turns within the step by a rotation vector `theta_i` (rad),
//! massless (no rotational inertia) and without state (it is the step's turn: it starts from
//! 0 every step, as the step's slip does), until the torque of its contacts' friction lies
//! within `mu_r` times its radius times its contacts' normal loads, Coulomb's law for the
//! torque (a rolling friction):
//!
//! `|tau_i| <= mu_r R_i sum_j s_i g_ij`, `tau_i = -R_i sum_j s_i n_ij x lambda_ij`
//!
//! in the friction's moves (m^2 and m; times `m_i / h^2` a torque in N m and a load in N),
//! with `R_i` the grain's radius (its collider margin, m), `n_ij` the pair's unit normal from
//! `j` to `i` (the contact at `-R_i n_ij` from `i`'s centre), `s_i` its share of the pair,
//! `g_ij` the overlap (m) and `lambda_ij` the friction multiplier (m) of
//! [`super::grain_friction`]. A turn moves each grain's surface at the contact, so the pair's
//! slip within the step is
//!
//! `(q_i - y_i^t) - (q_j - y_j^t) - (R_i theta_i + R_j theta_j) x n_ij`
//!
//! (`theta_j` = 0 for a partner that does not turn: pinned, or of a body without `mu_r`). At
//! each iteration, before the multipliers' relaxed step, a grain whose torque at the accepted
//! multipliers exceeds its limit turns further by
//!
//! `theta_i <- theta_i + e_i / sum_j s_i w_ij (R_i + t_j R_j)`,
//! `e_i = t_i - clamp(t_i, mu_r sum_j s_i g_ij)`, `t_i = -sum_j s_i n_ij x lambda_ij`
//!
//! (`t_i = tau_i / R_i`, m; `e_i` its excess over the limit; `w_ij` the multipliers'
//! relaxation; `t_j` 1 if `j` turns, else 0): the multipliers' next step moves by
//! `w_ij (R_i theta_i + R_j theta_j) x n_ij`, which changes `tau_i` by
//! `-R_i sum_j s_i w_ij (R_i theta_i + R_j theta_j)` in the tangent planes, so the turn takes
//! at most the excess out of the torque where the partners turn alike, by no more than it (two
//! free grains touching only each other: relaxed by `R_i` alone, they would overshoot twice
//! the excess, and at `mu_r = 0` swap the torque's sign for ever); a partner turning further
//! in one Jacobi iteration can still carry the torque past its bound, which later iterations
//! take back (the fixed point is the same). At the fixed point
//! every torque lies within its limit and every contact obeys Coulomb's law with the turns
//! in its slip. `mu_r = 0` rolls freely: the friction puts no torque on a grain, so a grain on
//! a single contact is not held by it (it slides off a grain below as if frictionless); a
//! grain on several contacts is, where their torques cancel. A body without `mu_r` never
//! turns (the previous model to the bit). Each turn is computed from its own grain's
//! partners in a fixed order, and a pair's two slips from exactly negated inputs
//! (`(R_j theta_j + R_i theta_i) x n_ji` is exactly the negated `(R_i theta_i + R_j theta_j) x
//! n_ij`), so the pair's multipliers stay equal and opposite (momentum) and the result is the
//! same for any thread count.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::real::Real;

use super::grain_contacts::{Contact, Pairs};

/// The grains' turns within the step (module doc): each particle's resistance and its turn as
/// accepted by the last iteration and as computed by the last trial.
pub(crate) struct GrainRolling<T: Real> {
    /// Each particle's `mu_r` (dimensionless), `None` for one that does not turn.
    resistance: Vec<Option<T>>,
    /// Each particle's turn `theta_i` (rad) of the accepted iteration and of the last trial.
    accepted: Vec<Vector3<T>>,
    trial: Vec<Vector3<T>>,
}

impl<T: Real> GrainRolling<T> {
    /// The rolling of particles with the resistances `resistance`, or `None` if none turns.
    pub fn of(resistance: Vec<Option<T>>) -> Option<Self> {
        let n = resistance.len();
        resistance.iter().any(Option::is_some).then(|| Self {
            resistance,
            accepted: vec![Vector3::zeros(); n],
            trial: vec![Vector3::zeros(); n],
        })
    }

    /// Starts a step: no grain has turned.
    pub fn start_step(&mut self) {
        self.accepted.fill(Vector3::zeros());
        self.trial.fill(Vector3::zeros());
    }

    /// Takes the turns of the last trial as the iteration's.
    pub fn accept(&mut self) {
        std::mem::swap(&mut self.accepted, &mut self.trial);
    }

    /// The trial turns (module doc) from the accepted ones and the accepted multipliers
    /// `multipliers` (m, per candidate entry of `pairs`), with `contact(i, j)` the pair's
    /// frictional contact, `share(i, j)` particle `i`'s share of it and `shares` each
    /// particle's sum of shares `S_i` (the relaxation `w_ij = 1 / (S_i + S_j)`).
    pub fn turn(
        &mut self,
        pairs: &Pairs<'_, T>,
        contact: &(impl Fn(usize, usize) -> Option<Contact<T>> + Sync),
        share: &(impl Fn(usize, usize) -> T + Sync),
        multipliers: &[Vector3<T>],
        shares: &[T],
    ) {
        let (resistance, accepted) = (&self.resistance, &self.accepted);
        let turns = |i: usize| resistance[i].is_some() && !pairs.pinned[i];
        self.trial
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, theta)| {
                *theta = accepted[i];
                let Some(mu_r) = resistance[i].filter(|_| !pairs.pinned[i]) else {
                    return;
                };
                let (mut torque, mut load, mut stiffness) =
                    (Vector3::zeros(), T::zero(), T::zero());
                for e in pairs.row(i) {
                    let j = pairs.indices[e] as usize;
                    if let Some(c) = contact(i, j) {
                        let s = share(i, j);
                        torque -= c.normal.cross(&multipliers[e]) * s;
                        load += c.overlap * s;
                        let reach = if turns(j) {
                            pairs.margin[i] + pairs.margin[j]
                        } else {
                            pairs.margin[i]
                        };
                        stiffness += s * reach / (shares[i] + shares[j]);
                    }
                }
                let (size, limit) = (torque.norm(), mu_r * load);
                if size > limit {
                    *theta += torque * ((T::one() - limit / size) / stiffness);
                }
            });
    }

    /// The move (m) that the trial turns of particles `i` and `j` add to the pair's slip at
    /// their contact of unit normal `normal` (from `j` to `i`), with the particles' radii
    /// `margin` (m): `(R_i theta_i + R_j theta_j) x n_ij`, exactly negated for `(j, i)`.
    #[inline(always)]
    pub fn rolled(&self, margin: &[T], i: usize, j: usize, normal: &Vector3<T>) -> Vector3<T> {
        (self.trial[i] * margin[i] + self.trial[j] * margin[j]).cross(normal)
    }
}
