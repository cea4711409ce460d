//! Rest data of a membrane: per-vertex rest frame, per-bond weights, masses and the stiffness
//! constants of the non-affine (bending and hourglass) energy, computed a vertex at a time
//! whenever needed (a solver build, a GPU upload, a query) rather than stored with the body.

use nalgebra::{Matrix3, Vector3};

use crate::error::{invalid, Result};
use crate::material::MaterialModel;
use crate::mesh::{angle_weighted_normals, vertex_areas, Neighborhood, TriangleMesh};
use crate::real::Real;

use super::MembraneParams;
use crate::geometry::any_orthogonal_unit;

/// Rest frame of a vertex: `t1`, `t2` span the plane on which the deformation gradient does not
/// depend on the virtual bond; `nc` completes a right-handed orthonormal frame (the rest
/// normal for a flat sheet).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame<T> {
    pub t1: Vector3<T>,
    pub t2: Vector3<T>,
    pub nc: Vector3<T>,
}

/// Rest data of a bond `i -> j`: `beta = (xi^T K_i^-1 t1, xi^T K_i^-1 t2)`, so that the
/// deformed tangent vectors are `a_k = sum_j beta_jk (y_j - y_i)`; the rest bond `xi` in the
/// vertex's rest-frame coordinates `(xi . t1, xi . t2, xi . nc)`; and
/// `curvature`, this bond's column of the scaled least-squares curvature fit: the bending
/// energy of the vertex is `1/2 |sum_j curvature_j (q_j . nc)|^2` (J).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BondRest<T> {
    pub beta: [T; 2],
    pub xi: Vector3<T>,
    pub curvature: Vector3<T>,
}

/// Per-vertex constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VertexConstants<T> {
    /// Lumped volume `V_i = thickness * area_i` (m^3).
    pub volume: T,
    /// Lumped mass `m_i = density * V_i` (kg).
    pub mass: T,
    /// `2 / sum_j |xi_ij|^2` (1/m^2): the isotropic in-plane approximation of `K_i^-1`
    /// (the discrete counterpart of the paper's `kappa_i^-1`, eq. 23), used by the preconditioner.
    pub k_iso: T,
    /// `lambda_max(sum_j beta_j beta_j^T)` (1/m^2): bounds `|T|^2 <= k_bound sum_j |e_j|^2`, so
    /// the bond Laplacian weighted by `k_bound` bounds the 1-ring deformation gradient's energy.
    pub k_bound: T,
    /// In-plane (hourglass) stiffness of the non-affine energy (N/m).
    pub kappa_t: T,
    /// Bound on the bending stiffness per bond, `lambda_max(sum_j c_j c_j^T)` (N/m), for the
    /// preconditioner.
    pub kappa_n: T,
    /// Half the thickness (m): colliders keep the mid-surface this far away.
    pub half_thickness: T,
    /// The material.
    pub material: MaterialModel<T>,
}

/// Rest data of several vertices (of one membrane or of several concatenated ones), in the
/// solver's precision. A user that keeps the bonds (and frames) elsewhere leaves them empty.
#[derive(Debug, Clone, PartialEq)]
pub struct RestData<T: Real> {
    pub frames: Vec<Frame<T>>,
    pub bonds: Vec<BondRest<T>>,
    pub vertices: Vec<VertexConstants<T>>,
}

/// The rest data of one vertex: its frame, its constants and its bonds (to `nb.of(i)`, in
/// that order), as computed by [`RestSource::vertex`].
#[derive(Debug, Clone, PartialEq)]
pub struct VertexRest<T> {
    pub frame: Frame<T>,
    pub constants: VertexConstants<T>,
    pub bonds: Vec<BondRest<T>>,
}

/// Lumped vertex volumes `V_i = thickness * area_i` (m^3), `area_i` a third of the area of
/// every incident triangle.
pub fn lumped_volumes(mesh: &TriangleMesh, thickness: f64) -> Vec<f64> {
    vertex_areas(mesh).iter().map(|a| thickness * a).collect()
}

