//! Colliders: a shape (a signed distance field: analytic, or a mesh sampled on a grid), a
//! constant velocity and a Coulomb friction coefficient. After each global iteration every
//! free point is kept at least its margin (a membrane vertex: half the thickness) outside
//! every collider.

use std::sync::Arc;

use nalgebra::{Matrix3, Vector3};

use super::pose::{rotation_matrix, Pose};
use super::sdf::SdfGrid;
use crate::error::{invalid, Result};
use crate::real::Real;
use crate::symmetric::SymmetricMatrix3;

/// The solid shape of a collider (SI units), in its own frame (the pose given at time 0).
/// Cloning is cheap: a mesh's grid is shared.
/// The most rounds [`ColliderModel::push_out`] takes to settle the normal at its end.
pub(crate) const PUSH_ROUNDS: usize = 12;

/// A push has settled when a round moves it by at most this many units of round-off of its
/// position (`epsilon (|p| + 1 m)`).
pub(crate) const PUSH_SETTLE_ULPS: f64 = 16.0;

#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// Half-space `{x : (x - point) . normal >= 0}` is free; `normal` is unit.
    Plane {
        point: Vector3<f64>,
        normal: Vector3<f64>,
    },
    /// Solid ball.
    Sphere { center: Vector3<f64>, radius: f64 },
    /// Solid oriented box: `axes` (orthonormal columns, det +1) are its edge directions,
    /// `half_extents` its half side lengths along them.
    Box {
        center: Vector3<f64>,
        half_extents: Vector3<f64>,
        axes: Matrix3<f64>,
    },
    /// Solid capsule: the points within `radius` of the segment `a`-`b`.
    Capsule {
        a: Vector3<f64>,
        b: Vector3<f64>,
        radius: f64,
    },
    /// Solid bounded by a closed triangle mesh, as a signed distance grid.
    Mesh(Arc<SdfGrid>),
}

fn finite(name: &str, v: &Vector3<f64>) -> Result<()> {
    if v.iter().all(|c| c.is_finite()) {
        Ok(())
    } else {
        Err(invalid!("{name} must be finite, got {:?}", v.as_slice()))
    }
}

fn positive(name: &str, v: f64) -> Result<f64> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(invalid!("{name} must be a finite length > 0 m, got {v}"))
    }
}

impl Shape {
    /// A plane through `point` whose free side is the one `normal` points to.
    pub fn plane(point: [f64; 3], normal: [f64; 3]) -> Result<Self> {
        let (point, normal) = (Vector3::from(point), Vector3::from(normal));
        finite("plane point", &point)?;
        let norm = normal.norm();
        if !(norm.is_finite() && norm > 1e-12) {
            return Err(invalid!(
                "plane normal must be a finite non-zero vector, got {:?}",
                normal.as_slice()
            ));
        }
        Ok(Self::Plane {
            point,
            normal: normal / norm,
        })
    }

    /// A sphere of `radius` (m, > 0) at `center`.
    pub fn sphere(center: [f64; 3], radius: f64) -> Result<Self> {
        let center = Vector3::from(center);
        finite("sphere center", &center)?;
        Ok(Self::Sphere {
            center,
            radius: positive("sphere radius", radius)?,
        })
    }

    /// A box of `half_extents` (m, each > 0) at `center`, turned by the rotation matrix
    /// `rotation` (orthonormal, det +1; its columns are the box's axes).
    pub fn cuboid(
        center: [f64; 3],
        half_extents: [f64; 3],
        rotation: [[f64; 3]; 3],
    ) -> Result<Self> {
        let center = Vector3::from(center);
        finite("box center", &center)?;
        for (k, h) in half_extents.iter().enumerate() {
            positive(&format!("box half_extents[{k}]"), *h)?;
        }
        Ok(Self::Box {
            center,
            half_extents: Vector3::from(half_extents),
            axes: rotation_matrix("box rotation", rotation)?,
        })
    }

