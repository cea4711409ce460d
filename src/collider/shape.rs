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
mod tests {
    use super::*;
    use crate::test_rng::Rng;

    fn shapes() -> Vec<Shape> {
        let turn = nalgebra::Rotation3::from_scaled_axis(Vector3::new(0.3, -0.5, 0.2)).into_inner();
        let rows = [
            [turn[(0, 0)], turn[(0, 1)], turn[(0, 2)]],
            [turn[(1, 0)], turn[(1, 1)], turn[(1, 2)]],
            [turn[(2, 0)], turn[(2, 1)], turn[(2, 2)]],
        ];
        vec![
            Shape::plane([0.0, 0.0, -1.0], [0.0, 1.0, 2.0]).unwrap(),
            Shape::sphere([0.0, 0.0, 1.0], 0.5).unwrap(),
            Shape::cuboid([0.1, -0.2, 0.3], [0.4, 0.2, 0.3], rows).unwrap(),
            Shape::capsule([0.0, 0.0, 0.0], [0.5, 0.2, -0.1], 0.15).unwrap(),
        ]
    }

    /// For every shape: the normal is the gradient of the signed distance (central differences),
    /// and projecting a point inside or near lands exactly at the margin.
    #[test]
    fn normals_are_distance_gradients_and_projection_lands_at_the_margin() {
        let mut rng = Rng::new(7);
        let mut next = move || rng.uniform();
        for shape in shapes() {
            let model = shape.to_real::<f64>();
            for _ in 0..300 {
                let x = Vector3::new(next(), next(), next()) * 0.8 + Vector3::new(0.0, 0.0, 0.3);
                let h = 1e-7;
                let fd = Vector3::from_fn(|k, _| {
                    let e = Vector3::ith(k, h);
                    (model.signed_distance(&(x + e)) - model.signed_distance(&(x - e))) / (2.0 * h)
                });
                // Skip points within reach of a kink of the field (box edges, medial planes).
                if (fd.norm() - 1.0).abs() < 1e-6 {
                    assert!(
                        (fd - model.normal(&x)).norm() < 1e-5,
                        "{shape:?} at {x}: {fd} vs {}",
                        model.normal(&x)
                    );
                }
                let p = model.project(x, 0.01);
                let d = model.signed_distance(&p);
                if model.signed_distance(&x) < 0.01 {
                    assert!((d - 0.01).abs() < 1e-12, "{shape:?}: {d}");
                } else {
                    assert_eq!(p, x);
                }
            }
        }
    }

    /// Near a shape, [`ColliderModel::push_out`] in the metric `A^-1` (random symmetric
    /// positive definite `A`) ends on the offset surface `d = margin` at a point `p` with
    /// `p - x = lambda A n(p)`, `lambda > 0` and `n` the normal returned, and no nearby point of
    /// that surface is closer to the start in `A^-1` (checked on points of the surface around
    /// `p`). Pushes up to 6 cm deep in a random metric of condition up to ~100 make an
    /// ill-posed problem on a curved surface (along a tangential soft axis each round tilts the
    /// normal more than the last): those pushes that do not settle (and those that cross a
    /// box's edge) end on the surface linearised at `x`. Points outside the margin stay.
    /// [`a_push_into_a_ball_ends_where_its_reaction_is_normal`] is the case of a step.
    #[test]
    fn pushing_out_in_a_metric_takes_its_shortest_move() {
        let mut rng = Rng::new(11);
        let margin = 0.01;
        for shape in shapes() {
            let model = crate::collider::MovingCollider::new(Collider::fixed(shape.clone()))
                .during_step::<f64>(0.0, 1.0);
            let (mut inside, mut outside, mut linearised) = (0, 0, 0);
            for _ in 0..300 {
                // Near the surface: within the margin (or inside) for u > -0.2, else outside.
                let seed = rng.vector() * 0.8 + Vector3::new(0.0, 0.0, 0.3);
                let on = seed - model.normal(&seed) * model.signed_distance(&seed);
                let x = on - model.normal(&on) * (0.05 * rng.uniform());
                let b = Matrix3::from_fn(|_, _| rng.uniform());
                let full = b * b.transpose() + Matrix3::identity() * 0.05;
                let inverse = SymmetricMatrix3 {
                    diagonal: [full[(0, 0)], full[(1, 1)], full[(2, 2)]],
                    upper: [full[(0, 1)], full[(0, 2)], full[(1, 2)]],
                };
                let gap = model.signed_distance(&x) - margin;
                let mut moved = x;
                let out = model.push_out(&mut moved, model.signed_distance(&x), &inverse, margin);
                if gap >= 0.0 {
                    assert!(out.is_none());
                    assert_eq!(moved, x);
                    outside += 1;
                    continue;
                }
                inside += 1;
                let (n, lambda) = out.unwrap();
                assert!(lambda > 0.0);
                assert!((moved - x - full * n * lambda).norm() < 1e-12);
                if (model.signed_distance(&moved) - margin).abs() > 1e-12 {
                    // The fallback: on the surface linearised at the start.
                    assert_eq!(n, model.normal(&x));
                    assert!((gap + n.dot(&(moved - x))).abs() < 1e-12, "{gap}");
                    linearised += 1;
                    continue;
                }
                assert!((n - model.normal(&moved)).norm() < 1e-9, "{shape:?}");
                let metric = full.try_inverse().unwrap();
                let cost = |w: &Vector3<f64>| (w - x).dot(&(metric * (w - x)));
                for _ in 0..20 {
                    let t = rng.vector() * 0.02;
                    let other = model.project(moved + t - n * n.dot(&t), margin);
                    let other =
                        other - model.normal(&other) * (model.signed_distance(&other) - margin);
                    let flat = matches!(shape, Shape::Box { .. });
                    let normal = model.normal(&other);
                    if normal.dot(&n) < 0.9 || flat && normal != n {
                        // Another face of the box, or its offset surface's rounded edge (a
                        // radius of `margin`, less than the push): no neighbour of `p`.
                        continue;
                    }
                    assert!(
                        cost(&other) >= cost(&moved) * (1.0 - 1e-9),
                        "{shape:?}: {} < {}",
                        cost(&other),
                        cost(&moved)
                    );
                }
            }
            // The share of pushes that settle: all on the plane, most on the 50 cm sphere, more
            // than a quarter on the 15 cm capsule and the box (measured 46 % on the capsule).
            let settled_enough = match shape {
                Shape::Plane { .. } => linearised == 0,
                Shape::Sphere { .. } => linearised * 3 < inside,
                _ => linearised * 4 < inside * 3,
            };
            assert!(
                inside > 20 && outside > 20 && settled_enough,
                "{shape:?}: {inside} inside, {outside} outside, {linearised} linearised"
            );
        }
    }