/// Computes the rest data of a membrane one vertex at a time, so that no user has to hold the
/// per-bond data of a whole membrane in f64: it is a pure function of the rest mesh, the
/// neighbourhood and the parameters. Holds the mesh-wide inputs (angle-weighted normals and
/// vertex areas, 32 bytes per vertex).
#[derive(Debug, Clone)]
pub struct RestSource<'a> {
    x: &'a [Vector3<f64>],
    nb: &'a Neighborhood,
    params: MembraneParams,
    normals: Vec<Vector3<f64>>,
    areas: Vec<f64>,
}

impl<'a> RestSource<'a> {
    /// The rest data source of a membrane with rest mesh `mesh`, neighbourhood `nb` (of that
    /// mesh) and parameters `params`; fails where a vertex has no normal.
    pub fn new(
        mesh: &'a TriangleMesh,
        nb: &'a Neighborhood,
        params: &MembraneParams,
    ) -> Result<Self> {
        Ok(Self {
            x: mesh.vertices(),
            nb,
            params: *params,
            normals: angle_weighted_normals(mesh)?,
            areas: vertex_areas(mesh),
        })
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// Whether the mesh has no vertices.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// The rest data of vertex `i`; fails, naming the vertex, where its neighbourhood does not
    /// span a plane.
    ///
    /// Shape tensor with the Kirchhoff-Love virtual bond `x_perp = (thickness/2) N_i` (eq. 13-14):
    /// `K_i = sum_j xi_ij xi_ij^T + x_perp x_perp^T`. The tangent plane is `c^perp` with
    /// `c = K_i^-1 x_perp`; on it the deformation gradient of eq. 15 is independent of the
    /// virtual bond.
    ///
    /// Bending: the curvature tensor H (in `t1, t2` coordinates) is fitted by least squares to
    /// the normal residuals, `q_j . nc ~ 1/2 xi_j^T H xi_j`, and the energy is `A_i D / 2 |H|_F^2`,
    /// a Kirchhoff plate with bending Poisson ratio 0 (a cylindrical bend of curvature k stores
    /// `D k^2 / 2` per area in any direction). Hourglass: `kappa_t = hourglass * mu * V_i * k_iso`.
    pub fn vertex(&self, i: usize) -> Result<VertexRest<f64>> {
        let (x, nb, params) = (self.x, self.nb, &self.params);
        let half = 0.5 * params.thickness;
        let x_perp = self.normals[i] * half;
        let mut k = x_perp * x_perp.transpose();
        let mut sum2 = 0.0;
        for &j in nb.of(i) {
            let xi = x[j as usize] - x[i];
            k += xi * xi.transpose();
            sum2 += xi.norm_squared();
        }
        let k_inv = invert_shape_tensor(i, &k, half)?;
        let nc = (k_inv * x_perp).normalize();
        let t1 = any_orthogonal_unit(&nc);
        let t2 = nc.cross(&t1);
        let (d1, d2) = (k_inv * t1, k_inv * t2);
        let mut beta_gram = nalgebra::Matrix2::zeros();
        let mut bonds = Vec::with_capacity(nb.of(i).len());
        for &j in nb.of(i) {
            let xi = x[j as usize] - x[i];
            let beta = nalgebra::Vector2::new(xi.dot(&d1), xi.dot(&d2));
            beta_gram += beta * beta.transpose();
            bonds.push(BondRest {
                beta: [beta.x, beta.y],
                xi: Vector3::new(xi.dot(&t1), xi.dot(&t2), xi.dot(&nc)),
                curvature: Vector3::zeros(),
            });
        }
        let area = self.areas[i];
        let kappa_n = curvature_fit(&mut bonds, params.bending * area);
        let volume = params.thickness * area;
        let k_iso = 2.0 / sum2;
        let constants = VertexConstants {
            volume,
            mass: params.density * volume,
            k_iso,
            k_bound: beta_gram.symmetric_eigen().eigenvalues.max(),
            kappa_t: params.hourglass * params.material.shear_modulus() * volume * k_iso,
            kappa_n,
            half_thickness: half,
            material: params.material.to_real::<f64>(),
        };
        Ok(VertexRest {
            frame: Frame { t1, t2, nc },
            constants,
            bonds,
        })
    }
}

impl VertexRest<f64> {
    /// The kernel's view of this vertex.
    pub fn stencil(&self) -> Stencil<'_, f64> {
        Stencil {
            bonds: &self.bonds,
            frame: &self.frame,
            constants: &self.constants,
        }
    }
}

