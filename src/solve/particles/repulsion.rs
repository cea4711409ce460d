//! Repulsion between particle bodies: a minimum-distance constraint between the particles of
//! different bodies, so that two bodies collide without passing through each other (DESIGN.md
//! section 6, "Boundaries and couplings"; the 2017 paper names no form for it). Within a
//! granular body too ([`crate::particles::Granular`]): its grains are balls that keep apart,
//! while the bonds, searched anew every step, would let them pass through each other. And
//! between the fluid and the solid particles of a mixed body
//! ([`crate::particles::RegionMaterial`]): across that boundary there are no bonds, and the
//! fluid's one-sided density constraints do not part a lone fluid particle from a solid one
//! (measured: a fluid particle came within 0.05 spacings of the solid half of a pushed blob).
//!
//! Each particle is a ball of its collider margin (half a spacing for a solid, half the
//! thickness of a shell, the radius of a rod): particles `i`, `j` of different bodies keep
//! `|y_i - y_j| >= d_ij = margin_i + margin_j` (m). Ghost particles take no part, as in
//! collisions. The constraint is projected in the local step, where the colliders are: the
//! global move proposes `p = y + alpha delta` for every particle, and each particle is moved by
//! its share of every violated pair at the proposed positions,
//! `c_i = sum_j D_j / (D_i + D_j) (d_ij - |p_i - p_j|) dir(p_i - p_j)` (m) between solid
//! bodies (elastic or plastic, no fluid particle, not granular: those the coarse step moves in
//! contact), a Jacobi pass of position-based dynamics in the metric of the Jacobi diagonal `D_i = m_i + h^2 L_ii` (kg),
//! as the colliders project: the two moves of a pair close its gap exactly, and `D_i c_i =
//! -D_j c_j`. The move `c_i` counts as a reaction in the convergence measure, as a collider's
//! does, so at the iteration's fixed point (`c_i = -alpha delta_i`) an isolated pair sits
//! exactly `d_ij` apart, and the pair's reactions in the residual, `r_i = -D_i c_i`, are equal
//! and opposite: the converged step keeps the bodies' momentum, and the coarse step
//! ([`super::coarse`]), which balances each body's net residual against its contacts, has
//! nothing left to move at the fixed point. (Shares by mass, `m_j / (m_i + m_j)`, leave the
//! pair a net force at the fixed point wherever its two particles' `D / m` differ, as between
//! a block's corner and the face of another.) Every other pair keeps the mass shares,
//! `m_j / (m_i + m_j)`: grains of one granular body, and any pair with a grain or a fluid
//! particle. No coarse step moves such a body while it touches anything, so the metric buys
//! nothing there, and the granular and fluid calibrations (tests/test_granular.py,
//! tests/test_wet_sand.py) were made with mass shares: with Jacobi-metric shares between sand
//! and water, the sand bed spread differently under the water and a grain the water had wetted
//! (theta 0.48) ended more than 2.5 spacings from it (test_wet_sand asks below 0.2).
//!
//! Candidates are found once per step, at its start, by cell lists ([`find_horizons`]) among
//! the colliding particles within `2 d_max + 2 s`, with `d_max` the largest margin and `s` the
//! largest predicted move of the step, `|h v + h^2 g|` (m; a pinned particle's move to its
//! target): a pair that closes by more than that within one step can be missed (a time step
//! far too long for the bodies' speeds).

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::error::Result;
use crate::geometry::find_horizons;
use crate::real::Real;
use crate::solve::points::Points;
use crate::solve::SavedGrainContact;

use super::grain_contacts::Pairs;
use super::grain_friction::GrainFriction;

/// The repulsion of the particle bodies of one family, with its scratch.
pub(crate) struct Repulsion<T: Real> {
    /// Body of each particle (an index into the family's body list).
    body: Vec<u32>,
    /// Per body, whether its own particles repel each other (a granular body).
    within: Vec<bool>,
    /// Per body, whether it is solid: two solid bodies' pairs share their moves in the Jacobi
    /// metric (module doc).
    solid: Vec<bool>,
    /// Candidate pairs of this step in compressed rows (particles of other bodies only).
    offsets: Vec<u32>,
    indices: Vec<u32>,
    /// The proposed positions `p` (m) and each particle's move `c_i` (m).
    proposed: Vec<Vector3<T>>,
    correction: Vec<Vector3<T>>,
    /// The friction at the contacts ([`super::grain_friction`]), if a body has a contact
    /// friction coefficient `mu_c` above 0.
    friction: Option<GrainFriction<T>>,
}

