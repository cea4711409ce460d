//! Continuous collision detection between two positions of a primitive pair.

mod additive;

pub use additive::{edge_edge_ccd, point_triangle_ccd, AdditiveCcd};
