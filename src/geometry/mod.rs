//! Geometry shared by every body family: distances between primitives, bounds and boxes, a
//! parallel stable counting sort, per-vertex indices in compressed rows, and a unit vector
//! orthogonal to another.

pub(crate) mod bounds;
pub(crate) mod counting_sort;
pub mod distance;
mod orthogonal;
pub(crate) mod vertex_index;

pub use orthogonal::any_orthogonal_unit;