    /// A capsule of `radius` (m, > 0) around the segment from `a` to `b` (m).
    pub fn capsule(a: [f64; 3], b: [f64; 3], radius: f64) -> Result<Self> {
        let (a, b) = (Vector3::from(a), Vector3::from(b));
        finite("capsule end a", &a)?;
        finite("capsule end b", &b)?;
        Ok(Self::Capsule {
            a,
            b,
            radius: positive("capsule radius", radius)?,
        })
    }

    /// The solid bounded by the closed mesh `vertices` (m) / `triangles`, as a signed distance
    /// grid of `resolution` cells along the mesh's longest side, padded by `margin` (m); see
    /// [`SdfGrid::build`].
    pub fn mesh(
        vertices: Vec<[f64; 3]>,
        triangles: Vec<[i64; 3]>,
        resolution: usize,
        margin: Option<f64>,
    ) -> Result<Self> {
        Ok(Self::Mesh(Arc::new(SdfGrid::build(
            vertices, triangles, resolution, margin,
        )?)))
    }

    /// Signed distance from the surface (m), positive outside.
    pub fn signed_distance(&self, x: &Vector3<f64>) -> f64 {
        self.to_real::<f64>().signed_distance(x)
    }

    /// The collider in the simulation's precision.
    pub fn to_real<T: Real>(&self) -> ShapeModel<T> {
        self.to_real_about(&Vector3::zeros())
    }

    /// The shape moved by `-anchor` (m, in its own frame; taken in f64), in the simulation's
    /// precision: its numbers (offset, centre, ends) are then of the size of their distance
    /// from `anchor`, not from the shape frame's origin ([`ColliderModel::in_frame`]). A mesh
    /// keeps its grid and `anchor`, added in f64 to a point before the grid is queried.
    pub fn to_real_about<T: Real>(&self, anchor: &Vector3<f64>) -> ShapeModel<T> {
        let v = |a: &Vector3<f64>| (a - anchor).map(T::of);
        match *self {
            Self::Plane { point, normal } => ShapeModel::Plane {
                offset: T::of((point - anchor).dot(&normal)),
                normal: normal.map(T::of),
            },
            Self::Sphere { center, radius } => ShapeModel::Sphere {
                center: v(&center),
                radius: T::of(radius),
            },
            Self::Box {
                center,
                half_extents,
                axes,
            } => ShapeModel::Box {
                center: v(&center),
                half_extents: half_extents.map(T::of),
                axes: axes.map(T::of),
            },
            Self::Capsule { a, b, radius } => ShapeModel::Capsule {
                a: v(&a),
                b: v(&b),
                radius: T::of(radius),
            },
            Self::Mesh(ref grid) => ShapeModel::Mesh(grid.clone(), *anchor),
        }
    }
}

/// A collider: a shape moving at a constant `velocity` (m/s) from its pose at time 0, with
/// Coulomb `friction` (dimensionless, >= 0) against the membranes it touches. A solver may
/// move it further by poses ([`crate::collider::MovingCollider`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Collider {
    pub shape: Shape,
    pub velocity: Vector3<f64>,
    pub friction: f64,
}

impl Collider {
    /// A collider of `shape`, checking `friction >= 0` and a finite `velocity`.
    pub fn new(shape: Shape, friction: f64, velocity: [f64; 3]) -> Result<Self> {
        if !(friction.is_finite() && friction >= 0.0) {
            return Err(invalid!(
                "friction must be a finite coefficient >= 0, got {friction}"
            ));
        }
        let velocity = Vector3::from(velocity);
        finite("collider velocity", &velocity)?;
        Ok(Self {
            shape,
            velocity,
            friction,
        })
    }

    /// A static, frictionless collider.
    pub fn fixed(shape: Shape) -> Self {
        Self {
            shape,
            velocity: Vector3::zeros(),
            friction: 0.0,
        }
    }

