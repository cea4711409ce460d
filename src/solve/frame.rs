//! Where a particle family's frame stands: the world point its positions are measured from
//! ([`super::points::Points::origin`]), near its bodies, so that a position in the solver's
//! precision holds `eps` of the body's size rather than of its distance from the world origin
//! (docs/architecture.md, "Particle frame").

use nalgebra::Vector3;

/// The frame follows the bodies once their bounding box leaves the cube of this many grid
/// cells around the origin ([`origin_near`]).
const DRIFT_CELLS: f64 = 2.0;

/// The smallest grid cell (m): bodies smaller than this share its grid.
const SMALLEST_CELL: f64 = 1.0 / 1024.0;

/// The origin (m, world) of a family's frame for the positions `positions` (m, world), given
/// the one it had (`previous`). The grid cell `g` is the smallest power of two at least the
/// bounding box's largest side (and [`SMALLEST_CELL`]); `previous` is kept while the box lies
/// within [`DRIFT_CELLS`] cells of it along each axis (a body at rest keeps its frame, so its
/// positions round-trip through the bodies bit for bit), else the origin is the box's centre
/// rounded to a multiple of `g`. Such an origin has few significant bits, so
/// `origin + y` of a position `y` in f32 is exact in f64 and `x - origin` of a world position
/// near it rounds only once, to the solver's precision. No positions: `previous`; a
/// non-finite position: the world origin (the step reports it).
pub(crate) fn origin_near<'a>(
    positions: impl Iterator<Item = &'a Vector3<f64>>,
    previous: &Vector3<f64>,
) -> Vector3<f64> {
    let mut low = Vector3::repeat(f64::INFINITY);
    let mut high = Vector3::repeat(f64::NEG_INFINITY);
    for x in positions {
        low = low.inf(x);
        high = high.sup(x);
    }
    if low.x > high.x {
        return *previous;
    }
    let side = (high - low).max();
    if !side.is_finite() {
        return Vector3::zeros();
    }
    let cell = side.max(SMALLEST_CELL).log2().ceil().exp2();
    let reach = DRIFT_CELLS * cell;
    let kept = (0..3).all(|k| low[k] >= previous[k] - reach && high[k] <= previous[k] + reach);
    if kept {
        *previous
    } else {
        ((low + high) * 0.5 / cell).map(f64::round) * cell
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 0.1 m cube 10 m along x: its origin is a multiple of its 0.125 m cell, within half a
    /// cell of its centre; at the world origin the frame is the world's; a small drift keeps
    /// the frame, a drift of more than two cells moves it.
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
        assert_eq!(origin_near(cube(zero).iter(), &zero), zero);
        let far = cube(Vector3::new(10.0, 0.0, 0.0));
        let origin = origin_near(far.iter(), &zero);
        assert_eq!(origin, Vector3::new(10.0, 0.0, 0.0));
        assert_eq!(origin.map(|c| (c / 0.125).fract()), zero);
        let drifted = cube(Vector3::new(10.1, 0.0, 0.0));
        assert_eq!(origin_near(drifted.iter(), &origin), origin);
        let gone = cube(Vector3::new(10.5, 0.0, 0.0));
        assert_eq!(
            origin_near(gone.iter(), &origin),
            Vector3::new(10.5, 0.0, 0.0)
        );
        assert_eq!(origin_near(std::iter::empty(), &origin), origin);
    }
}
