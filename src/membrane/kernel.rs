//! The per-vertex kernel: deformation, energy, its exact gradient with respect to the vertex's
//! bonds, and the SISSM preconditioner block.
//!
//! ## Deformation (Lu et al. 2023, eq. 13-15, Kirchhoff-Love form)
//!
//! With the rest frame `(t1, t2, nc)` and bond weights `beta` of [`super::RestData`], the
//! deformed tangent vectors are `a_k = F t_k = sum_j beta_jk (y_j - y_i)` (eq. 15 restricted to
//! the tangent plane, where the virtual bond drops out) and the deformed director is the unit
//! normal `n = (a1 x a2) / |a1 x a2|`. The deformation gradient is
//! `F = a1 t1^T + a2 t2^T + n nc^T`: the normal stays normal and unstretched, so the principal
//! stretches are the two singular values of `T = [a1 a2]` and 1, and `det F >= 0`.
//!
//! Choosing the director orthogonal to `T` (rather than the angle-weighted normal of the
//! deformed mesh) keeps the energy an exact function of the positions: the stretch energy is
//! stationary with respect to the director (its stress along `nc` is parallel to `n`), so the
//! gradient below is exact, rotations give zero force, and forces and torques balance.
//!
//! ## Energy of vertex i
//!
//! `E_i = V_i Psi(sigma_1, sigma_2, 1) + E_bend + E_hourglass`, from the non-affine residuals
//! `q_j = F^-1 (y_j - y_i) - xi_j` (zero for every affine map of a flat sheet):
//!
//! - bending (eq. 42 made isotropic): the normal residuals of a bent sheet are
//!   `q_j . nc = 1/2 xi_j^T H xi_j` with H the curvature tensor, so H is fitted to them by least
//!   squares over the 1-ring and `E_bend = A_i D / 2 |H|_F^2 = 1/2 |sum_j c_j (q_j . nc)|^2`
//!   with per-bond vectors `c_j` (`BondRest::curvature`) computed at rest;
//! - hourglass: `E_hourglass = kappa_t / 2 sum_j |q_j - nc (q_j . nc)|^2`, a penalty on the
//!   in-plane zero-energy modes of the 1-ring deformation gradient (a checkerboard
//!   displacement leaves F unchanged).
//!
//! ## Gradient
//!
//! `dE_i/d(y_j - y_i) = beta_j1 g_1 + beta_j2 g_2 + d_j`, with `g_k = dE_i/da_k` and
//! `d_j = F^-T W_j q_j`, `W_j q = kappa_t (q - nc (q . nc)) + nc (c_j . h)` (the explicit bending
//! term of eq. 43 with `F^-T`, see docs/model.md). The
//! stretch part is `g_k = V_i sum_m P_m u_m v_mk` (`T = U diag(sigma) V^T`, eq. 19); the
//! non-affine part adds `-(sum_j d_j (F^-1 e_j)^T) t_k` and the director term
//! `a2 x p`, `p x a1` with `p = (I - n n^T) h / |a1 x a2|`, `h = -(sum_j d_j (F^-1 e_j)^T) nc`.
//!
//! ## Preconditioner (eq. 24-26)
//!
//! `C_i = V_i k [w_1 u1 u1^T + w_2 u2 u2^T + w_n n n^T] + kappa_t sum_m u_m u_m^T / sigma_m^2
//! + kappa_n n n^T` with `kappa_n = lambda_max(sum_j c_j c_j^T)` bounding the bending term: the Hessian of the quadratic model `1/2 sum_j e_j^T C_i e_j` whose bond
//! Laplacian SISSM inverts approximately; see [`Preconditioner`] for the stretching weights.

use nalgebra::{SimdBool, Vector3};

use crate::geometry::any_orthogonal_unit;
use crate::real::{array_from_fn, select, Lanes, Real};
use crate::symmetric::SymmetricMatrix3;

use super::{Stencil, VertexConstants};

/// What the kernel reports for one vertex (or, for a SIMD pack, for one vertex per lane).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VertexResponse<S> {
    /// Stretching energy `V_i Psi` (J).
    pub stretch: S,
    /// Bending energy (J).
    pub bending: S,
    /// Hourglass energy (J).
    pub hourglass: S,
    /// Preconditioner block `C_i` (N/m), symmetric positive semi-definite.
    pub precond: SymmetricMatrix3<S>,
}

impl<S: Lanes> VertexResponse<S> {
    /// Total energy of the vertex (J).
    #[inline]
    pub fn energy(&self) -> S {
        self.stretch + self.bending + self.hourglass
    }
}