    /// Signed distance (m, positive outside) at time `time` (s), moved by the velocity alone.
    pub fn signed_distance(&self, x: &Vector3<f64>, time: f64) -> f64 {
        self.shape
            .to_real::<f64>()
            .signed_distance(&(x - self.velocity * time))
    }
}

/// A collider during one step: its shape in the pose it reaches at the end of the step, the
/// rigid map from there back to its pose at the start (for friction: where the collider's
/// material point under a contact was), and its friction.
#[derive(Debug, Clone, PartialEq)]
pub struct ColliderModel<T: Real> {
    shape: ShapeModel<T>,
    /// End pose `x = R b + t` of a shape point `b`.
    rotation: Matrix3<T>,
    translation: Vector3<T>,
    /// `x -> R_0 R^T (x - t) + t_0`: a material point's start position from its end position.
    back_rotation: Matrix3<T>,
    back_translation: Vector3<T>,
    pub friction: T,
}

impl<T: Real> ColliderModel<T> {
    /// `collider` moving during a step from the pose `start` to the pose `end`.
    pub fn new(collider: &Collider, start: &Pose, end: &Pose) -> Self {
        Self::with_shape(collider, collider.shape.to_real(), start, end)
    }

    /// [`Self::new`] in the frame whose origin is the world point `origin` (m): the frame's
    /// point `x` is the world point `origin + x` (a particle family's frame,
    /// [`crate::solve::points::Points::origin`]). The shape is re-anchored, in f64, at the
    /// place `a = R^T (origin - t)` of its frame the frame's origin has under the end pose
    /// `(R, t)` ([`Shape::to_real_about`]), and each pose `(R_k, t_k)` becomes
    /// `(R_k, R_k a + t_k - origin)`, so that the numbers a distance near the frame's origin
    /// is computed from are of the size of that distance, not of `|origin|`: in f32 a floor
    /// 10 m from the world origin is resolved to `eps` times the body's size, not
    /// `eps 10 m` (docs/architecture.md, "Particle frame"). A mesh keeps its grid, queried
    /// in f64 at the point plus the anchor, so the point reaches it in `T` as a small number.
    pub fn in_frame(collider: &Collider, start: &Pose, end: &Pose, origin: &Vector3<f64>) -> Self {
        let anchor = end.rotation.tr_mul(&(origin - end.translation));
        let framed = |pose: &Pose| Pose {
            rotation: pose.rotation,
            translation: pose.rotation * anchor + pose.translation - origin,
        };
        let shape = collider.shape.to_real_about(&anchor);
        Self::with_shape(collider, shape, &framed(start), &framed(end))
    }

    /// `collider` as `shape` (in the simulation's precision) from the pose `start` to `end`.
    fn with_shape(collider: &Collider, shape: ShapeModel<T>, start: &Pose, end: &Pose) -> Self {
        let back = end.back_to(start);
        Self {
            shape,
            rotation: end.rotation.map(T::of),
            translation: end.translation.map(T::of),
            back_rotation: back.rotation.map(T::of),
            back_translation: back.translation.map(T::of),
            friction: T::of(collider.friction),
        }
    }

    /// The shape, in its own frame.
    pub fn shape(&self) -> &ShapeModel<T> {
        &self.shape
    }

    /// The translation `t` of the end pose (m); for a collider that does not turn, the shape
    /// is the given geometry moved by `t`.
    pub fn translation(&self) -> Vector3<T> {
        self.translation
    }

    /// Whether the collider keeps its given orientation during the step (only translates).
    pub fn translates_only(&self) -> bool {
        self.rotation == Matrix3::identity() && self.back_rotation == Matrix3::identity()
    }

    /// `x` in the shape's frame, `R^T (x - t)`.
    #[inline]
    fn local(&self, x: &Vector3<T>) -> Vector3<T> {
        self.rotation.tr_mul(&(x - self.translation))
    }

