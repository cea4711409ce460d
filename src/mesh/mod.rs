//! Triangle meshes: validation, neighbourhoods (CSR) and rest geometry.

mod geometry;
mod neighborhood;
mod topology;

pub use geometry::{angle_weighted_normals, vertex_areas};
pub use neighborhood::Neighborhood;
pub use topology::TriangleMesh;
