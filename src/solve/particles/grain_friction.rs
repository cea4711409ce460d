//! Coulomb friction at the contacts of touching grains ([`super::repulsion`]; beyond the 2017
//! paper, whose grains have none: docs/particles/granular.md). A granular body's
//! particles keep apart as balls of half a spacing; frictionless (the default), those balls
//! carry a pile's weight while sliding freely over each other. With the material's contact
//! friction `mu_c` (`Granular::contact_friction`, dimensionless) a touching pair's relative
//! tangential move within the step is limited, in the position-based style of the repulsion
//! (a constraint projected in the local step), by `mu_c` times the pair's normal correction.
//!
//! Each touching pair keeps its accumulated tangential correction `lambda_ij` (m, in the
//! pair's tangent plane; `lambda_ji = -lambda_ij`), which moves particle `i` by
//! `s_i lambda_ij` and `j` by `-s_j lambda_ij`, with `s_i` the repulsion's share of `i` in the
//! pair (`m_j / (m_i + m_j)` between grains, 1 against a pinned partner). At each iteration the
//! proposed positions `p` (m) are corrected by the repulsion's normal moves and the friction
//! moves of the accepted multipliers, `q_i = p_i + c_i^n + sum_j s_i lambda_ij`, and every
//! multiplier takes a relaxed step against the pair's relative slip within the step at `q`,
//! its total kept in Coulomb's disc (a projected Jacobi iteration on the pairs):
//!
//! `lambda_ij <- clamp((I - n n^T) (lambda_ij - w_ij ((q_i - y_i^t) - (q_j - y_j^t))), mu_c g)`
//!
//! with `y^t` the step's start (m), `n` the pair's unit normal at `p`,
//! `g = d_ij - |p_i - p_j| > 0` the pair's overlap (m, the repulsion's normal move of the
//! pair), `mu_c` the smaller of the two particles' coefficients,
//! `clamp(v, l) = v min(1, l / |v|)`, and the relaxation
//! `w_ij = 1 / (S_i + S_j)`, `S_i = sum_k s_i` over particle `i`'s frictional pairs at `p`
//! (0 for a pinned particle): the largest step for which the pairs' Jacobi iteration cannot
//! overshoot (Gershgorin: a pair's slip changes by at most `S_i + S_j` per unit change of
//! every multiplier at `i` or `j`), where the whole slip from every pair would carry a grain
//! sticking to `n` pinned partners back by `n - 1` slips. The relaxation sets how fast the
//! multipliers converge, not where: at the iteration's fixed point (`q` the iterate itself) a
//! pair inside the disc does not slip within the step (it sticks) and one on its rim slips
//! against its friction, whose move is `mu_c` times its normal one: Coulomb's law, one
//! coefficient for sticking and sliding. (A relaxed correction recomputed from the positions
//! alone would instead keep the fraction `1 - w` of the slip at its fixed point: a softer
//! contact, not a slower one.) A step's multipliers start from the pair's accepted ones of
//! the previous step (0 for a new pair): a resting contact carries the same load step after
//! step, so its multiplier starts converged, where from 0 the iterations would leave part of
//! each step's slip (docs/particles/granular.md). They are a run's state: a state file saves them
//! ([`crate::solve::SolverState::grain_contacts`]), and positions set from outside start the
//! body's from 0 ([`GrainFriction::forget`]). A pair's two moves are equal and opposite in momentum
//! (`m_i s_i = m_j s_j`) at every iteration, as its two copies of `lambda` are computed from
//! exactly negated inputs; each particle's sums run over its partners in a fixed order, so the
//! result is the same for any thread count.
//! With a body's rolling resistance (`Granular::rolling_resistance`) its grains also turn within
//! the step, and the slip above counts the turns' moves at the contact
//! ([`super::grain_rolling`]); without one no grain turns.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::real::Real;
use crate::solve::SavedGrainContact;

use super::grain_contacts::{Contact, Pairs};
use super::grain_rolling::GrainRolling;

/// The friction at the grains' contacts (module doc): the coefficients and the per-pair
/// multipliers, with their scratch.
pub(crate) struct GrainFriction<T: Real> {
    /// Each particle's `mu_c` (dimensionless; 0 for a particle of a body without one).
    coefficient: Vec<T>,
    /// The particle whose row holds each candidate entry.
    owner: Vec<u32>,
    /// Each candidate entry's multiplier `lambda_ij` (m) as accepted by the last iteration,
    /// and as computed by the last trial.
    accepted: Vec<Vector3<T>>,
    trial: Vec<Vector3<T>>,
    /// Each particle's sum of its shares in its frictional pairs `S_i` and its corrected
    /// position `q_i` (m).
    shares: Vec<T>,
    corrected: Vec<Vector3<T>>,
    /// The previous step's candidate pairs, whose multipliers start the next step's.
    previous_offsets: Vec<u32>,
    previous_indices: Vec<u32>,
    /// The grains' turns within the step ([`super::grain_rolling`]), if a body rolls.
    rolling: Option<GrainRolling<T>>,
}