/// The part of a vertex's response that the solver keeps: what the move of every vertex in
/// its neighbourhood gathers (`C_i` and the total energy `E_i`; the split by term is only
/// reported, by [`super::Membrane::energy_terms`]). Eight scalars in one aligned array
/// (`C_00, C_11, C_22, C_01, C_02, C_12, E_i`, then a zero), so that a move sums its
/// neighbours' records with a few wide additions.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[repr(C, align(32))]
pub struct GatheredResponse<S> {
    values: [S; 8],
}

impl<S: Lanes> GatheredResponse<S> {
    #[inline(always)]
    pub fn new(precond: SymmetricMatrix3<S>, energy: S) -> Self {
        let ([d0, d1, d2], [u0, u1, u2]) = (precond.diagonal, precond.upper);
        Self {
            values: [d0, d1, d2, u0, u1, u2, energy, S::zero()],
        }
    }

    /// Preconditioner block `C_i` (N/m).
    #[inline(always)]
    pub fn precond(&self) -> SymmetricMatrix3<S> {
        let [d0, d1, d2, u0, u1, u2, ..] = self.values;
        SymmetricMatrix3 {
            diagonal: [d0, d1, d2],
            upper: [u0, u1, u2],
        }
    }

    /// `E_i` (J).
    #[inline(always)]
    pub fn energy(&self) -> S {
        self.values[6]
    }

    /// The response of lane `l` of a pack.
    #[inline(always)]
    pub fn lane(&self, l: usize) -> GatheredResponse<S::Scalar> {
        GatheredResponse {
            values: array_from_fn(|k| self.values[k].extract(l)),
        }
    }
}

impl<S: Lanes> From<&VertexResponse<S>> for GatheredResponse<S> {
    #[inline(always)]
    fn from(r: &VertexResponse<S>) -> Self {
        Self::new(r.precond, r.energy())
    }
}

impl<T: Real> std::ops::AddAssign for GatheredResponse<T> {
    /// Entry-wise (the padding stays zero).
    #[inline(always)]
    fn add_assign(&mut self, rhs: Self) {
        T::add_eight(&mut self.values, &rhs.values);
    }
}

/// The local deformation of a vertex: `T = [a1 a2] = U diag(sigma) V^T`, director `n`.
#[derive(Debug, Clone, Copy)]
pub struct Deformation<S: Lanes> {
    pub a1: Vector3<S>,
    pub a2: Vector3<S>,
    /// `|a1 x a2| = sigma_1 sigma_2` (area ratio).
    pub area_ratio: S,
    /// Unit director, orthogonal to `a1` and `a2`.
    pub normal: Vector3<S>,
    /// Left singular vectors (deformed tangent plane); `(u1, u2, normal)` is right-handed.
    pub u: [Vector3<S>; 2],
    /// Right singular vectors in `(t1, t2)` coordinates, a rotation (det = +1).
    pub v: [[S; 2]; 2],
    /// Singular values, descending, clamped from below at [`Lanes::stretch_floor`].
    pub sigma: [S; 2],
}

impl<S: Lanes> Deformation<S> {
    /// Principal stretches (two in-plane, descending, then the unstretched normal).
    #[inline]
    pub fn stretches(&self) -> [S; 3] {
        [self.sigma[0], self.sigma[1], S::one()]
    }

    /// Computes the deformation of a vertex from its deformed bond vectors `edges[j] = y_j - y_i`
    /// (in the order of the stencil's bonds).
    #[inline(always)]
    pub fn of(edges: &[Vector3<S>], stencil: &Stencil<'_, S>) -> Self {
        let (mut a1, mut a2) = (Vector3::zeros(), Vector3::zeros());
        for (e, b) in edges.iter().zip(stencil.bonds) {
            a1 += e * b.beta[0];
            a2 += e * b.beta[1];
        }
        let (p, r, s) = (a1.dot(&a1), a1.dot(&a2), a2.dot(&a2));
        let [cos, sin] = leading_eigenvector(p, r, s);
        let v = [[cos, sin], [-sin, cos]];
        let t_v1 = a1 * cos + a2 * sin;
        let sigma1 = t_v1.norm();
        let cross = a1.cross(&a2);
        let area_ratio = cross.norm();
        let tiny = S::stretch_floor() * S::stretch_floor();
        let stretched = sigma1.simd_gt(tiny);
        let u1 = select(stretched, t_v1 / sigma1, stencil.frame.t1);
        let regular = area_ratio.simd_gt(tiny * (p + s)) & area_ratio.simd_gt(S::zero());
        let mut normal = cross / area_ratio;
        if !regular.all() {
            normal = select(regular, normal, fallback_normal(&u1, &stencil.frame.nc));
        }
        let u2 = normal.cross(&u1);
        let sigma2 = (area_ratio / sigma1).select(stretched, S::zero());
        let lo = S::stretch_floor();
        Self {
            a1,
            a2,
            area_ratio,
            normal,
            u: [u1, u2],
            v,
            sigma: [sigma1.simd_max(lo), sigma2.simd_max(lo)],
        }
    }
}

