//! Bounds shared by the pair lists: a NaN-propagating maximum, axis-aligned boxes and the
//! gap between two of them, and rounding a slack down to `f32` so that it stays a lower bound.

use nalgebra::Vector3;

/// The larger of `m` and `x`, NaN if either is.
pub(crate) fn nan_max(m: f64, x: f64) -> f64 {
    if x.is_nan() || x > m {
        x
    } else {
        m
    }
}

/// The axis-aligned box `(lo, hi)` of `points` (m, at least one), or the whole space where a
/// point is not finite, so that its [`box_gap`] to any box is 0: a gap from the finite
/// points' bounds would bound nothing there (an infinite coordinate can leave it finite and
/// large, while distances to the point are NaN), and callers then keep what a gap would
/// have left out.
pub(crate) fn bounding_box<'a>(
    points: impl IntoIterator<Item = &'a Vector3<f64>>,
) -> (Vector3<f64>, Vector3<f64>) {
    let mut points = points.into_iter();
    let first = *points.next().expect("a box of at least one point");
    let not_finite = |q: &Vector3<f64>| !q.iter().all(|c| c.is_finite());
    let everywhere = (
        Vector3::repeat(f64::NEG_INFINITY),
        Vector3::repeat(f64::INFINITY),
    );
    if not_finite(&first) {
        return everywhere;
    }
    let mut bounds = (first, first);
    for q in points {
        if not_finite(q) {
            return everywhere;
        }
        bounds = (bounds.0.inf(q), bounds.1.sup(q));
    }
    bounds
}

/// The distance (m) between the boxes `(lo, hi)` `a` and `b` (0 where they overlap): at most
/// the distance between any of their points. A NaN corner counts as no bound (`sup` passes
/// NaN over); [`bounding_box`] gives none.
pub(crate) fn box_gap(a: (Vector3<f64>, Vector3<f64>), b: (Vector3<f64>, Vector3<f64>)) -> f64 {
    let ((alo, ahi), (blo, bhi)) = (a, b);
    (blo - ahi).sup(&(alo - bhi)).sup(&Vector3::zeros()).norm()
}

/// `x` as an `f32` no larger than it (NaN stays NaN): a slack rounded down stays a lower bound.
pub(crate) fn round_down(x: f64) -> f32 {
    let f = x as f32;
    if f.is_nan() || f64::from(f) <= x {
        f
    } else if f == 0.0 {
        -f32::from_bits(1)
    } else if f > 0.0 {
        f32::from_bits(f.to_bits() - 1)
    } else {
        f32::from_bits(f.to_bits() + 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The box of points is their exact bounds, and the whole space, 0 away from any box, as
    /// soon as one point is not finite (first or last, infinite or NaN), where a gap from the
    /// finite points' bounds would come out finite.
    #[test]
    fn a_box_is_the_whole_space_where_a_point_is_not_finite() {
        let points = [
            Vector3::new(0.0, 2.0, -1.0),
            Vector3::new(1.0, -3.0, 0.5),
            Vector3::new(-0.5, 0.0, 4.0),
        ];
        let (lo, hi) = bounding_box(&points);
        assert_eq!(lo, Vector3::new(-0.5, -3.0, -1.0));
        assert_eq!(hi, Vector3::new(1.0, 2.0, 4.0));
        let far = (Vector3::repeat(10.0), Vector3::repeat(11.0));
        assert!((box_gap((lo, hi), far) - (81.0_f64 + 64.0 + 36.0).sqrt()).abs() < 1e-12);
        for bad in [f64::INFINITY, f64::NEG_INFINITY, f64::NAN] {
            for k in [0, 2] {
                let mut with_bad = points;
                with_bad[k].y = bad;
                let (lo, hi) = bounding_box(&with_bad);
                assert!(
                    lo.iter().all(|&c| c == f64::NEG_INFINITY)
                        && hi.iter().all(|&c| c == f64::INFINITY),
                    "{bad} at {k}"
                );
                assert_eq!(box_gap((lo, hi), far), 0.0);
            }
        }
    }

    #[test]
    fn rounding_down_keeps_a_lower_bound() {
        for x in [
            0.1,
            -0.1,
            1e-300,
            -1e-300,
            3.0,
            1e300,
            -1e300,
            f64::INFINITY,
        ] {
            let f = round_down(x);
            assert!(f64::from(f) <= x, "{x} -> {f}");
        }
        assert!(round_down(f64::NAN).is_nan());
        assert_eq!(round_down(0.5), 0.5);
    }
}