    /// At the scale of a step (a vertex pushed 1 mm into a 10 cm ball, in the Jacobi metric of
    /// a stiff sheet lying on it: compliance 100 times larger along the sheet's normal than
    /// in its plane), every push
    /// settles on the offset sphere with the reaction along the normal where it ends:
    /// `p - x = lambda A n(p)` to 1e-15 m, on the surface to 1e-14 m (the rounds stop at 16 ulp).
    #[test]
    fn a_push_into_a_ball_ends_where_its_reaction_is_normal() {
        let mut rng = Rng::new(5);
        let (center, radius, margin) = (Vector3::new(0.0, 0.0, 0.0), 0.1, 1e-3);
        let model = crate::collider::MovingCollider::new(Collider::fixed(
            Shape::sphere([0.0, 0.0, 0.0], radius).unwrap(),
        ))
        .during_step::<f64>(0.0, 1.0);
        for _ in 0..500 {
            let n = loop {
                let v = rng.vector();
                if v.norm() > 0.1 {
                    break v.normalize();
                }
            };
            let x = center + n * (radius - 1e-3 * rng.uniform());
            // The soft axis of a sheet lying on the ball: its normal, tilted up to ~30 degrees.
            let axis = (n + rng.vector() * 0.3).normalize();
            let full = Matrix3::identity() * 1e-2 + axis * axis.transpose();
            let inverse = SymmetricMatrix3 {
                diagonal: [full[(0, 0)], full[(1, 1)], full[(2, 2)]],
                upper: [full[(0, 1)], full[(0, 2)], full[(1, 2)]],
            };
            let mut p = x;
            let (normal, lambda) = model
                .push_out(&mut p, model.signed_distance(&x), &inverse, margin)
                .unwrap();
            let off = model.signed_distance(&p) - margin;
            assert!(off.abs() < 1e-14, "{off:e} m off the offset sphere");
            let tilt = (normal - (p - center).normalize()).norm();
            assert!(tilt < 1e-12, "normal tilted {tilt:e}");
            let miss = (p - x - full * normal * lambda).norm();
            assert!(miss < 1e-15, "{miss:e} m from the normal reaction");
        }
    }

    /// A box turning by 0.4 rad and moving 0.3 m during a step: a point carried from the start
    /// of the step ([`ColliderModel::carried`]) keeps its signed distance (the motion is rigid),
    /// and [`ColliderModel::displacement`] at the carried point is the move that carried it.
    /// The crossing check measures start-of-step positions this way ([`MoveStart::OfStep`]).
    #[test]
    fn a_point_carried_by_a_turning_collider_keeps_its_distance() {
        let turn = |angle: f64| {
            nalgebra::Rotation3::from_scaled_axis(Vector3::new(0.1, -0.2, 1.0).normalize() * angle)
                .into_inner()
        };
        let box_shape = shapes()[2].clone();
        let collider = Collider::fixed(box_shape);
        let start = Pose {
            rotation: turn(0.1),
            translation: Vector3::new(0.05, 0.0, -0.02),
        };
        let end = Pose {
            rotation: turn(0.5),
            translation: Vector3::new(0.2, 0.25, 0.1),
        };
        let at_start = ColliderModel::<f64>::new(&collider, &start, &start);
        let moving = ColliderModel::<f64>::new(&collider, &start, &end);
        let mut rng = Rng::new(13);
        for _ in 0..200 {
            let x = rng.vector() * 0.8;
            let carried = moving.carried(&x);
            let (before, after) = (
                at_start.signed_distance(&x),
                moving.signed_distance(&carried),
            );
            assert!((before - after).abs() < 1e-12, "{before} vs {after}");
            assert!((moving.displacement(&carried) - (carried - x)).norm() < 1e-12);
        }
    }

    #[test]
    fn bad_shapes_are_named() {
        assert!(Shape::sphere([0.0; 3], 0.0)
            .unwrap_err()
            .to_string()
            .contains("radius"));
        assert!(Shape::plane([0.0; 3], [0.0; 3])
            .unwrap_err()
            .to_string()
            .contains("normal"));
        let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(Shape::cuboid([0.0; 3], [1.0, -1.0, 1.0], id)
            .unwrap_err()
            .to_string()
            .contains("half_extents[1]"));
        let skew = [[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(Shape::cuboid([0.0; 3], [1.0; 3], skew)
            .unwrap_err()
            .to_string()
            .contains("rotation"));
        assert!(Shape::capsule([0.0; 3], [f64::NAN, 0.0, 0.0], 1.0)
            .unwrap_err()
            .to_string()
            .contains("end b"));
    }
}