/// Everything the kernel needs to know about one vertex at rest (or, with a SIMD pack, about
/// one vertex per lane).
#[derive(Debug, Clone, Copy)]
pub struct Stencil<'a, T> {
    pub bonds: &'a [BondRest<T>],
    pub frame: &'a Frame<T>,
    pub constants: &'a VertexConstants<T>,
}

impl<T: Real> RestData<T> {
    /// The rest stencil of vertex `i` (this data's neighbourhood is `nb`); its bonds are those
    /// to `nb.of(i)`, in that order.
    #[inline]
    pub fn stencil<'a>(&'a self, nb: &'a Neighborhood, i: usize) -> Stencil<'a, T> {
        Stencil {
            bonds: &self.bonds[nb.bonds(i)],
            frame: &self.frames[i],
            constants: &self.vertices[i],
        }
    }

    /// Appends the rest data of every vertex of `source`, computed one vertex at a time and
    /// converted to this precision; with `geometry` false only the per-vertex constants (for a
    /// user that keeps frames and bonds elsewhere). No copy of the whole body in f64 is made.
    pub fn extend_from(&mut self, source: &RestSource, geometry: bool) -> Result<()> {
        for i in 0..source.len() {
            self.push(&source.vertex(i)?, geometry);
        }
        Ok(())
    }

    /// Appends one vertex's rest data converted to this precision (frame and bonds only with
    /// `geometry`).
    pub fn push(&mut self, one: &VertexRest<f64>, geometry: bool) {
        let v = |a: &Vector3<f64>| a.map(T::of);
        if geometry {
            let f = &one.frame;
            self.frames.push(Frame {
                t1: v(&f.t1),
                t2: v(&f.t2),
                nc: v(&f.nc),
            });
            self.bonds.extend(one.bonds.iter().map(|b| BondRest {
                beta: b.beta.map(T::of),
                xi: v(&b.xi),
                curvature: v(&b.curvature),
            }));
        }
        let c = &one.constants;
        self.vertices.push(VertexConstants {
            volume: T::of(c.volume),
            mass: T::of(c.mass),
            k_iso: T::of(c.k_iso),
            k_bound: T::of(c.k_bound),
            kappa_t: T::of(c.kappa_t),
            kappa_n: T::of(c.kappa_n),
            half_thickness: T::of(c.half_thickness),
            material: c.material.to_real(),
        });
    }

    /// Reserves room for `vertices` more vertices and `bonds` more bonds (frames only with
    /// `geometry`).
    pub fn reserve(&mut self, vertices: usize, bonds: usize, geometry: bool) {
        if geometry {
            self.frames.reserve_exact(vertices);
        }
        self.bonds.reserve_exact(bonds);
        self.vertices.reserve_exact(vertices);
    }

    /// Empty rest data.
    pub fn empty() -> Self {
        Self {
            frames: Vec::new(),
            bonds: Vec::new(),
            vertices: Vec::new(),
        }
    }
}