    /// Signed distance (m, positive outside).
    #[inline]
    pub fn signed_distance(&self, x: &Vector3<T>) -> T {
        self.shape.signed_distance(&self.local(x))
    }

    /// Unit outward normal, the gradient of the signed distance.
    #[inline]
    pub fn normal(&self, x: &Vector3<T>) -> Vector3<T> {
        self.rotation * self.shape.normal(&self.local(x))
    }

    /// The unit outward normal at `x` where the surface is flat within `edge` (m) of the
    /// point of it nearest `x` ([`ShapeModel::flat_normal`]), else `None`.
    #[inline]
    pub fn flat_normal(&self, x: &Vector3<T>, edge: T) -> Option<Vector3<T>> {
        (self.shape.flat_normal(&self.local(x), edge)).map(|n| self.rotation * n)
    }

    /// Whether a particle may slide along this collider: frictionless, with a flat part where
    /// [`Self::flat_normal`] can answer (a plane, a box).
    #[inline]
    pub fn may_slide(&self) -> bool {
        self.friction == T::zero() && self.shape.has_flat_part()
    }

    /// `x` itself when it is at least `margin` outside, else the point at distance `margin`
    /// along the normal.
    #[inline]
    pub fn project(&self, x: Vector3<T>, margin: T) -> Vector3<T> {
        self.project_at(x, self.signed_distance(&x), margin)
    }

    /// [`Self::project`] of `x` whose signed distance `distance` (m) is known.
    #[inline]
    fn project_at(&self, x: Vector3<T>, distance: T, margin: T) -> Vector3<T> {
        if distance >= margin {
            return x;
        }
        let local = self.shape.project_at(self.local(&x), distance, margin);
        self.rotation * local + self.translation
    }

    /// Moves `x`, when it is less than `margin` outside (`distance`: its signed distance, m),
    /// to the nearest point of the offset surface `d = margin` in the metric `A^-1`, where
    /// `inverse` is `A` (symmetric positive definite): the point `p = x + lambda A n(p)` with
    /// `d(p) = margin`, `n(p)` the outward normal at `p` itself. Returns `n(p)` and `lambda`
    /// (m per unit of `A`), or `None` where `x` is outside or `A` has no positive curvature
    /// along `n`. With `A = I` it is the normal projection; with `A = D^-1` (1/kg) the
    /// reaction is the force impulse `lambda n` (kg m) that stops the move of a vertex whose
    /// system is `D`, normal to the surface where the vertex ends, so that a vertex held there
    /// has a residual force along that normal alone: the frictionless constrained minimum.
    ///
    /// Solved by moving along `A n_k` to the surface linearised at the last point `p_k`:
    /// `lambda_k = (margin - d(p_k) - n_k . (x - p_k)) / (n_k . A n_k)` from `p_0 = x` (so the
    /// first point is the push to the surface linearised at `x`), until the normal no longer
    /// changes (a plane, a box face: one round) or the point moves by round-off. Each round
    /// removes the tilt of the normal over the push, a factor `|lambda A n|_t / R` on a surface
    /// of radius `R`; where the rounds do not settle (at an edge, in a grid's kinks) the first
    /// point is kept, on the surface linearised at `x`.
    #[inline]
    pub fn push_out(
        &self,
        x: &mut Vector3<T>,
        distance: T,
        inverse: &SymmetricMatrix3<T>,
        margin: T,
    ) -> Option<(Vector3<T>, T)> {
        if distance - margin >= T::zero() {
            return None;
        }
        let start = *x;
        let towards = |n: &Vector3<T>, at: &Vector3<T>, d: T| -> Option<(Vector3<T>, T)> {
            let along = inverse.mul_vector(n);
            let reach = n.dot(&along);
            (reach > T::zero()).then(|| {
                let lambda = (margin - d - n.dot(&(start - at))) / reach;
                (start + along * lambda, lambda)
            })
        };
        let mut n = self.normal(&start);
        let (first, first_lambda) = towards(&n, &start, distance)?;
        let (mut p, mut lambda) = (first, first_lambda);
        for _ in 0..PUSH_ROUNDS {
            let normal = self.normal(&p);
            if normal == n {
                *x = p;
                return Some((n, lambda));
            }
            let Some((next, next_lambda)) = towards(&normal, &p, self.signed_distance(&p)) else {
                break;
            };
            let settled = (next - p).norm()
                <= T::default_epsilon() * T::of(PUSH_SETTLE_ULPS) * (p.norm() + T::one());
            (p, lambda, n) = (next, next_lambda, normal);
            if settled {
                *x = p;
                return Some((n, lambda));
            }
        }
        *x = first;
        Some((self.normal(&start), first_lambda))
    }