impl<T: Real> Repulsion<T> {
    /// The repulsion of the bodies laid out in `points`, those marked in `within` among
    /// their own particles too, and of the particles marked in `fluid` (the fluid particles
    /// of mixed bodies) with the rest of their body; `None` for a single body that does not
    /// repel itself.
    pub fn of(points: &Points<T>, mut within: Vec<bool>, fluid: &[bool]) -> Option<Self> {
        let mixed = fluid.iter().any(|&f| f);
        if points.ranges.len() < 2 && !within.iter().any(|&w| w) && !mixed {
            return None;
        }
        let n = points.mass.len();
        let mut body = vec![0; n];
        for (b, range) in points.ranges.iter().enumerate() {
            body[range.clone()].fill(b as u32);
        }
        // A mixed body's fluid particles form a body of their own, which repels nothing
        // within.
        let bodies = points.ranges.len() as u32;
        for (b, &f) in body.iter_mut().zip(fluid) {
            *b += if f { bodies } else { 0 };
        }
        within.resize(2 * bodies as usize, false);
        Some(Self {
            body,
            within,
            solid: Vec::new(),
            offsets: vec![0; n + 1],
            indices: Vec::new(),
            proposed: vec![Vector3::zeros(); n],
            correction: vec![Vector3::zeros(); n],
            friction: None,
        })
    }

    /// With Coulomb friction at the contacts ([`super::grain_friction`]) of the particles of
    /// the bodies whose coefficient `mu_c` in `per_body` (dimensionless) is above 0.
    pub fn with_friction(mut self, per_body: &[f64]) -> Self {
        let of = |b: u32| per_body.get(b as usize).copied().unwrap_or(0.0);
        self.friction = GrainFriction::of(self.body.iter().map(|&b| T::of(of(b))).collect());
        self
    }

    /// With the grains of the bodies whose rolling resistance `mu_r` in `per_body`
    /// (dimensionless) is not `None` turning within the step ([`super::grain_rolling`]; only
    /// at contacts with friction, so after [`Self::with_friction`]).
    pub fn with_rolling(mut self, per_body: &[Option<f64>]) -> Self {
        let of = |b: u32| per_body.get(b as usize).copied().flatten().map(T::of);
        let resistance = self.body.iter().map(|&b| of(b)).collect();
        self.friction = self.friction.map(|f| f.with_rolling(resistance));
        self
    }

    /// With the moves of pairs between the bodies marked in `solid` (per body) shared in the
    /// Jacobi metric (module doc); mass shares for the rest.
    pub fn with_solid(mut self, solid: &[bool]) -> Self {
        self.solid = solid.to_vec();
        self.solid.resize(self.within.len(), false);
        self
    }

    /// The candidate pairs of the step of `h` (s) under `gravity` (m/s^2) that starts at the
    /// loaded positions, velocities and pins of `points`.
    pub fn start_step(&mut self, points: &Points<T>, h: f64, gravity: [f64; 3]) -> Result<()> {
        let colliding: Vec<u32> = (0..points.mass.len() as u32)
            .filter(|&i| points.collides[i as usize])
            .collect();
        let kick = Vector3::from(gravity) * (h * h);
        let (d_max, s) = colliding
            .iter()
            .map(|&i| {
                let i = i as usize;
                let moved = if points.pinned[i] {
                    (points.y_star[i] - points.y_start[i]).map(|c| c.to_f64())
                } else {
                    points.velocity[i].map(|c| c.to_f64()) * h + kick
                };
                (points.margin[i].to_f64(), moved.norm())
            })
            .fold((0.0, 0.0), |(a, b), (d, m)| {
                (f64::max(a, d), f64::max(b, m))
            });
        let at: Vec<Vector3<T>> = colliding
            .iter()
            .map(|&i| points.y_start[i as usize])
            .collect();
        let near = find_horizons(&at, 2.0 * d_max + 2.0 * s)?;
        self.offsets.clear();
        self.offsets.push(0);
        self.indices.clear();
        let mut next = colliding.iter().enumerate().peekable();
        for i in 0..self.body.len() {
            if let Some((k, _)) = next.next_if(|(_, &c)| c as usize == i) {
                let body = self.body[i];
                let within = self.within[body as usize];
                self.indices.extend(
                    near.of(k)
                        .iter()
                        .map(|&l| colliding[l as usize])
                        .filter(|&j| within || self.body[j as usize] != body),
                );
            }
            self.offsets.push(self.indices.len() as u32);
        }
        if let Some(friction) = &mut self.friction {
            friction.start_step(&self.offsets, &self.indices);
        }
        Ok(())
    }

