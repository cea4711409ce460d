//! Geometry shared by every body family: distances between primitives, bounds and boxes, a
//! parallel stable counting sort, per-vertex indices in compressed rows, horizon
//! neighbourhoods of point sets (cell lists in Z-order, CSR), each point's nearest other point
//! (a k-d tree), and a unit vector orthogonal to another.

pub(crate) mod bounds;
pub(crate) mod counting_sort;
pub mod distance;
pub(crate) mod nearest;
pub mod neighbors;
mod orthogonal;
pub(crate) mod vertex_index;

pub use neighbors::{find_horizons, Horizons};
pub use orthogonal::any_orthogonal_unit;