/// A director for a collapsed neighbourhood: orthogonal to `u1`, as close to the rest normal
/// `nc` as possible.
#[inline]
fn fallback_normal<S: Lanes>(u1: &Vector3<S>, nc: &Vector3<S>) -> Vector3<S> {
    let n = u1.cross(nc);
    let usable = n.norm().simd_gt(S::lit(1e-3));
    select(usable, n.normalize().cross(u1), any_orthogonal_unit(u1))
}

/// Unit eigenvector `(cos, sin)` of the larger eigenvalue of the symmetric 2x2 matrix
/// `[[p, r], [r, s]]`, from whichever of its two closed forms does not cancel.
#[inline(always)]
fn leading_eigenvector<S: Lanes>(p: S, r: S, s: S) -> [S; 2] {
    let half_gap = (p - s) * S::lit(0.5);
    let root = (half_gap * half_gap + r * r).simd_sqrt();
    let upper = half_gap.simd_ge(S::zero());
    let x = (half_gap + root).select(upper, r); // (lambda_1 - s, r)
    let y = r.select(upper, root - half_gap); // (r, lambda_1 - p)
    let norm = (x * x + y * y).simd_sqrt();
    let defined = norm.simd_gt(S::zero());
    [
        (x / norm).select(defined, S::one()),
        (y / norm).select(defined, S::zero()),
    ]
}

/// Writes the deformed bond vectors `y_j - y_i` of vertex `i`, whose neighbours are `neighbors`,
/// into `edges` (the input of [`Deformation::of`] and [`vertex_kernel`]).
#[inline]
pub fn bond_vectors<T: Real>(
    i: usize,
    y: &[Vector3<T>],
    neighbors: &[u32],
    edges: &mut [Vector3<T>],
) {
    let yi = y[i];
    for (&j, e) in neighbors.iter().zip(edges) {
        *e = y[j as usize] - yi;
    }
}