impl<T: Real> GrainFriction<T> {
    /// The friction of particles with the coefficients `coefficient`, or `None` if none
    /// is above 0.
    pub fn of(coefficient: Vec<T>) -> Option<Self> {
        let n = coefficient.len();
        coefficient.iter().any(|&mu| mu > T::zero()).then(|| Self {
            coefficient,
            owner: Vec::new(),
            accepted: Vec::new(),
            trial: Vec::new(),
            shares: vec![T::zero(); n],
            previous_offsets: Vec::new(),
            previous_indices: Vec::new(),
            corrected: vec![Vector3::zeros(); n],
            rolling: None,
        })
    }

    /// With the grains of particles whose rolling resistance `mu_r` in `resistance`
    /// (dimensionless) is not `None` turning within the step ([`super::grain_rolling`]).
    pub fn with_rolling(mut self, resistance: Vec<Option<T>>) -> Self {
        self.rolling = GrainRolling::of(resistance);
        self
    }

    /// The multipliers that start a step with the candidate pairs `indices` in the rows of
    /// `offsets`: each pair's accepted one of the previous step, 0 for a new pair.
    pub fn start_step(&mut self, offsets: &[u32], indices: &[u32]) {
        let entries = *offsets.last().unwrap_or(&0) as usize;
        self.owner.clear();
        for (i, row) in offsets.windows(2).enumerate() {
            self.owner
                .extend(std::iter::repeat_n(i as u32, (row[1] - row[0]) as usize));
        }
        self.trial.clear();
        self.trial.resize(entries, Vector3::zeros());
        if self.previous_offsets.len() == offsets.len() {
            for (e, t) in self.trial.iter_mut().enumerate() {
                let (i, j) = (self.owner[e] as usize, indices[e]);
                let old = self.previous_offsets[i] as usize..self.previous_offsets[i + 1] as usize;
                if let Some(k) = self.previous_indices[old.clone()]
                    .iter()
                    .position(|&l| l == j)
                {
                    *t = self.accepted[old.start + k];
                }
            }
        }
        std::mem::swap(&mut self.accepted, &mut self.trial);
        self.trial.clear();
        self.trial.resize(entries, Vector3::zeros());
        self.previous_offsets.clear();
        self.previous_offsets.extend_from_slice(offsets);
        self.previous_indices.clear();
        self.previous_indices.extend_from_slice(indices);
        if let Some(rolling) = &mut self.rolling {
            rolling.start_step();
        }
    }

    /// The nonzero multipliers the next step starts from (the accepted ones of the last
    /// step, or those restored), each with its pair.
    pub fn saved(&self) -> Vec<SavedGrainContact> {
        let mut saved = Vec::new();
        for (i, row) in self.previous_offsets.windows(2).enumerate() {
            for e in row[0] as usize..row[1] as usize {
                if self.accepted[e] != Vector3::zeros() {
                    saved.push(SavedGrainContact {
                        particles: [i as u32, self.previous_indices[e]],
                        multiplier: self.accepted[e].map(|c| c.to_f64()),
                    });
                }
            }
        }
        saved
    }

    /// Makes `contacts` (checked: distinct pairs of the family's particles) the multipliers
    /// the next step starts from, every other pair's from 0.
    pub fn restore(&mut self, contacts: &[SavedGrainContact]) {
        let n = self.coefficient.len();
        self.previous_offsets.clear();
        self.previous_offsets.resize(n + 1, 0);
        for c in contacts {
            self.previous_offsets[c.particles[0] as usize + 1] += 1;
        }
        for i in 0..n {
            self.previous_offsets[i + 1] += self.previous_offsets[i];
        }
        let mut next: Vec<u32> = self.previous_offsets[..n].to_vec();
        self.previous_indices.clear();
        self.previous_indices.resize(contacts.len(), 0);
        self.accepted.clear();
        self.accepted.resize(contacts.len(), Vector3::zeros());
        for c in contacts {
            let [i, j] = c.particles;
            let e = next[i as usize] as usize;
            next[i as usize] += 1;
            self.previous_indices[e] = j;
            self.accepted[e] = c.multiplier.map(T::of);
        }
    }

    /// Starts the friction of every pair with a particle in `particles` from 0 at the next
    /// step (their positions were replaced: the contacts' loads are another configuration's).
    pub fn forget(&mut self, particles: std::ops::Range<usize>) {
        for (i, row) in self.previous_offsets.windows(2).enumerate() {
            for e in row[0] as usize..row[1] as usize {
                if particles.contains(&i)
                    || particles.contains(&(self.previous_indices[e] as usize))
                {
                    self.accepted[e] = Vector3::zeros();
                }
            }
        }
    }

    /// Takes the multipliers of the last trial as the iteration's.
    pub fn accept(&mut self) {
        std::mem::swap(&mut self.accepted, &mut self.trial);
        if let Some(rolling) = &mut self.rolling {
            rolling.accept();
        }
    }

