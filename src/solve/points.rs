//! The state every body family steps: the points of a family's bodies concatenated into one
//! range, in the simulation's precision, and the phases of a step that act on points alone
//! (predict and finish, Lu et al. 2023, Algorithm 1 lines 2 and 16).

use std::ops::Range;

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::collider::ColliderModel;
use crate::real::Real;

use super::body::Body;
use super::clearance::Clearance;

/// The points of one family's bodies: identities and ranges, state and iterates.
pub(crate) struct Points<T: Real> {
    /// Identity of each body, to detect a changed body list.
    pub ids: Vec<u64>,
    /// Point range of each body.
    pub ranges: Vec<Range<usize>>,
    /// The world point (m) the points' positions are measured from, in f64: the world
    /// position of point `i` is `origin + y_i`, exact at the edge ([`Self::load`],
    /// [`Self::store`]). Zero for membranes; a particle family's near its bodies
    /// ([`crate::solve::frame`]), so that a position holds `eps` of its distance from there
    /// rather than from the world origin.
    pub origin: Vector3<f64>,
    /// Lumped mass of each point (kg).
    pub mass: Vec<T>,
    /// How far each point keeps from a collider's surface (m): a membrane vertex's half
    /// thickness.
    pub margin: Vec<T>,
    /// Positions at the start of the step, y_t (m).
    pub y_start: Vec<Vector3<T>>,
    /// Velocities v_t (m/s).
    pub velocity: Vec<Vector3<T>>,
    /// Inertial target y* (m; pinned points: their target).
    pub y_star: Vec<Vector3<T>>,
    /// Current iterate and the next one (m).
    pub y: Vec<Vector3<T>>,
    pub y_next: Vec<Vector3<T>>,
    /// The iterate before `y`, kept only while Chebyshev acceleration needs it (else empty).
    pub y_prev: Vec<Vector3<T>>,
    pub pinned: Vec<bool>,
    /// False for a point no collider acts on (a particle body's ghost, [`Self::colliders_of`]).
    pub collides: Vec<bool>,
    /// Partial sums of the energy reductions (reused).
    pub energy_chunks: Vec<f64>,
    /// How far each point was from the colliders when last measured in this step.
    pub clearance: Clearance<T>,
}

impl<T: Real> Points<T> {
    /// Room for the points of `bodies`, with each point's mass (kg) and collider margin (m);
    /// the state is loaded by [`Self::load`].
    pub fn new<B: Body>(bodies: &[&mut B], mass: Vec<T>, margin: Vec<T>) -> Self {
        let mut ids = Vec::with_capacity(bodies.len());
        let mut ranges = Vec::with_capacity(bodies.len());
        let mut start = 0;
        for body in bodies {
            let n = body.num_points();
            ids.push(body.id());
            ranges.push(start..start + n);
            start += n;
        }
        debug_assert!(mass.len() == start && margin.len() == start);
        let zeros = vec![Vector3::zeros(); start];
        Self {
            ids,
            ranges,
            origin: Vector3::zeros(),
            mass,
            margin,
            y_start: zeros.clone(),
            velocity: zeros.clone(),
            y_star: zeros.clone(),
            y: zeros.clone(),
            y_next: zeros,
            y_prev: Vec::new(),
            pinned: vec![false; start],
            collides: vec![true; start],
            energy_chunks: Vec::new(),
            clearance: Clearance::default(),
        }
    }

