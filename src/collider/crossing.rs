//! Moves that would cross a collider in one go: a fast impact on a thin wall, or a ball
//! smaller than the move. Every collider pass projects a point onto the *nearest* surface,
//! and for a point past the middle of a solid (or through it and out) that is the far side: the
//! membrane would tunnel. So each pass first follows the straight path from where the vertex
//! was (outside) to where the move ends, by sphere tracing on the signed distance, and keeps the
//! end on the side the path reached the surface from.

use nalgebra::Vector3;

use crate::collider::ShapeModel;
use crate::real::Real;

/// At most this many sphere-tracing steps along a path. A path still short of the surface
/// after them grazes it (or, for a mesh, winds near it); the point reached counts as touching
/// (the conservative choice).
pub(crate) const TRACE_STEPS: usize = 64;

/// The path reaches the surface where the signed distance has fallen to this fraction of its
/// value at the start of the path, or to [`TOUCH_DISTANCE`] if that is smaller.
pub(crate) const TRACE_TOLERANCE: f64 = 1e-3;

/// The path reaches the surface at the latest where the signed distance has fallen to this
/// (m): a micrometre, far below any margin, so that a move from far out (a fast collider seen
/// from the start of the step) ends on the surface and not a fraction of its start's distance
/// short of it.
pub(crate) const TOUCH_DISTANCE: f64 = 1e-6;

/// How much faster than the length moved a shape's signed distance can change along a path:
/// 1 for an exact distance (every analytic shape); up to `sqrt 3` for a mesh's grid, whose
/// trilinear interpolation of exact distances at the nodes can be steeper (a cone's tip at a
/// cell corner). Steps and bounds of the trace are divided by it.
const MESH_SLOPE: f64 = 1.732_050_807_568_877_2;

/// The signed distance (m) at which a path from a start at `start` (m) reaches the surface:
/// [`TRACE_TOLERANCE`] of it, at most [`TOUCH_DISTANCE`].
#[inline(always)]
fn touch_distance<T: Real>(start: T) -> T {
    (start * T::of(TRACE_TOLERANCE)).min(T::of(TOUCH_DISTANCE))
}

impl<T: Real> ShapeModel<T> {
    /// See [`MESH_SLOPE`].
    #[inline(always)]
    fn slope(&self) -> T {
        match self {
            Self::Mesh(..) => T::of(MESH_SLOPE),
            _ => T::one(),
        }
    }

    /// Whether a straight path (`path`, m) stays outside because its end is farther from the
    /// surface (`distance`, m) than the distance can change along it. The common case, so it
    /// avoids a square root. False for a NaN distance.
    #[inline(always)]
    pub(super) fn surely_outside(&self, distance: T, path: &Vector3<T>) -> bool {
        let reach = self.slope() * distance;
        distance >= T::zero() && reach * reach >= path.norm_squared()
    }

    /// The first point where the straight path from `from` to `to` (`distance`: the signed
    /// distance at `to`, m) reaches the surface, by sphere tracing (each step as long as the
    /// signed distance where it starts, over [`MESH_SLOPE`] for a mesh, which cannot overshoot
    /// the surface); `None` where the path stays outside, or where `from` is not outside (no
    /// side to keep). Two bounds end the trace early. The distance changes by at most the
    /// length moved, so the rest of the path stays outside where it is shorter than the
    /// distances at its two ends together (a slide along a surface, or a path that comes close
    /// and leaves again). And every analytic shape is convex, so the distance along a line is
    /// a convex function: once a step does not bring the path closer, the rest of it stays
    /// out. A trace that is still open after [`TRACE_STEPS`] steps touches where it stopped.
    pub fn first_touch(
        &self,
        from: &Vector3<T>,
        to: &Vector3<T>,
        distance: T,
    ) -> Option<Vector3<T>> {
        let start = self.signed_distance(from);
        // A point not surely outside (NaN included) has no side.
        if start.partial_cmp(&T::zero()) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let path = to - from;
        let length = path.norm();
        // No move, or a non-finite one (caught as a divergence by the solver).
        if length.partial_cmp(&T::zero()) != Some(std::cmp::Ordering::Greater)
            || !length.is_finite()
        {
            return None;
        }
        let direction = path / length;
        let beyond = if distance > T::zero() {
            distance
        } else {
            T::zero()
        };
        let slope = self.slope();
        let close = touch_distance(start);
        let convex = !matches!(self, Self::Mesh(..));
        let (mut along, mut last) = (T::zero(), start);
        for _ in 0..TRACE_STEPS {
            if (length - along) * slope < last + beyond {
                return None;
            }
            along += last / slope;
            let x = from + direction * along;
            let here = self.signed_distance(&x);
            if here <= close {
                return Some(x);
            }
            if convex && here >= last {
                return None;
            }
            last = here;
        }
        ((length - along) * slope >= last + beyond).then(|| from + direction * along)
    }

