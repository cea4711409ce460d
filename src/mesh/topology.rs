//! A validated triangle mesh: finite vertices, in-range non-repeated indices, no degenerate or
//! duplicate triangles, manifold edges, no isolated vertices.

use std::collections::HashMap;

use nalgebra::Vector3;

use crate::error::{invalid, Result};

/// A triangle mesh that passed [`TriangleMesh::new`]'s checks.
#[derive(Debug, Clone)]
pub struct TriangleMesh {
    vertices: Vec<Vector3<f64>>,
    triangles: Vec<[u32; 3]>,
}

impl TriangleMesh {
    /// Validates and builds a mesh. Every failure names the offending vertex or triangle.
    ///
    /// A triangle is degenerate when its area is below `1e-12` times the square of its
    /// longest edge (a sliver that thin has no usable shape).
    pub fn new(vertices: Vec<[f64; 3]>, triangles: Vec<[i64; 3]>) -> Result<Self> {
        let n = vertices.len();
        if n < 3 {
            return Err(invalid!("a membrane needs at least 3 vertices, got {n}"));
        }
        if triangles.is_empty() {
            return Err(invalid!("a membrane needs at least one triangle, got 0"));
        }
        if n > u32::MAX as usize / 2 {
            return Err(invalid!("too many vertices: {n}"));
        }
        for (i, v) in vertices.iter().enumerate() {
            if let Some(c) = v.iter().position(|c| !c.is_finite()) {
                return Err(invalid!(
                    "vertex {i} has a non-finite coordinate {c}: {:?}",
                    v
                ));
            }
        }
        let vertices: Vec<Vector3<f64>> = vertices.iter().map(|v| Vector3::from(*v)).collect();
        let mut tris = Vec::with_capacity(triangles.len());
        for (t, tri) in triangles.iter().enumerate() {
            for &i in tri {
                if i < 0 || i as usize >= n {
                    return Err(invalid!(
                        "triangle {t} has vertex index {i} out of range [0, {n}): {:?}",
                        tri
                    ));
                }
            }
            let [a, b, c] = tri.map(|i| i as u32);
            if a == b || b == c || a == c {
                return Err(invalid!("triangle {t} repeats a vertex: {:?}", tri));
            }
            let (pa, pb, pc) = (
                vertices[a as usize],
                vertices[b as usize],
                vertices[c as usize],
            );
            let twice_area = (pb - pa).cross(&(pc - pa)).norm();
            let longest = (pb - pa).norm().max((pc - pb).norm()).max((pa - pc).norm());
            if twice_area <= 2e-12 * longest * longest {
                return Err(invalid!(
                    "triangle {t} {:?} is degenerate (area {:e} m^2 for its longest edge {:e} m)",
                    tri,
                    0.5 * twice_area,
                    longest
                ));
            }
            tris.push([a, b, c]);
        }
        let mut seen: HashMap<[u32; 3], usize> = HashMap::with_capacity(tris.len());
        for (t, tri) in tris.iter().enumerate() {
            let mut key = *tri;
            key.sort_unstable();
            if let Some(first) = seen.insert(key, t) {
                return Err(invalid!(
                    "triangle {t} {:?} duplicates triangle {first} (same vertices)",
                    tri
                ));
            }
        }
        let mut edge_count: HashMap<(u32, u32), (u32, usize)> =
            HashMap::with_capacity(3 * tris.len());
        for (t, tri) in tris.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                let e = edge_count.entry((a.min(b), a.max(b))).or_insert((0, t));
                e.0 += 1;
                if e.0 > 2 {
                    return Err(invalid!(
                        "edge ({}, {}) is non-manifold: triangle {t} is its third triangle (first: {})",
                        a.min(b),
                        a.max(b),
                        e.1
                    ));
                }
            }
        }
        let mut used = vec![false; n];
        for tri in &tris {
            for &i in tri {
                used[i as usize] = true;
            }
        }
        if let Some(i) = used.iter().position(|u| !u) {
            return Err(invalid!(
                "vertex {i} belongs to no triangle (isolated vertices are not allowed)"
            ));
        }
        Ok(Self {
            vertices,
            triangles: tris,
        })
    }

    /// Rest positions (m).
    pub fn vertices(&self) -> &[Vector3<f64>] {
        &self.vertices
    }

    /// Triangles as vertex indices.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.vertices.len()
    }

    /// A flat `nx` x `ny` vertex grid of size `a` x `b` (m) in the z = 0 plane, vertex
    /// `j * nx + i` at `(i a / (nx - 1), j b / (ny - 1), 0)`, two counter-clockwise triangles per
    /// cell split along the same diagonal (the layout of Python's `peridyn.grid`).
    pub fn grid(nx: usize, ny: usize, a: f64, b: f64) -> Result<Self> {
        if nx < 2 || ny < 2 {
            return Err(invalid!("a grid needs nx, ny >= 2, got ({nx}, {ny})"));
        }
        let mut v = Vec::with_capacity(nx * ny);
        for j in 0..ny {
            for i in 0..nx {
                v.push([
                    a * i as f64 / (nx - 1) as f64,
                    b * j as f64 / (ny - 1) as f64,
                    0.0,
                ]);
            }
        }
        let mut t = Vec::with_capacity(2 * (nx - 1) * (ny - 1));
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let p = (j * nx + i) as i64;
                let (right, up, diag) = (p + 1, p + nx as i64, p + nx as i64 + 1);
                t.push([p, right, diag]);
                t.push([p, diag, up]);
            }
        }
        Self::new(v, t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> (Vec<[f64; 3]>, Vec<[i64; 3]>) {
        (
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        )
    }

    fn message(v: Vec<[f64; 3]>, t: Vec<[i64; 3]>) -> String {
        TriangleMesh::new(v, t).unwrap_err().to_string()
    }

    #[test]
    fn accepts_a_valid_square() {
        let (v, t) = square();
        assert_eq!(TriangleMesh::new(v, t).unwrap().triangles().len(), 2);
    }

    #[test]
    fn names_every_kind_of_bad_input() {
        let (mut v, t) = square();
        v[2][1] = f64::NAN;
        assert!(message(v, t).contains("vertex 2"));
        let (v, mut t) = square();
        t[1][2] = 7;
        assert!(message(v, t).contains("triangle 1 has vertex index 7"));
        let (v, mut t) = square();
        t[0] = [0, 1, 1];
        assert!(message(v, t).contains("triangle 0 repeats"));
        let (v, mut t) = square();
        t.push([2, 0, 1]);
        assert!(message(v, t).contains("triangle 2 [2, 0, 1] duplicates triangle 0"));
        let (mut v, mut t) = square();
        v.push([2.0, 0.0, 0.0]);
        t.push([1, 4, 2]);
        t.push([4, 3, 0]);
        v.push([0.0, 0.0, 1.0]);
        t.push([0, 2, 5]);
        assert!(message(v, t).contains("non-manifold"));
        let (mut v, t) = square();
        v.push([5.0, 5.0, 5.0]);
        assert!(message(v, t).contains("vertex 4 belongs to no triangle"));
        let (mut v, t) = square();
        v[2] = [2.0, 0.0, 0.0];
        assert!(message(v, t).contains("triangle 0 [0, 1, 2] is degenerate"));
    }
}