    /// Whether particle `i` (not pinned) can be held where it started by its contacts
    /// (static friction, eq. 28, for a grain that yielded: [`super::static_friction`]): it
    /// touches a frictional partner among its candidates `partners` at the proposed positions
    /// `proposed` (m) of the step's last iteration (the accepted trial's), the particles'
    /// collider margins `margin` (m), and at every such contact the tangential part of its
    /// move in the step `d` (m, the move the hold takes back) lies within Coulomb's limit,
    /// `|(I - n n^T) d| <= mu_c min(g, |y* - y^t|)`, with `n`, `g` and `mu_c` the contact's
    /// normal, overlap (m) and coefficient ([`touching`], as the iterations found them), and
    /// `|y* - y^t|` the grain's inertial move (m: its momentum's and its weight's in the
    /// step, the normal load the grain itself puts on a contact). The overlap alone would
    /// count the load of the grains above, whose sideways pull the contact carries as well: a
    /// perfect-lattice column then held its edges (docs/particles/granular.md, round u).
    pub fn sticks(
        &self,
        proposed: &[Vector3<T>],
        margin: &[T],
        partners: &[u32],
        i: usize,
        moved: &Vector3<T>,
        inertial: T,
    ) -> bool {
        let mut contacts = partners
            .iter()
            .filter_map(|&j| touching(&self.coefficient, proposed, margin, i, j as usize))
            .peekable();
        contacts.peek().is_some()
            && contacts
                .all(|c| tangential(&c.normal, moved).norm() <= c.mu * c.overlap.min(inertial))
    }

    /// Adds each particle's friction move to `correction`, which holds its normal move
    /// `c_i^n` (m), after one relaxed step of the multipliers (module doc); `share(i, j)` is
    /// particle `i`'s share of its pair with `j`.
    pub fn add_moves(
        &mut self,
        pairs: &Pairs<'_, T>,
        share: &(impl Fn(usize, usize) -> T + Sync),
        correction: &mut [Vector3<T>],
    ) {
        let coefficient = &self.coefficient;
        let contact =
            |i: usize, j: usize| touching(coefficient, pairs.proposed, pairs.margin, i, j);
        let accepted = &self.accepted;
        let normal_move = &*correction;
        self.shares
            .par_iter_mut()
            .zip(self.corrected.par_iter_mut())
            .enumerate()
            .for_each(|(i, (shares, q))| {
                *shares = T::zero();
                *q = pairs.proposed[i] + normal_move[i];
                if pairs.pinned[i] {
                    return;
                }
                for e in pairs.row(i) {
                    let j = pairs.indices[e] as usize;
                    if let Some(c) = contact(i, j) {
                        let s = share(i, j);
                        *shares += s;
                        *q += tangential(&c.normal, &accepted[e]) * s;
                    }
                }
            });
        if let Some(rolling) = &mut self.rolling {
            rolling.turn(pairs, &contact, share, accepted, &self.shares);
        }
        let (owner, shares, corrected) = (&self.owner, &self.shares, &self.corrected);
        let rolling = self.rolling.as_ref();
        self.trial
            .par_iter_mut()
            .enumerate()
            .for_each(|(e, lambda)| {
                *lambda = Vector3::zeros();
                let (i, j) = (owner[e] as usize, pairs.indices[e] as usize);
                if pairs.pinned[i] {
                    return;
                }
                let Some(Contact {
                    normal,
                    overlap,
                    mu,
                }) = contact(i, j)
                else {
                    return;
                };
                let relaxation = T::one() / (shares[i] + shares[j]);
                let mut slip = (corrected[i] - pairs.start[i]) - (corrected[j] - pairs.start[j]);
                if let Some(rolling) = rolling {
                    slip -= rolling.rolled(pairs.margin, i, j, &normal);
                }
                let free = tangential(&normal, &(accepted[e] - slip * relaxation));
                let (length, limit) = (free.norm(), mu * overlap);
                *lambda = if length <= limit {
                    free
                } else {
                    free * (limit / length)
                };
            });
        let trial = &self.trial;
        correction.par_iter_mut().enumerate().for_each(|(i, c)| {
            for e in pairs.row(i) {
                if trial[e] != Vector3::zeros() {
                    *c += trial[e] * share(i, pairs.indices[e] as usize);
                }
            }
        });
    }
}

/// The contact of particle `i` with `j` at the proposed positions `proposed` (m), the
/// particles' coefficients `coefficient` (dimensionless) and collider margins `margin` (m), if
/// the pair touches and has friction (`mu_c`, the smaller coefficient, above 0); computed
/// from exactly negated inputs for `(j, i)`.
#[inline(always)]
fn touching<T: Real>(
    coefficient: &[T],
    proposed: &[Vector3<T>],
    margin: &[T],
    i: usize,
    j: usize,
) -> Option<Contact<T>> {
    let mu = coefficient[i].min(coefficient[j]);
    let gap = proposed[i] - proposed[j];
    let (distance, reach) = (gap.norm(), margin[i] + margin[j]);
    (mu > T::zero() && distance < reach && distance > T::zero()).then(|| Contact {
        normal: gap / distance,
        overlap: reach - distance,
        mu,
    })
}

/// The part of `v` in the plane normal to the unit vector `normal`, `(I - n n^T) v`.
#[inline(always)]
fn tangential<T: Real>(normal: &Vector3<T>, v: &Vector3<T>) -> Vector3<T> {
    v - normal * normal.dot(v)
}