    /// The end of the move from `from` (outside; both at the end pose) to `to` to take out of
    /// the collider, and its signed distance (m): `to`, or where the move would cross the
    /// collider, its slide along the near side ([`ShapeModel::crossing_end`]).
    #[inline]
    pub fn keep_side(&self, from: &Vector3<T>, to: Vector3<T>) -> (Vector3<T>, T) {
        let local_to = self.local(&to);
        let distance = self.shape.signed_distance(&local_to);
        // The common case, decided without looking at `from`'s side.
        if self.shape.surely_outside(distance, &(to - from)) {
            return (to, distance);
        }
        match self
            .shape
            .crossing_end(&self.local(from), &local_to, distance)
        {
            Some(end) => (
                self.rotation * end + self.translation,
                self.shape.signed_distance(&end),
            ),
            None => (to, distance),
        }
    }

    /// Where the collider's material point at `x` at the start of the step is at its end,
    /// `R R_0^T (x - t_0) + t` (m; the inverse of the map in [`Self::displacement`]).
    #[inline]
    pub fn carried(&self, x: &Vector3<T>) -> Vector3<T> {
        self.back_rotation.tr_mul(&(x - self.back_translation))
    }

    /// How far the collider's material point now at `x` moved during the step (m):
    /// `x - (R_0 R^T (x - t) + t_0)`; the same for every point of a translating collider.
    #[inline]
    pub fn displacement(&self, x: &Vector3<T>) -> Vector3<T> {
        x - (self.back_rotation * x + self.back_translation)
    }
}

/// Where a move that a collider pass checks started (m), outside every collider.
#[derive(Debug, Clone, Copy)]
pub enum MoveStart<T: Real> {
    /// A position during the step, relative to the colliders' end poses (an iterate).
    Now(Vector3<T>),
    /// The position at the start of the step, relative to the colliders' start poses: each
    /// collider checks the move from where its motion carried that point
    /// ([`ColliderModel::carried`]), so a collider sweeping past a vertex is a move too.
    OfStep(Vector3<T>),
}

impl<T: Real> MoveStart<T> {
    /// The start of the move relative to `collider` at its end pose.
    #[inline]
    fn seen_by(&self, collider: &ColliderModel<T>) -> Vector3<T> {
        match self {
            Self::Now(x) => *x,
            Self::OfStep(x) => collider.carried(x),
        }
    }
}

/// `x`, the end of a move from `from`, moved out of every one of `colliders` to at least
/// `margin` (m) from it: kept on the side the move came from ([`ColliderModel::keep_side`]),
/// back to each surface by the shortest move in the metric whose inverse is `inverse`
/// ([`ColliderModel::push_out`]; `None`: the identity), then onto it wherever the surface's
/// curvature left `x` inside (for `None`, the normal projection alone).
#[inline]
pub fn push_out_of_colliders<T: Real>(
    colliders: &[ColliderModel<T>],
    from: MoveStart<T>,
    mut x: Vector3<T>,
    margin: T,
    inverse: Option<&SymmetricMatrix3<T>>,
) -> Vector3<T> {
    for c in colliders {
        let (end, distance) = c.keep_side(&from.seen_by(c), x);
        x = match inverse {
            None => c.project_at(end, distance, margin),
            Some(a) => {
                let mut pushed = end;
                match c.push_out(&mut pushed, distance, a, margin) {
                    Some(_) => c.project(pushed, margin),
                    None => c.project_at(end, distance, margin),
                }
            }
        };
    }
    x
}

