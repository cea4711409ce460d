//! A closed, consistently oriented triangle surface and the sign of the distance to it, by
//! angle-weighted pseudonormals (Baerentzen and Aanaes 2005): with `c` the closest surface
//! point to `p` and `n` the pseudonormal of the feature `c` lies on (the face normal inside a
//! face, the sum of the two face normals on an edge, the angle-weighted normal at a vertex),
//! `p` is outside exactly when `(p - c) . n >= 0`. This holds for every point of a closed
//! manifold surface, and unlike a ray parity test it needs no extra queries.

use std::collections::HashMap;

use nalgebra::Vector3;

use crate::error::{invalid, Result};
use crate::mesh::{angle_weighted_normals, TriangleMesh};

use crate::collider::sdf::nearest::Nearest;

/// A validated closed surface, oriented with its normals pointing out of the solid.
#[derive(Debug, Clone)]
pub struct ClosedSurface {
    pub vertices: Vec<Vector3<f64>>,
    /// Vertex indices, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    face_normals: Vec<Vector3<f64>>,
    /// Per triangle, edge `k` (from corner `k` to corner `k + 1`): the sum of the unit normals
    /// of the two triangles sharing it.
    edge_normals: Vec<[Vector3<f64>; 3]>,
    vertex_normals: Vec<Vector3<f64>>,
}

impl ClosedSurface {
    /// Checks the mesh (finite vertices, in-range indices, no degenerate or duplicate
    /// triangles: see [`TriangleMesh::new`]), that it is closed (every edge shared by exactly
    /// two triangles) and consistently oriented (they traverse it in opposite directions), and
    /// turns it outward (reversing every triangle when the enclosed volume is negative). Every
    /// failure names the offending triangle, edge or vertex.
    pub fn new(vertices: Vec<[f64; 3]>, triangles: Vec<[i64; 3]>) -> Result<Self> {
        if vertices.len() < 4 || triangles.len() < 4 {
            return Err(invalid!(
                "a closed mesh needs at least 4 vertices and 4 triangles, got {} and {}",
                vertices.len(),
                triangles.len()
            ));
        }
        let mesh = TriangleMesh::new(vertices.clone(), triangles.clone())?;
        check_closed(mesh.triangles())?;
        let x = mesh.vertices();
        let volume: f64 = mesh
            .triangles()
            .iter()
            .map(|t| x[t[0] as usize].dot(&x[t[1] as usize].cross(&x[t[2] as usize])) / 6.0)
            .sum();
        let scale = x
            .iter()
            .fold(0.0f64, |m, v| m.max((v - x[0]).norm()))
            .powi(3);
        if volume.abs() <= 1e-12 * scale {
            return Err(invalid!(
                "the closed mesh encloses no volume ({volume:e} m^3): it is flat"
            ));
        }
        let mesh = if volume > 0.0 {
            mesh
        } else {
            let flipped = triangles.iter().map(|t| [t[0], t[2], t[1]]).collect();
            TriangleMesh::new(vertices, flipped)?
        };
        let x = mesh.vertices().to_vec();
        let triangles = mesh.triangles().to_vec();
        let face_normals: Vec<Vector3<f64>> = triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| x[i as usize]);
                (b - a).cross(&(c - a)).normalize()
            })
            .collect();
        let mut across: HashMap<(u32, u32), usize> = HashMap::with_capacity(3 * triangles.len());
        for (t, tri) in triangles.iter().enumerate() {
            for k in 0..3 {
                across.insert((tri[k], tri[(k + 1) % 3]), t);
            }
        }
        let edge_normals = triangles
            .iter()
            .enumerate()
            .map(|(t, tri)| {
                std::array::from_fn(|k| {
                    let other = across[&(tri[(k + 1) % 3], tri[k])];
                    face_normals[t] + face_normals[other]
                })
            })
            .collect();
        let vertex_normals = angle_weighted_normals(&mesh)?;
        Ok(Self {
            vertices: x,
            triangles,
            face_normals,
            edge_normals,
            vertex_normals,
        })
    }

    /// The corners (m) of every triangle.
    pub fn corners(&self) -> Vec<[Vector3<f64>; 3]> {
        self.triangles
            .iter()
            .map(|t| t.map(|i| self.vertices[i as usize]))
            .collect()
    }

    /// Whether the query point whose closest surface point is `nearest` lies inside the solid.
    pub fn is_inside(&self, nearest: &Nearest) -> bool {
        let t = nearest.triangle;
        let w = nearest.weights;
        let zeros = w.iter().filter(|c| **c == 0.0).count();
        let pseudonormal = match zeros {
            0 => self.face_normals[t],
            1 => {
                // The edge between the two corners with non-zero weight.
                let k = (w.iter().position(|c| *c == 0.0).expect("one zero") + 1) % 3;
                self.edge_normals[t][k]
            }
            _ => {
                let k = w.iter().position(|c| *c != 0.0).unwrap_or(0);
                self.vertex_normals[self.triangles[t][k] as usize]
            }
        };
        nearest.separation.dot(&pseudonormal) < 0.0
    }
}

/// Every edge must be traversed once in each direction (a closed, consistently oriented
/// 2-manifold; [`TriangleMesh::new`] already rejected edges with three or more triangles).
fn check_closed(triangles: &[[u32; 3]]) -> Result<()> {
    let mut directed: HashMap<(u32, u32), usize> = HashMap::with_capacity(3 * triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            if let Some(first) = directed.insert((a, b), t) {
                return Err(invalid!(
                    "triangles {first} and {t} traverse edge ({a}, {b}) in the same direction: the mesh is not consistently oriented"
                ));
            }
        }
    }
    for (t, tri) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            if !directed.contains_key(&(b, a)) {
                return Err(invalid!(
                    "the mesh is not closed: edge ({a}, {b}) of triangle {t} has no triangle on its other side (MeshCollider needs a closed, watertight surface)"
                ));
            }
        }
    }
    Ok(())
}