/// Fills the bonds' `curvature` vectors of one vertex and returns the preconditioner bound
/// `lambda_max(sum_j c_j c_j^T)`.
///
/// With `phi_j = 1/2 (x^2, y^2, 2xy)` for `(x, y)` the bond's `(t1, t2)` coordinates, the fitted
/// curvature is `H = (Phi^T Phi)^+ Phi^T q_n`. Scaling by `sqrt(A D) diag(1, 1, sqrt 2)` makes
/// `|c|^2 = A D |H|_F^2`. Directions the 1-ring cannot resolve (a corner vertex with two
/// neighbours) are left out of the pseudo-inverse.
fn curvature_fit(bonds: &mut [BondRest<f64>], area_rigidity: f64) -> f64 {
    if area_rigidity == 0.0 {
        return 0.0;
    }
    let phi = |xi: &Vector3<f64>| {
        let (x, y) = (xi.x, xi.y);
        Vector3::new(0.5 * x * x, 0.5 * y * y, x * y)
    };
    let gram: Matrix3<f64> = bonds
        .iter()
        .map(|b| phi(&b.xi) * phi(&b.xi).transpose())
        .sum();
    let eig = gram.symmetric_eigen();
    let top = eig.eigenvalues.max();
    let mut pinv = Matrix3::zeros();
    for k in 0..3 {
        let l = eig.eigenvalues[k];
        if l > 1e-9 * top {
            let v = eig.eigenvectors.column(k);
            pinv += v * v.transpose() / l;
        }
    }
    let scale = Vector3::new(1.0, 1.0, std::f64::consts::SQRT_2) * area_rigidity.sqrt();
    let mut outer = Matrix3::zeros();
    for b in bonds.iter_mut() {
        b.curvature = (pinv * phi(&b.xi)).component_mul(&scale);
        outer += b.curvature * b.curvature.transpose();
    }
    outer.symmetric_eigen().eigenvalues.max()
}

/// Smallest ratio of the shape tensor's eigenvalues that is inverted.
const SHAPE_TENSOR_CONDITION: f64 = 1e-14;

/// `K^-1`, refusing shape tensors too ill-conditioned to invert reliably. The normal
/// direction's eigenvalue is `half^2` (the virtual bond, `half` = thickness / 2), so a
/// thickness far below the bond lengths alone makes `K` ill-conditioned: that is named as such.
fn invert_shape_tensor(i: usize, k: &Matrix3<f64>, half: f64) -> Result<Matrix3<f64>> {
    let eig = k.symmetric_eigen().eigenvalues;
    let (lo, hi) = (eig.min(), eig.max());
    let in_plane = eig
        .iter()
        .filter(|&&l| l > lo)
        .fold(f64::INFINITY, |a, &l| a.min(l));
    let thin = half > 0.0
        && half * half <= SHAPE_TENSOR_CONDITION * hi
        && in_plane > SHAPE_TENSOR_CONDITION * hi;
    if thin && lo <= SHAPE_TENSOR_CONDITION * hi {
        return Err(invalid!(
            "vertex {i}: thickness {:e} m is too small for the mesh's bond lengths (up to about \
             {:e} m): thickness / 2 must exceed {SHAPE_TENSOR_CONDITION:e}^(1/2) = 1e-7 times \
             the bonds' size for the shape tensor (eigenvalues {lo:e}..{hi:e}) to be inverted \
             reliably; use thickness > {:e} m, or a finer mesh",
            2.0 * half,
            hi.sqrt(),
            2.0 * (SHAPE_TENSOR_CONDITION * hi).sqrt()
        ));
    }
    if lo.is_nan() || lo <= SHAPE_TENSOR_CONDITION * hi {
        return Err(invalid!(
            "vertex {i}: its neighbourhood does not span a plane (shape tensor eigenvalues {lo:e}..{hi:e}); \
             check for collinear neighbours or a thickness of zero"
        ));
    }
    k.try_inverse()
        .ok_or_else(|| invalid!("vertex {i}: singular shape tensor"))
}