    /// Each particle's move `c_i` (m) for the proposed moves `alpha delta` (m) from the
    /// iterate, among the candidates of [`Self::start_step`], `diagonal(i)` the Jacobi
    /// diagonal `D_i` (kg) that weighs particle `i`'s share.
    pub fn correct(
        &mut self,
        points: &Points<T>,
        delta: &[Vector3<T>],
        alpha: T,
        diagonal: impl Fn(usize) -> T + Sync,
    ) {
        let (y, pinned) = (&points.y, &points.pinned);
        self.proposed.par_iter_mut().enumerate().for_each(|(i, p)| {
            *p = if pinned[i] {
                y[i]
            } else {
                y[i] + delta[i] * alpha
            };
        });
        let (proposed, offsets, indices) = (&self.proposed, &self.offsets, &self.indices);
        let (margin, body, solid) = (&points.margin, &self.body, &self.solid);
        let share = |i: usize, j: usize| share_of(body, solid, points, &diagonal, i, j);
        self.correction
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, c)| {
                *c = Vector3::zeros();
                if pinned[i] {
                    return;
                }
                for &j in &indices[offsets[i] as usize..offsets[i + 1] as usize] {
                    let j = j as usize;
                    let gap = proposed[i] - proposed[j];
                    let (distance, reach) = (gap.norm(), margin[i] + margin[j]);
                    if distance >= reach || distance == T::zero() {
                        continue;
                    }
                    *c += gap * (share(i, j) * (reach - distance) / distance);
                }
            });
        if let Some(friction) = &mut self.friction {
            let pairs = Pairs {
                proposed,
                start: &points.y_start,
                margin,
                pinned,
                offsets,
                indices,
            };
            friction.add_moves(&pairs, &share, &mut self.correction);
        }
    }

    /// Takes the friction's multipliers of the last [`Self::correct`] as the iteration's (the
    /// trial the line search accepted, [`super::grain_friction`]).
    pub fn accept(&mut self) {
        if let Some(friction) = &mut self.friction {
            friction.accept();
        }
    }

    /// The grains' contact friction multipliers the next step starts from
    /// ([`GrainFriction::saved`]); none without friction.
    pub fn saved_friction(&self) -> Vec<SavedGrainContact> {
        self.friction
            .as_ref()
            .map_or_else(Vec::new, GrainFriction::saved)
    }

    /// Whether particle `i` (not pinned)'s grain contacts at the last [`Self::correct`] (the
    /// trial the step's last iteration accepted) can hold it where it started, its move in the
    /// step `moved` (m), its inertial move `inertial` (m) and the particles' collider margins
    /// `margin` (m) ([`GrainFriction::sticks`]); false without contact friction.
    pub fn sticks(&self, margin: &[T], i: usize, moved: &Vector3<T>, inertial: T) -> bool {
        self.friction
            .as_ref()
            .is_some_and(|f| f.sticks(&self.proposed, margin, self.partners(i), i, moved, inertial))
    }

    /// Whether some body has contact friction.
    pub fn has_friction(&self) -> bool {
        self.friction.is_some()
    }

    /// Restores the multipliers of [`Self::saved_friction`] ([`GrainFriction::restore`]).
    pub fn restore_friction(&mut self, contacts: &[SavedGrainContact]) {
        if let Some(friction) = &mut self.friction {
            friction.restore(contacts);
        }
    }

    /// Starts the contact friction of the particles in `particles` from 0
    /// ([`GrainFriction::forget`]).
    pub fn forget_friction(&mut self, particles: std::ops::Range<usize>) {
        if let Some(friction) = &mut self.friction {
            friction.forget(particles);
        }
    }

    /// The candidate partners of particle `i` this step (particles of other bodies, or of its
    /// own granular body).
    #[inline(always)]
    pub fn partners(&self, i: usize) -> &[u32] {
        &self.indices[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }

    /// Particle `i`'s share of its pair with particle `j` (module doc), `diagonal(i)` the
    /// Jacobi diagonal `D_i` (kg): the fraction of the pair's overlap that `i` moves.
    pub fn share(
        &self,
        points: &Points<T>,
        diagonal: &impl Fn(usize) -> T,
        i: usize,
        j: usize,
    ) -> T {
        share_of(&self.body, &self.solid, points, diagonal, i, j)
    }

    /// Particle `i`'s move (m) from the last [`Self::correct`].
    #[inline(always)]
    pub fn of_particle(&self, i: usize) -> Vector3<T> {
        self.correction[i]
    }
}

/// Particle `i`'s share of its pair with `j` (module doc) for the bodies `body` (per particle)
/// of which `solid` marks those that share in the Jacobi metric `diagonal` (kg).
#[inline(always)]
fn share_of<T: Real>(
    body: &[u32],
    solid: &[bool],
    points: &Points<T>,
    diagonal: &impl Fn(usize) -> T,
    i: usize,
    j: usize,
) -> T {
    let in_metric = |b: u32| solid.get(b as usize).copied().unwrap_or(false);
    if points.pinned[j] {
        T::one()
    } else if body[i] != body[j] && in_metric(body[i]) && in_metric(body[j]) {
        let (d_i, d_j) = (diagonal(i), diagonal(j));
        d_j / (d_i + d_j)
    } else {
        points.mass[j] / (points.mass[i] + points.mass[j])
    }
}