    /// The colliders point `k` meets: all of `colliders`, none where it does not collide.
    #[inline(always)]
    pub fn colliders_of<'a>(
        collides: &[bool],
        k: usize,
        colliders: &'a [ColliderModel<T>],
    ) -> &'a [ColliderModel<T>] {
        if collides[k] {
            colliders
        } else {
            &[]
        }
    }

    /// True when the points were laid out for exactly these bodies.
    pub fn matches<B: Body>(&self, bodies: &[&mut B]) -> bool {
        self.ids.len() == bodies.len() && self.ids.iter().zip(bodies).all(|(id, b)| *id == b.id())
    }

    /// Copies the bodies' positions (less [`Self::origin`], in f64), velocities and pins in;
    /// pinned points get their target as inertial target. Every position is loaded from the
    /// body, never kept from the last step: a fresh solver given the same bodies (a restored
    /// run) loads the same state, bit for bit.
    pub fn load<B: Body>(&mut self, bodies: &[&mut B]) {
        for (body, range) in bodies.iter().zip(&self.ranges) {
            let base = range.start;
            for (k, (x, v)) in body.positions().iter().zip(body.velocities()).enumerate() {
                self.y_start[base + k] = (x - self.origin).map(T::of);
                self.velocity[base + k] = v.map(T::of);
            }
        }
        self.load_pins(bodies);
    }

    /// Copies the bodies' pins in: the flags, and their targets (less [`Self::origin`], in
    /// f64) into `y_star`.
    pub fn load_pins<B: Body>(&mut self, bodies: &[&mut B]) {
        self.pinned.fill(false);
        for (body, range) in bodies.iter().zip(&self.ranges) {
            for (&i, target) in body.pins() {
                self.pinned[range.start + i as usize] = true;
                self.y_star[range.start + i as usize] = (target - self.origin).map(T::of);
            }
        }
    }

    /// Copies the state back into the bodies (in f64, positions plus [`Self::origin`]).
    pub fn store<B: Body>(&self, bodies: &mut [&mut B]) {
        for (body, range) in bodies.iter_mut().zip(&self.ranges) {
            let (x, v) = body.state_mut();
            for (k, i) in range.clone().enumerate() {
                x[k] = self.origin + self.y_start[i].map(|c| c.to_f64());
                v[k] = self.velocity[i].map(|c| c.to_f64());
            }
        }
    }

    /// The body and local point index of a point.
    pub fn locate(&self, point: usize) -> (usize, usize) {
        let body = self
            .ranges
            .iter()
            .position(|r| r.contains(&point))
            .unwrap_or(0);
        (body, point - self.ranges.get(body).map_or(0, |r| r.start))
    }

    /// The first free point whose move in the step by its velocity and `gravity` (m/s^2),
    /// `|h v_t + h^2 g|` (m, in f64, `h` in s), has no finite square (above about 1.3e154 m):
    /// no distance can measure where it goes (a granular body's contact search would be asked
    /// for an infinite radius), so the step diverges before it starts.
    pub fn first_unbounded_move(&self, h: f64, gravity: Vector3<f64>) -> Option<usize> {
        let kick = gravity * (h * h);
        (0..self.velocity.len()).into_par_iter().find_first(|&i| {
            let moved = self.velocity[i].map(|c| c.to_f64()) * h + kick;
            !self.pinned[i] && !moved.norm_squared().is_finite()
        })
    }

    /// `y* = y_t + h v_t + h^2 g` for free points (h in s, g in m/s^2); the initial iterate is
    /// `y*` (Algorithm 1, line 2).
    pub fn predict(&mut self, h: T, gravity: Vector3<T>) {
        let (y_start, velocity, pinned) = (&self.y_start, &self.velocity, &self.pinned);
        let kick = gravity * (h * h);
        self.y_star
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, star)| {
                if !pinned[i] {
                    *star = y_start[i] + velocity[i] * h + kick;
                }
            });
        self.y.copy_from_slice(&self.y_star);
    }

    /// The first point whose new velocity `(y_{t+1} - y_t) / h` would not be finite (finite
    /// positions can still overflow there) or, unless it is pinned (its motion prescribed),
    /// would exceed `max_speed` (m/s), with that speed (m/s, [`step_speed`]); checked before
    /// [`finish`](Self::finish) changes anything, so that a diverged step leaves the bodies at
    /// their last good state.
    pub fn first_bad_velocity(&self, h: T, max_speed: f64) -> Option<(usize, f64)> {
        let inv_h = 1.0 / h.to_f64();
        (0..self.y.len())
            .into_par_iter()
            .map(|i| (i, step_speed(&self.y[i], &self.y_start[i], inv_h)))
            .find_first(|&(i, s)| s.is_infinite() || (s > max_speed && !self.pinned[i]))
    }

    /// `v_{t+1} = (y_{t+1} - y_t) / h`, `y_t <- y_{t+1}` (Algorithm 1, line 16).
    pub fn finish(&mut self, h: T) {
        let inv_h = T::one() / h;
        let y = &self.y;
        self.velocity
            .par_iter_mut()
            .zip(self.y_start.par_iter_mut())
            .enumerate()
            .for_each(|(i, (v, start))| {
                *v = (y[i] - *start) * inv_h;
                *start = y[i];
            });
    }
}

/// Moves within this many ulps of the coordinates are round-off, never too fast.
const ROUNDOFF_MOVES: f64 = 8.0;

/// The speed (m/s) of a point that moves from `y_start` to `y` in a step of `1 / inv_h`
/// seconds: infinite where the velocity would not be finite, 0 for a move within the round-off
/// of the coordinates (`ROUNDOFF_MOVES` ulps of the larger of `|y_t|`, `|y_{t+1}|`), so that a
/// tiny `h` does not turn one rounding into a divergence. Also the GPU backend's reading of a
/// vertex its kernels flagged.
pub(crate) fn step_speed<T: Real>(y: &Vector3<T>, y_start: &Vector3<T>, inv_h: f64) -> f64 {
    let epsilon = T::default_epsilon().to_f64();
    // The velocity `finish` stores is in the solver's precision: a move whose velocity
    // overflows it there (f32 above 3.4e38 m/s) is not finite, whatever f64 makes of it.
    let stored = (y - y_start) * T::of(inv_h);
    let d = (y - y_start).map(|c| c.to_f64());
    let v = d * inv_h;
    let stored_finite = stored.iter().all(|c| c.to_f64().is_finite());
    if !(stored_finite && v.iter().all(|c| c.is_finite())) {
        return f64::INFINITY;
    }
    let largest = v.amax();
    let scale = y.amax().to_f64().max(y_start.amax().to_f64());
    if largest == 0.0 || d.amax() <= ROUNDOFF_MOVES * epsilon * scale {
        return 0.0;
    }
    // Scaled, so that a finite speed above 1e154 m/s does not overflow the norm.
    largest * (v / largest).norm()
}