/// Computes a vertex's energy and the gradient with respect to its bonds. On entry `bonds[j]`
/// holds the deformed bond vector `y_j - y_i` of the stencil's `j`-th bond; on return it holds
/// `dE_i / d(y_j - y_i)`.
///
/// Written over [`Lanes`]: with a SIMD pack, every lane is one vertex (a vertex with fewer
/// bonds than the pack's slots has zero rest data and zero bond vectors in the extra slots,
/// which contribute exactly nothing).
#[inline(always)]
pub fn vertex_kernel<S: Lanes>(
    stencil: &Stencil<'_, S>,
    mode: Preconditioner,
    bonds: &mut [Vector3<S>],
) -> VertexResponse<S> {
    let (rest, c) = (stencil.bonds, stencil.constants);
    let def = Deformation::of(bonds, stencil);
    let stretches = def.stretches();
    let [u1, u2] = def.u;
    let n = def.normal;
    let [v1, v2] = def.v;

    // Stretching: dPsi/dT = sum_m P_m u_m v_m^T.
    let stress = c.material.stress(stretches);
    let (p1, p2) = (stress[0] * c.volume, stress[1] * c.volume);
    let mut g1 = u1 * (p1 * v1[0]) + u2 * (p2 * v2[0]);
    let mut g2 = u1 * (p1 * v1[1]) + u2 * (p2 * v2[1]);
    let stretch_energy = c.volume * c.material.energy(stretches);

    let mut w = stretch_stiffness(mode, stretches, stress, c);

    let (mut bending, mut hourglass) = (S::zero(), S::zero());
    let non_affine = c.kappa_t.simd_gt(S::zero()) | c.kappa_n.simd_gt(S::zero());
    if non_affine.any() {
        // F^-1 in rest-frame coordinates: rows g1, g2, n map a deformed vector e to the
        // (t1, t2, nc) coordinates of F^-1 e.
        let inv = [S::one() / def.sigma[0], S::one() / def.sigma[1]];
        let row1 = u1 * (v1[0] * inv[0]) + u2 * (v2[0] * inv[1]);
        let row2 = u1 * (v1[1] * inv[0]) + u2 * (v2[1] * inv[1]);
        // First pass: the rest images F^-1 e_j (kept in `bonds` for the second pass) and the
        // fitted curvature h = sum_j curvature_j (q_j . nc).
        let mut curvature = Vector3::zeros();
        for (b, io) in rest.iter().zip(bonds.iter_mut()) {
            let e = *io;
            let image = Vector3::new(row1.dot(&e), row2.dot(&e), n.dot(&e));
            curvature += b.curvature * (image.z - b.xi.z);
            *io = image;
        }
        bending = S::lit(0.5) * curvature.norm_squared();
        let (mut h1, mut h2, mut hn) = (Vector3::zeros(), Vector3::zeros(), Vector3::zeros());
        for (b, io) in rest.iter().zip(bonds.iter_mut()) {
            let image = *io;
            let (q1, q2) = (image.x - b.xi.x, image.y - b.xi.y);
            hourglass += c.kappa_t * (q1 * q1 + q2 * q2);
            // d = F^-T W q with W q = (kappa_t q1, kappa_t q2, curvature_j . h) in the rest frame.
            let d =
                row1 * (c.kappa_t * q1) + row2 * (c.kappa_t * q2) + n * b.curvature.dot(&curvature);
            *io = d;
            h1 += d * image.x;
            h2 += d * image.y;
            hn += d * image.z;
        }
        hourglass *= S::lit(0.5);
        g1 -= h1;
        g2 -= h2;
        let p = (-hn + n * n.dot(&hn))
            / def
                .area_ratio
                .simd_max(S::stretch_floor() * S::stretch_floor());
        g1 += def.a2.cross(&p);
        g2 += p.cross(&def.a1);
        w[0] += c.kappa_t * inv[0] * inv[0];
        w[1] += c.kappa_t * inv[1] * inv[1];
        w[2] += c.kappa_n;
        for (b, io) in rest.iter().zip(bonds.iter_mut()) {
            *io += g1 * b.beta[0] + g2 * b.beta[1];
        }
    } else {
        for (b, io) in rest.iter().zip(bonds.iter_mut()) {
            *io = g1 * b.beta[0] + g2 * b.beta[1];
        }
    }
    let precond = SymmetricMatrix3::outer(&u1, w[0])
        + SymmetricMatrix3::outer(&u2, w[1])
        + SymmetricMatrix3::outer(&n, w[2]);
    VertexResponse {
        stretch: stretch_energy,
        bending,
        hourglass,
        precond,
    }
}

/// How the stretching stiffness enters the SISSM preconditioner `C_i`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Preconditioner {
    /// Curvature bounds: in-plane `max(d2Psi/dl_m^2 + |d2Psi/dl1 dl2|, (P1 -+ P2)/(l1 -+ l2))`,
    /// normal the tension stiffness `max(0, P_m / l_m)`, scaled by `V_i k_bound`. The quadratic
    /// model then bounds the energy's Hessian, so the Jacobi sweep cannot overshoot however
    /// stiff the material or long the step.
    #[default]
    Tangent,
    /// The paper's split (eq. 24-26): `U diag(P+ / lambda) U^T` scaled by `V_i k_iso`. Cheaper
    /// per iteration but the explicit part is stiffer than the implicit one, so stiff materials
    /// at large time steps can diverge.
    Paper,
}

/// Per-direction stiffness `(w_u1, w_u2, w_n)` (N/m) of the stretching part of `C_i`.
#[inline(always)]
fn stretch_stiffness<S: Lanes>(
    mode: Preconditioner,
    stretches: [S; 3],
    stress: [S; 3],
    c: &VertexConstants<S>,
) -> [S; 3] {
    match mode {
        Preconditioner::Paper => {
            let scale = c.volume * c.k_iso;
            c.material.implicit_stiffness(stretches).map(|s| s * scale)
        }
        Preconditioner::Tangent => {
            let [l1, l2, _] = stretches;
            let [h11, h22, h12] = c.material.in_plane_hessian(stretches);
            let pair_plus = (stress[0] + stress[1]) / (l1 + l2);
            let gap = l1 - l2;
            let distinct = gap.simd_gt(S::lit(1e-6) * l1);
            let pair_minus = ((stress[0] - stress[1]) / gap).select(distinct, S::zero());
            let shear = pair_plus.simd_max(pair_minus);
            let tension = (stress[0] / l1)
                .simd_max(stress[1] / l2)
                .simd_max(S::zero());
            let scale = c.volume * c.k_bound;
            let h12 = h12.simd_abs();
            [
                (h11 + h12).simd_max(shear) * scale,
                (h22 + h12).simd_max(shear) * scale,
                tension * scale,
            ]
        }
    }
}
