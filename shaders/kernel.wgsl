// The per-vertex kernel (src/membrane/kernel.rs): for vertex i at the iterate y, its energy
// E_i (J), the gradient dE_i/d(y_j - y_i) (N) of every bond i -> j into bond_grad, and the
// SISSM preconditioner block C_i (N/m) into response.
//
// Deformation (Lu et al. 2023, eq. 13-15, Kirchhoff-Love form): a_k = sum_j beta_jk (y_j - y_i),
// T = [a1 a2] = U diag(sigma) V^T by the closed-form 2x2 SVD of the metric T^T T, director
// n = a1 x a2 / |a1 x a2|, stretches (sigma1, sigma2, 1).
// Energy: E_i = V_i Psi(sigma) + 1/2 |sum_j c_j (q_j . nc)|^2 + kappa_t/2 sum_j |q_j,t|^2 with the
// non-affine residuals q_j = F^-1 (y_j - y_i) - xi_j.
// Gradient: dE_i/de_j = beta_j1 g1 + beta_j2 g2 + d_j, g_k = V_i sum_m P_m u_m v_mk plus the
// non-affine and director terms, d_j = F^-T W_j q_j.
// Preconditioner: C_i = w1 u1 u1^T + w2 u2 u2^T + wn n n^T.

struct Deformation {
    a1: vec3<real>,
    a2: vec3<real>,
    area_ratio: real,        // |a1 x a2| = sigma1 sigma2
    normal: vec3<real>,
    u1: vec3<real>,
    u2: vec3<real>,
    v1: vec2<real>,          // right singular vectors in (t1, t2) coordinates
    v2: vec2<real>,
    sigma: vec2<real>,       // descending, clamped below at min_stretch
}

// A unit vector orthogonal to the unit vector n, chosen deterministically.
fn any_orthogonal_unit(n: vec3<real>) -> vec3<real> {
    let a = abs(n);
    var axis = vec3<real>(0.0, 0.0, 1.0);
    if a.x <= a.y && a.x <= a.z {
        axis = vec3<real>(1.0, 0.0, 0.0);
    } else if a.y <= a.z {
        axis = vec3<real>(0.0, 1.0, 0.0);
    }
    return normalize(cross(n, axis));
}

// Unit eigenvector (cos, sin) of the larger eigenvalue of the symmetric 2x2 matrix
// [[p, r], [r, s]], from whichever of its two closed forms does not cancel.
fn leading_eigenvector(p: real, r: real, s: real) -> vec2<real> {
    let half_gap = (p - s) * 0.5;
    let root = sqrt(half_gap * half_gap + r * r);
    var v = vec2<real>(r, root - half_gap);     // (r, lambda_1 - p)
    if half_gap >= 0.0 {
        v = vec2<real>(half_gap + root, r);     // (lambda_1 - s, r)
    }
    let norm = length(v);
    if norm > 0.0 {
        return v / norm;
    }
    return vec2<real>(1.0, 0.0);
}

fn deformation_of(i: u32, yi: vec3<real>) -> Deformation {
    let c = vertices[i];
    var a1 = vec3<real>(0.0);
    var a2 = vec3<real>(0.0);
    for (var b = offsets[i]; b < offsets[i + 1u]; b++) {
        let e = y[indices[b]].xyz - yi;
        a1 += e * bonds[b].beta1;
        a2 += e * bonds[b].beta2;
    }
    let p = dot(a1, a1);
    let r = dot(a1, a2);
    let s = dot(a2, a2);
    let v = leading_eigenvector(p, r, s);
    let cs = v.x;
    let sn = v.y;
    let t_v1 = a1 * cs + a2 * sn;
    let sigma1 = length(t_v1);
    let cr = cross(a1, a2);
    let area_ratio = length(cr);
    let tiny = params.min_stretch * params.min_stretch;
    var u1 = c.t1;
    if sigma1 > tiny {
        u1 = t_v1 / sigma1;
    }
    var normal: vec3<real>;
    if area_ratio > tiny * (p + s) && area_ratio > 0.0 {
        normal = cr / area_ratio;
    } else {
        let m = cross(u1, c.nc);
        if length(m) > 1e-3 {
            normal = cross(normalize(m), u1);
        } else {
            normal = any_orthogonal_unit(u1);
        }
    }
    var sigma2: real = 0.0;
    if sigma1 > tiny {
        sigma2 = area_ratio / sigma1;
    }
    var d: Deformation;
    d.a1 = a1;
    d.a2 = a2;
    d.area_ratio = area_ratio;
    d.normal = normal;
    d.u1 = u1;
    d.u2 = cross(normal, u1);
    d.v1 = vec2<real>(cs, sn);
    d.v2 = vec2<real>(-sn, cs);
    d.sigma = max(vec2<real>(sigma1, sigma2), vec2<real>(params.min_stretch));
    return d;
}

