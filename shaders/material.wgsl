// Constitutive models in principal stretches l = (l1, l2, l3), mirroring src/material/
// (the CPU/GPU parity tests pin the two together). Energies in J/m^3, stresses in Pa.
//
// StretchA3 (Lu et al. 2023, eq. 39-41): Psi = s0 sum_m (l_m^2 - 1)^2 (l_m^2 + 2) / (12 l_m^2),
//   P_m = s0 (l_m^3 - l_m^-3) / 3.
// NeoHookean (eq. 36-38): Psi = s0 sum_m (x - 1 - ln x)|_{x = l_m^2} + s1 (J - 1)^2,
//   P_m = 2 s0 l_m + 2 s1 J^2 / l_m - 2 (s0 + s1 J) / l_m.

const STRETCH_A3: u32 = 0u;

fn material_energy(c: Vertex, l: vec3<real>) -> real {
    if c.model == STRETCH_A3 {
        let s2 = l * l;
        let strain = (l - 1.0) * (l + 1.0);
        let terms = strain * strain * (s2 + 2.0) / s2 * (1.0 / 12.0);
        return (terms.x + terms.y + terms.z) * c.s0;
    }
    let j = l.x * l.y * l.z;
    var shear: real = 0.0;
    for (var m = 0u; m < 3u; m++) {
        // As src/material/neo_hookean.rs: u - ln(1 + u) near 1, u - ln x far from it (in f32
        // 1 + u does not hold a tiny x = l^2).
        let u = (l[m] - 1.0) * (l[m] + 1.0);
        var term: real;
        if abs(u) < 0.5 {
            term = u_minus_ln_1p(u);
        } else {
            term = u - ln_real(l[m] * l[m]);
        }
        shear += max(term, 0.0);
    }
    return c.s0 * shear + c.s1 * (j - 1.0) * (j - 1.0);
}

// u - ln(1 + u) for |u| < 1/2: below |u| = 0.1 the series u^2 (1/2 - u/3 + u^2/4 - ...) in 14
// terms (the difference of the two terms would cancel), as u_minus_ln_1p on the CPU.
fn u_minus_ln_1p(u: real) -> real {
    if abs(u) < 0.1 {
        var series: real = 0.0;
        for (var k = 15; k >= 2; k--) {
            series = series * u + select(real(-1.0), real(1.0), k % 2 == 0) / real(k);
        }
        return u * u * series;
    }
    return u - ln_1p(u);
}

// dPsi/dl_m, summed from the split P+ + P- like the CPU.
fn material_stress(c: Vertex, l: vec3<real>) -> vec3<real> {
    if c.model == STRETCH_A3 {
        let third = c.s0 * (1.0 / 3.0);
        return third * l * l * l + (-third / (l * l * l));
    }
    let j = l.x * l.y * l.z;
    return (2.0 * c.s0 * l + 2.0 * c.s1 * j * j / l) + (-2.0 * (c.s0 + c.s1 * j) / l);
}

// (d2Psi/dl1^2, d2Psi/dl2^2, d2Psi/dl1 dl2) at fixed l3.
fn material_in_plane_hessian(c: Vertex, l: vec3<real>) -> vec3<real> {
    if c.model == STRETCH_A3 {
        let d = c.s0 * (l * l + 1.0 / (l * l * l * l));
        return vec3<real>(d.x, d.y, 0.0);
    }
    let j = l.x * l.y * l.z;
    let d = 2.0 * c.s0 * (1.0 + 1.0 / (l * l)) + 2.0 * c.s1 * (j / l) * (j / l);
    return vec3<real>(d.x, d.y, 2.0 * c.s1 * j * (2.0 * j - 1.0) / (l.x * l.y));
}

// P+_m / l_m, the implicit stiffness of the paper's split (eq. 24-26).
fn material_implicit_stiffness(c: Vertex, l: vec3<real>) -> vec3<real> {
    if c.model == STRETCH_A3 {
        return c.s0 * (1.0 / 3.0) * l * l;
    }
    let j = l.x * l.y * l.z;
    return 2.0 * c.s0 + 2.0 * c.s1 * j * j / (l * l);
}