    /// The end of the move from `from` (outside) to `to` (`distance`: its signed distance, m)
    /// to take out of the shape instead of `to`, so that the nearest surface is on the side
    /// the move came from; `None`: `to` itself. That is every `to` whose path stays outside
    /// ([`Self::first_touch`]; a caller that sees [`Self::surely_outside`] need not ask), or
    /// that ends inside on the side it entered (the normal at `to` within 90 degrees of the
    /// normal `n` at the entry point `e`).
    /// Any other `to` crossed the solid, or entered and left it: it is replaced by its slide
    /// along the tangent plane at the entry, `e + (I - n n^T)(to - e)`. That plane separates a
    /// convex shape from the free side, so the slide is outside and keeps the move's
    /// tangential part; where it is not outside (a concave mesh), the entry point itself.
    pub fn crossing_end(
        &self,
        from: &Vector3<T>,
        to: &Vector3<T>,
        distance: T,
    ) -> Option<Vector3<T>> {
        let entry = self.first_touch(from, to, distance)?;
        let n = self.normal(&entry);
        if distance < T::zero() && self.normal(to).dot(&n) > T::zero() {
            return None;
        }
        let rest = to - entry;
        let slide = entry + (rest - n * n.dot(&rest));
        Some(if self.signed_distance(&slide) >= T::zero() {
            slide
        } else {
            entry
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collider::Shape;
    use crate::test_rng::Rng;

    /// Thin shapes, each with the half-width (m) of its flat part where it has a rim within
    /// reach of the random moves (a move into a slab that ends near its rim may end nearer the
    /// adjacent face, where the grid's normal turns: no crossing, but no side either).
    fn thin_shapes() -> Vec<(&'static str, Shape, Option<f64>)> {
        let turn = nalgebra::Rotation3::from_scaled_axis(Vector3::new(0.2, 0.4, -0.1));
        let rows = turn.into_inner().transpose().into();
        vec![
            ("ball", Shape::sphere([0.0, 0.0, 0.0], 0.01).unwrap(), None),
            (
                "plate",
                Shape::cuboid([0.0; 3], [0.5, 0.5, 0.002], rows).unwrap(),
                None,
            ),
            (
                "rod",
                Shape::capsule([-0.5, 0.0, 0.0], [0.5, 0.1, 0.0], 0.003).unwrap(),
                None,
            ),
            // A 4 cm slab as a mesh, on a grid of 1 cm cells: its thickness is four cells (a
            // grid cannot hold a wall thinner than a cell), and its distance field is the
            // grid's trilinear one, up to `MESH_SLOPE` steep.
            (
                "mesh slab",
                {
                    let (vertices, triangles) =
                        crate::collider::sdf::tests::box_mesh([0.45, 0.45, 0.02]);
                    Shape::mesh(vertices, triangles, 90, None).unwrap()
                },
                Some(0.45),
            ),
        ]
    }

    /// Random moves from outside the near side of thin shapes (a 1 cm ball, a 4 mm plate, a
    /// 6 mm rod, a 4 cm slab as a mesh) to points past them, inside them or beside them, up to
    /// 0.5 m long. Whatever the
    /// move, the end taken out of the shape (the crossing end, or `to`) projects to the side
    /// the path entered from: the projection's normal is within 90 degrees of the normal at
    /// the entry. Moves whose path stays outside keep their end, and do stay outside (1000
    /// points along each); ends inside on the entry side are kept too. Every kind of move
    /// occurs.
    #[test]
    fn a_move_through_a_thin_shape_is_kept_on_the_side_it_came_from() {
        let mut rng = Rng::new(5);
        let margin = 5e-4;
        for (name, shape, rim) in thin_shapes() {
            let model = shape.to_real::<f64>();
            let (mut crossed, mut missed, mut stayed_inside, mut grazing) = (0, 0, 0, 0);
            for _ in 0..2000 {
                let seed = rng.vector() * 0.3;
                let normal = model.normal(&seed);
                let on = seed - normal * model.signed_distance(&seed);
                // Outside by at least half the margin (the projection only matters for the
                // mesh, whose grid normal and distance take `on` only near the surface).
                let from = model.project(
                    on + normal * (margin * (1.0 + 0.5 * rng.uniform())),
                    0.5 * margin,
                );
                let reach = if rng.uniform() < 0.5 { 0.5 } else { 0.005 };
                let to =
                    from + rng.vector() * reach * rng.uniform() - normal * 0.03 * rng.uniform();
                // Moves that end within 5 cm of a rim (see `thin_shapes`).
                if rim.is_some_and(|half| to.x.abs().max(to.y.abs()) > half - 0.05) {
                    continue;
                }
                let end = model.crossing_end(&from, &to, model.signed_distance(&to));
                let Some(entry) = model.first_touch(&from, &to, model.signed_distance(&to)) else {
                    assert_eq!(end, None, "{name}: a move that stays outside is kept");
                    // ... and does stay outside (1000 points along it).
                    for k in 0..=1000 {
                        let x = from + (to - from) * (f64::from(k) / 1000.0);
                        let d = model.signed_distance(&x);
                        assert!(d > 0.0, "{name}: the path from {:?} to {:?} enters at {:?} by {d:e} (start {:e}, end {:e})", from.as_slice(), to.as_slice(), x.as_slice(), model.signed_distance(&from), model.signed_distance(&to));
                    }
                    missed += 1;
                    continue;
                };
                let entry_normal = model.normal(&entry);
                let taken = end.unwrap_or(to);
                if end.is_none() {
                    stayed_inside += 1;
                    assert!(model.signed_distance(&to) < 0.0);
                } else {
                    crossed += 1;
                    assert!(model.signed_distance(&taken) >= 0.0, "{name}: slide inside");
                }
                let landed = model.project(taken, margin);
                assert!(
                    model.normal(&landed).dot(&entry_normal) > 0.0,
                    "{name}: from {from} to {to} landed on the far side at {landed}"
                );
                // The entry is on the path, outside, and (on a convex shape) closer than the
                // start: on the surface to the trace's tolerance unless the path grazes it.
                // A mesh's trace may stop at its cap farther out than it started.
                let along = (entry - from).cross(&(to - from)).norm() / (to - from).norm();
                assert!(along < 1e-12, "{name}: entry off the path by {along}");
                let depth = model.signed_distance(&entry);
                let start = model.signed_distance(&from);
                let convex = !matches!(model, ShapeModel::Mesh(..));
                assert!(
                    depth >= 0.0 && (depth < start || !convex),
                    "{name}: {depth} from {start}, {from} to {to}, entry {entry}"
                );
                grazing += usize::from(depth > touch_distance(start));
            }
            // Most touches are on the surface. A mesh's trace more often ends at its cap
            // outside (shorter steps, no convexity to end it): 111 of 607 here.
            let capped = if matches!(model, ShapeModel::Mesh(..)) {
                4
            } else {
                10
            };
            assert!(
                crossed > 100 && missed > 100 && stayed_inside > 10 && grazing < crossed / capped,
                "{name}: {crossed} crossed, {missed} missed, {stayed_inside} inside, {grazing} \
                 grazing"
            );
        }
    }

    /// Paths aimed at a cube's corner, which sits on a node of its mesh's grid. There the
    /// grid's trilinear distance rises with slope up to `sqrt 3` (each of its three partial
    /// derivatives is 1 at the corner's node: along the diagonal the distance grows as
    /// `sqrt 3` times the length), so a trace stepping by the distance itself would jump past
    /// the corner into the cube. Stepping by the distance over [`MESH_SLOPE`], every path
    /// from 1-12 mm out, within 21 degrees of the diagonal, touches outside the cube and within
    /// a tenth of a millimetre of the corner.
    #[test]
    fn a_trace_into_a_mesh_corner_on_a_grid_node_stops_outside() {
        let (vertices, triangles) = crate::collider::sdf::tests::box_mesh([0.1; 3]);
        // Cells of 1 cm and a margin of three cells: the corners are grid nodes.
        let cube = Shape::mesh(vertices, triangles, 20, Some(0.03))
            .unwrap()
            .to_real::<f64>();
        let corner = Vector3::repeat(0.1);
        let mut rng = Rng::new(11);
        for _ in 0..200 {
            let tilt = rng.vector() * 0.2;
            let direction = (Vector3::repeat(1.0).normalize() + tilt).normalize();
            let from = corner + direction * (0.0065 + 0.0055 * rng.uniform());
            let to = corner - direction * 0.05;
            let touch = cube
                .first_touch(&from, &to, cube.signed_distance(&to))
                .unwrap();
            let depth = cube.signed_distance(&touch);
            assert!(
                depth >= 0.0,
                "from {from} the trace stepped {depth:e} m into the cube"
            );
            assert!((touch - corner).norm() < 1e-4, "touched at {touch}");
        }
    }

    /// A 4 mm plate, 1 m wide, in the plane `z = 0`.
    fn flat_plate() -> ShapeModel<f64> {
        Shape::cuboid(
            [0.0; 3],
            [0.5, 0.5, 0.002],
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        )
        .unwrap()
        .to_real::<f64>()
    }

    /// A head-on move straight through a 4 mm plate ends on the plate's near side, with the
    /// move's tangential part kept; a slanted one slides along the near face by its tangential
    /// part.
    #[test]
    fn a_move_through_a_plate_slides_along_its_near_face() {
        let plate = flat_plate();
        let from = Vector3::new(0.0, 0.0, 0.0025);
        let to = Vector3::new(0.1, -0.05, -0.2);
        let end = plate
            .crossing_end(&from, &to, plate.signed_distance(&to))
            .unwrap();
        // On the near face to the trace's tolerance (1e-3 of the start's 0.5 mm).
        assert!(
            (end - Vector3::new(0.1, -0.05, 0.002)).norm() < 5e-7,
            "{end}"
        );
        // Without the check the projection takes the far side.
        let far = plate.project(Vector3::new(0.1, -0.05, -0.2), 5e-4);
        assert!(far.z < 0.0);
    }

    /// A move that starts far out (a fast collider seen from the start of the step, or a long
    /// step) ends on the near face to the trace's absolute tolerance, not to a fraction of its
    /// start's distance: from 0.5 m above a plate, straight and slanted through it (a
    /// thousandth of the start's distance, up to 0.5 mm, the size of a typical margin, left
    /// the slanted moves 44 micrometres short).
    #[test]
    fn a_move_from_far_out_ends_on_the_near_face() {
        let plate = flat_plate();
        for slant in [0.0_f64, 0.3, 0.6] {
            let from = Vector3::new(0.0, 0.0, 0.5);
            let to = Vector3::new(0.6 * slant.tan(), 0.0, -0.1);
            let end = plate
                .crossing_end(&from, &to, plate.signed_distance(&to))
                .unwrap();
            let height = plate.signed_distance(&end);
            assert!(
                (0.0..=TOUCH_DISTANCE).contains(&height),
                "slant {slant}: {height} m above the face"
            );
        }
    }

    /// A path slanted 2 degrees onto a plate's face, from 1 mm above it: sphere tracing
    /// shortens its steps by `1 - sin 2deg` each, so after [`TRACE_STEPS`] steps it is still
    /// about 0.1 mm short of the surface, 26 mm along a path that crosses the face at 29 mm
    /// and the plate after it. The trace counts that point as the touch (it is on the path,
    /// outside, and the rest of the path is not certified outside), and the crossing end
    /// slides from it along the near face: the move does not end under the plate.
    #[test]
    fn a_trace_that_runs_out_of_steps_counts_as_a_touch_on_the_near_side() {
        let plate = flat_plate();
        let slant = 2f64.to_radians();
        let from = Vector3::new(0.0, 0.0, 0.003);
        let to = from + Vector3::new(slant.cos(), 0.0, -slant.sin()) * 0.2;
        assert!(to.z < -0.002, "the path passes the plate");
        let distance = plate.signed_distance(&to);
        let touch = plate.first_touch(&from, &to, distance).unwrap();
        let off_path = (touch - from).cross(&(to - from)).norm() / (to - from).norm();
        assert!(off_path < 1e-12);
        let height = plate.signed_distance(&touch);
        assert!(
            (5e-5..2e-4).contains(&height),
            "the trace stopped {height} above the face: not at its cap"
        );
        let end = plate.crossing_end(&from, &to, distance).unwrap();
        assert!(
            (end.z - (0.002 + height)).abs() < 1e-12,
            "slides at the touch's height: {end}"
        );
        assert!((end.x - to.x).abs() < 1e-12 && end.y.abs() < 1e-12);
    }
}
