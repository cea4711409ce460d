//! Rest geometry of a mesh: lumped vertex areas and angle-weighted normals.

use nalgebra::Vector3;

use crate::error::{invalid, Result};
use crate::mesh::TriangleMesh;

/// Lumped area per vertex (m^2): a third of each incident triangle's area.
pub fn vertex_areas(mesh: &TriangleMesh) -> Vec<f64> {
    let x = mesh.vertices();
    let mut area = vec![0.0; x.len()];
    for &[a, b, c] in mesh.triangles() {
        let (a, b, c) = (a as usize, b as usize, c as usize);
        let third = (x[b] - x[a]).cross(&(x[c] - x[a])).norm() / 6.0;
        area[a] += third;
        area[b] += third;
        area[c] += third;
    }
    area
}

/// Angle-weighted vertex normals (Lu et al. 2023, eq. 13): `normalize(sum_J theta_J n_J)` over
/// the triangles J incident to the vertex, with theta_J the triangle's inner angle there.
///
/// Fails, naming the vertex, where the weighted normals cancel (a vertex whose triangles
/// fold back onto each other has no tangent plane).
pub fn angle_weighted_normals(mesh: &TriangleMesh) -> Result<Vec<Vector3<f64>>> {
    let x = mesh.vertices();
    let mut sum = vec![Vector3::zeros(); x.len()];
    let mut weight = vec![0.0; x.len()];
    for &tri in mesh.triangles() {
        let p = tri.map(|i| x[i as usize]);
        let normal = (p[1] - p[0]).cross(&(p[2] - p[0])).normalize();
        for k in 0..3 {
            let u = p[(k + 1) % 3] - p[k];
            let v = p[(k + 2) % 3] - p[k];
            let angle = u.angle(&v);
            sum[tri[k] as usize] += normal * angle;
            weight[tri[k] as usize] += angle;
        }
    }
    sum.iter()
        .zip(&weight)
        .enumerate()
        .map(|(i, (s, w))| {
            let norm = s.norm();
            if norm > 1e-6 * w {
                Ok(s / norm)
            } else {
                Err(invalid!(
                    "vertex {i} has no well-defined normal: its incident triangles fold back onto each other"
                ))
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flat_square_has_upward_normals_and_areas_summing_to_one() {
        let mesh = TriangleMesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        )
        .unwrap();
        let total: f64 = vertex_areas(&mesh).iter().sum();
        assert!((total - 1.0).abs() < 1e-15);
        for n in angle_weighted_normals(&mesh).unwrap() {
            assert!((n - Vector3::z()).norm() < 1e-15);
        }
    }
}
