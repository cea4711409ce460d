//! A unit vector orthogonal to another, for frames built from a single direction (a membrane
//! vertex's tangent plane, a capsule's radial direction).

use nalgebra::Vector3;

use crate::real::{select, Lanes};

/// A unit vector orthogonal to the unit vector `n`, chosen deterministically.
/// (The cross product with the coordinate axis along which `n` is smallest.)
#[inline(always)]
pub fn any_orthogonal_unit<S: Lanes>(n: &Vector3<S>) -> Vector3<S> {
    let (x, y, z) = (n.x.simd_abs(), n.y.simd_abs(), n.z.simd_abs());
    let axis = select(
        x.simd_le(y) & x.simd_le(z),
        Vector3::x(),
        select(y.simd_le(z), Vector3::y(), Vector3::z()),
    );
    n.cross(&axis).normalize()
}