/// [`Shape`] in the simulation's precision.
#[derive(Debug, Clone, PartialEq)]
pub enum ShapeModel<T: Real> {
    Plane {
        normal: Vector3<T>,
        offset: T,
    },
    Sphere {
        center: Vector3<T>,
        radius: T,
    },
    Box {
        center: Vector3<T>,
        half_extents: Vector3<T>,
        axes: Matrix3<T>,
    },
    Capsule {
        a: Vector3<T>,
        b: Vector3<T>,
        radius: T,
    },
    /// Queried in f64 whatever `T`, at the point plus the anchor (m, the shape frame's point
    /// the model's origin stands at, [`Shape::to_real_about`]).
    Mesh(Arc<SdfGrid>, Vector3<f64>),
}

/// The signed distance (m) of `x` from the plane `n . x = offset` (`n` a unit normal).
#[inline(always)]
fn plane_distance<T: Real>(x: &Vector3<T>, normal: &Vector3<T>, offset: T) -> T {
    x.dot(normal) - offset
}

/// `x` in f64.
#[inline]
fn wide<T: Real>(x: &Vector3<T>) -> Vector3<f64> {
    x.map(|c| c.to_f64())
}

impl<T: Real> ShapeModel<T> {
    /// Signed distance from the surface (m), positive outside: exact Euclidean distance for
    /// every analytic shape, so that moving along [`Self::normal`] changes it one for one; the
    /// grid's interpolated distance for a mesh (see [`SdfGrid`] for its accuracy). A plane's
    /// is taken where it is asked (this dispatch is always inlined: the floor under a body
    /// is asked for every particle in every trial), the other shapes' in [`Self::distance`].
    #[inline(always)]
    pub fn signed_distance(&self, x: &Vector3<T>) -> T {
        match *self {
            Self::Plane { normal, offset } => plane_distance(x, &normal, offset),
            _ => self.distance(x),
        }
    }

    /// [`Self::signed_distance`] of any shape, out of line.
    #[inline]
    fn distance(&self, x: &Vector3<T>) -> T {
        match *self {
            Self::Plane { normal, offset } => plane_distance(x, &normal, offset),
            Self::Sphere { center, radius } => (x - center).norm() - radius,
            Self::Box {
                center,
                half_extents,
                axes,
            } => {
                let q = (axes.transpose() * (x - center)).abs() - half_extents;
                let outside = q.map(|c| c.max(T::zero())).norm();
                outside + q.max().min(T::zero())
            }
            Self::Capsule { a, b, radius } => (x - closest_on_segment(x, &a, &b)).norm() - radius,
            Self::Mesh(ref grid, anchor) => T::of(grid.signed_distance(&(wide(x) + anchor))),
        }
    }

    /// Unit outward normal: the gradient of the signed distance at `x` (on the medial axis, a
    /// fixed choice).
    #[inline]
    pub fn normal(&self, x: &Vector3<T>) -> Vector3<T> {
        match *self {
            Self::Plane { normal, .. } => normal,
            Self::Sphere { center, .. } => unit_or_z(x - center),
            Self::Box {
                center,
                half_extents,
                axes,
            } => {
                let p = axes.transpose() * (x - center);
                let q = p.abs() - half_extents;
                let sign = p.map(|c| if c < T::zero() { -T::one() } else { T::one() });
                let local = if q.max() > T::zero() {
                    q.map(|c| c.max(T::zero())).component_mul(&sign).normalize()
                } else {
                    let k = q.imax();
                    Vector3::ith(k, sign[k])
                };
                axes * local
            }
            Self::Capsule { a, b, .. } => {
                let d = x - closest_on_segment(x, &a, &b);
                if d.norm() > T::zero() {
                    d.normalize()
                } else {
                    crate::geometry::any_orthogonal_unit(&unit_or_z(b - a))
                }
            }
            Self::Mesh(ref grid, anchor) => grid.normal(&(wide(x) + anchor)).map(T::of),
        }
    }