// Per-direction stiffness (w_u1, w_u2, w_n) (N/m) of the stretching part of C_i.
fn stretch_stiffness(c: Vertex, l: vec3<real>, stress: vec3<real>) -> vec3<real> {
    if params.preconditioner == 1u {
        return material_implicit_stiffness(c, l) * (c.volume * c.k_iso);
    }
    let hess = material_in_plane_hessian(c, l);
    let pair_plus = (stress.x + stress.y) / (l.x + l.y);
    let gap = l.x - l.y;
    var pair_minus: real = 0.0;
    if gap > 1e-6 * l.x {
        pair_minus = (stress.x - stress.y) / gap;
    }
    let shear = max(pair_plus, pair_minus);
    let tension = max(max(stress.x / l.x, stress.y / l.y), 0.0);
    let scale = c.volume * c.k_bound;
    return vec3<real>(
        max(hess.x + abs(hess.z), shear) * scale,
        max(hess.y + abs(hess.z), shear) * scale,
        tension * scale,
    );
}

@compute @workgroup_size(64)
fn evaluate(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= params.n || !live() {
        return;
    }
    let c = vertices[i];
    let yi = y[i].xyz;
    let def = deformation_of(i, yi);
    let l = vec3<real>(def.sigma, 1.0);
    let u1 = def.u1;
    let u2 = def.u2;
    let n = def.normal;

    // Stretching: dPsi/dT = sum_m P_m u_m v_m^T.
    let stress = material_stress(c, l);
    let p1 = stress.x * c.volume;
    let p2 = stress.y * c.volume;
    var g1 = u1 * (p1 * def.v1.x) + u2 * (p2 * def.v2.x);
    var g2 = u1 * (p1 * def.v1.y) + u2 * (p2 * def.v2.y);
    var energy = c.volume * material_energy(c, l);
    var w = stretch_stiffness(c, l, stress);

    let first = offsets[i];
    let last = offsets[i + 1u];
    if c.kappa_t > 0.0 || c.kappa_n > 0.0 {
        // F^-1 in rest-frame coordinates: rows row1, row2, n map a deformed vector e to the
        // (t1, t2, nc) coordinates of F^-1 e (bonds[b].xi is in those coordinates too).
        let inv = 1.0 / def.sigma;
        let row1 = u1 * (def.v1.x * inv.x) + u2 * (def.v2.x * inv.y);
        let row2 = u1 * (def.v1.y * inv.x) + u2 * (def.v2.y * inv.y);
        // First pass: rest images F^-1 e_j (kept in bond_grad) and the fitted curvature.
        var curvature = vec3<real>(0.0);
        for (var b = first; b < last; b++) {
            let e = y[indices[b]].xyz - yi;
            let image = vec3<real>(dot(row1, e), dot(row2, e), dot(n, e));
            curvature += bonds[b].curvature * (image.z - bonds[b].xi.z);
            bond_grad[b] = vec4<real>(image, 0.0);
        }
        let bending = 0.5 * dot(curvature, curvature);
        var hourglass: real = 0.0;
        var h1 = vec3<real>(0.0);
        var h2 = vec3<real>(0.0);
        var hn = vec3<real>(0.0);
        for (var b = first; b < last; b++) {
            let image = bond_grad[b].xyz;
            let q1 = image.x - bonds[b].xi.x;
            let q2 = image.y - bonds[b].xi.y;
            hourglass += c.kappa_t * (q1 * q1 + q2 * q2);
            // d = F^-T W q with W q = (kappa_t q1, kappa_t q2, curvature_j . h) in the rest frame.
            let d = row1 * (c.kappa_t * q1) + row2 * (c.kappa_t * q2) + n * dot(bonds[b].curvature, curvature);
            bond_grad[b] = vec4<real>(d, 0.0);
            h1 += d * image.x;
            h2 += d * image.y;
            hn += d * image.z;
        }
        energy = energy + bending + 0.5 * hourglass;
        g1 -= h1;
        g2 -= h2;
        let tiny = params.min_stretch * params.min_stretch;
        let pv = (-hn + n * dot(n, hn)) / max(def.area_ratio, tiny);
        g1 += cross(def.a2, pv);
        g2 += cross(pv, def.a1);
        w += vec3<real>(c.kappa_t * inv.x * inv.x, c.kappa_t * inv.y * inv.y, c.kappa_n);
        for (var b = first; b < last; b++) {
            bond_grad[b] += vec4<real>(g1 * bonds[b].beta1 + g2 * bonds[b].beta2, 0.0);
        }
    } else {
        for (var b = first; b < last; b++) {
            bond_grad[b] = vec4<real>(g1 * bonds[b].beta1 + g2 * bonds[b].beta2, 0.0);
        }
    }
    let cm = outer(u1, u1) * w.x + outer(u2, u2) * w.y + outer(n, n) * w.z;
    var out: Response;
    out.c_diag = vec3<real>(cm[0][0], cm[1][1], cm[2][2]);
    out.energy = energy;
    out.c_off = vec3<real>(cm[1][0], cm[2][0], cm[2][1]);
    out.pad = 0.0;
    response[i] = out;
}
