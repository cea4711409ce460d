//! Where a particle family's frame stands: the world point its positions are measured from
//! ([`super::points::Points::origin`]), near its bodies, so that a position in the solver's
//! precision holds `eps` of the body's size rather than of its distance from the world origin
//! (docs/architecture.md, "Particle frame").

use nalgebra::Vector3;

/// Bodies whose bounding box lies within this many grid cells of the world origin keep the
/// world frame ([`origin_near`]).
const WORLD_CELLS: f64 = 2.0;

/// The smallest grid cell (m): bodies smaller than this share its grid.
const SMALLEST_CELL: f64 = 1.0 / 1024.0;

/// The origin (m, world) of a family's frame for the positions `positions` (m, world): a pure
/// function of them, so a run restored from its saved positions into a fresh solver chooses
/// the frame the run that went on chose (docs/architecture.md, "Particle frame"). The grid
/// cell `g` is the smallest power of two at least the bounding box's largest side (and
/// [`SMALLEST_CELL`]); a box within [`WORLD_CELLS`] cells of the world origin along each axis
/// keeps the world frame (there a position holds `eps` of a few cells already), else the
/// origin is the box's centre rounded to a multiple of `g`. Such an origin has few
/// significant bits, so `origin + y` of a position `y` in f32 is exact in f64 and
/// `x - origin` of a world position `x` within a few cells of it is exact in f64 (and rounds
/// once, to the solver's precision). A body at rest has the same positions, so it keeps its
/// frame. No positions: the world origin. A non-finite position (NaN or infinite): the world
/// origin too, so the step's own checks see the position itself and report it.
pub(crate) fn origin_near<'a>(positions: impl Iterator<Item = &'a Vector3<f64>>) -> Vector3<f64> {
    let mut low = Vector3::repeat(f64::INFINITY);
    let mut high = Vector3::repeat(f64::NEG_INFINITY);
    let mut finite = true;
    for x in positions {
        finite &= x.iter().all(|c| c.is_finite());
        low = low.inf(x);
        high = high.sup(x);
    }
    if !(finite && low.x <= high.x) {
        return Vector3::zeros();
    }
    let side = (high - low).max();
    let cell = side.max(SMALLEST_CELL).log2().ceil().exp2();
    let reach = WORLD_CELLS * cell;
    if (0..3).all(|k| low[k] >= -reach && high[k] <= reach) {
        Vector3::zeros()
    } else {
        ((low + high) * 0.5 / cell).map(f64::round) * cell
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 0.1 m cube 10 m along x: its origin is a multiple of its 0.125 m cell, within half a
    /// cell of its centre, and the same for the same positions (no state: a drift of the box
    /// moves the origin to the multiple nearest its centre); within two cells of the world
    /// origin, no positions or a non-finite one: the world frame.
    #[test]
    fn the_origin_is_a_coarse_grid_point_near_the_bodies() {
        let cube = |at: Vector3<f64>| {
            (0..8)
                .map(|k| {
                    at + Vector3::new((k & 1) as f64, ((k >> 1) & 1) as f64, (k >> 2) as f64) * 0.1
                })
                .collect::<Vec<_>>()
        };
        let zero = Vector3::zeros();
        assert_eq!(origin_near(cube(zero).iter()), zero);
        assert_eq!(origin_near(cube(Vector3::new(0.1, -0.2, 0.1)).iter()), zero);
        let far = cube(Vector3::new(10.0, 0.0, 0.0));
        let origin = origin_near(far.iter());
        assert_eq!(origin, Vector3::new(10.0, 0.0, 0.0));
        assert_eq!(origin.map(|c| (c / 0.125).fract()), zero);
        assert_eq!(origin_near(far.iter()), origin);
        let drifted = cube(Vector3::new(10.1, 0.0, 0.0));
        assert_eq!(origin_near(drifted.iter()), Vector3::new(10.125, 0.0, 0.0));
        assert_eq!(origin_near(std::iter::empty()), zero);
        let mut broken = far.clone();
        broken[3].y = f64::NAN;
        assert_eq!(origin_near(broken.iter()), zero);
        broken[3].y = f64::INFINITY;
        assert_eq!(origin_near(broken.iter()), zero);
    }
}