    /// The unit outward normal at `x` where it is the same at every point within `edge` (m)
    /// of the surface's point nearest `x` (a plane anywhere; a box's face at least `edge`
    /// from the face's edges), else `None` (a box near an edge or corner, a sphere, a capsule,
    /// a mesh): a particle that slides along the surface keeps this normal
    /// ([`crate::solve::particles`]' two-level correction, "Sliding particles").
    #[inline]
    pub fn flat_normal(&self, x: &Vector3<T>, edge: T) -> Option<Vector3<T>> {
        match *self {
            Self::Plane { normal, .. } => Some(normal),
            Self::Box {
                center,
                half_extents,
                axes,
            } => box_face_normal(x, &center, &half_extents, &axes, edge),
            _ => None,
        }
    }

    /// Whether [`Self::flat_normal`] answers somewhere (a plane, a box).
    #[inline]
    pub fn has_flat_part(&self) -> bool {
        matches!(self, Self::Plane { .. } | Self::Box { .. })
    }

    /// `x` itself when it is at least `margin` outside, else the point at distance `margin`
    /// along the normal (the closest such point); for a mesh, Newton steps along the field's
    /// gradient to its `margin` level ([`SdfGrid::project`]).
    #[inline]
    pub fn project(&self, x: Vector3<T>, margin: T) -> Vector3<T> {
        self.project_at(x, self.signed_distance(&x), margin)
    }

    /// [`Self::project`] of `x` whose signed distance `distance` (m) is known (a mesh's
    /// projection evaluates its own field).
    #[inline]
    pub fn project_at(&self, x: Vector3<T>, distance: T, margin: T) -> Vector3<T> {
        if let Self::Mesh(grid, anchor) = self {
            let at = grid.project(wide(&x) + anchor, margin.to_f64());
            return (at - anchor).map(T::of);
        }
        let gap = distance - margin;
        if gap < T::zero() {
            x - self.normal(&x) * gap
        } else {
            x
        }
    }
}

/// The unit outward normal of the face of the box (`center`, `half_extents`, `axes`: its
/// edge directions as columns; m) nearest `x`, where that face's point nearest `x` is at
/// least `edge` (m) from the face's edges ([`ShapeModel::flat_normal`]).
fn box_face_normal<T: Real>(
    x: &Vector3<T>,
    center: &Vector3<T>,
    half_extents: &Vector3<T>,
    axes: &Matrix3<T>,
    edge: T,
) -> Option<Vector3<T>> {
    let offset = axes.tr_mul(&(x - center));
    let outside = offset.abs() - half_extents;
    let k = outside.imax();
    let on_face = (0..3).all(|j| j == k || outside[j] <= -edge);
    let sign = if offset[k] < T::zero() {
        -T::one()
    } else {
        T::one()
    };
    on_face.then(|| axes.column(k) * sign)
}

/// The point of the segment `a`-`b` closest to `x`.
#[inline]
fn closest_on_segment<T: Real>(x: &Vector3<T>, a: &Vector3<T>, b: &Vector3<T>) -> Vector3<T> {
    let ab = b - a;
    let len2 = ab.norm_squared();
    let t = if len2 > T::zero() {
        ((x - a).dot(&ab) / len2).max(T::zero()).min(T::one())
    } else {
        T::zero()
    };
    a + ab * t
}

fn unit_or_z<T: Real>(v: Vector3<T>) -> Vector3<T> {
    let n = v.norm();
    if n > T::zero() {
        v / n
    } else {
        Vector3::z()
    }
}

#[cfg(test)]
#[path = "shape_tests.rs"]
mod tests;
