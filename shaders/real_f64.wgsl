// The scalar type of the f64 kernels (adapters with SHADER_F64). SPIR-V and the other shading
// languages offer sin, cos, atan2 and log in 32 bits only, so the two functions that need them
// are written with sqrt, ldexp and a series instead, to f64 accuracy.

alias real = f64;
const REAL_MAX: real = 1.7976931348623157e308;
const LN_2: real = 0.6931471805599453;

// (cos theta, sin theta) for theta = atan2(y, x) / 2 by the half-angle formulas:
// cos 2theta = x / r, cos theta = sqrt((1 + cos 2theta) / 2) >= 0, sin theta = sin 2theta /
// (2 cos theta); near theta = +-pi/2 the roles swap. atan2(0, 0) = 0.
fn half_angle(y_: real, x: real) -> vec2<real> {
    let r = sqrt(x * x + y_ * y_);
    if r == 0.0 {
        return vec2<real>(1.0, 0.0);
    }
    let c2 = x / r;
    let cs = sqrt(max(0.5 * (1.0 + c2), 0.0));
    if cs > 0.5 {
        return vec2<real>(cs, y_ / (2.0 * r * cs));
    }
    var sn = sqrt(max(0.5 * (1.0 - c2), 0.0));
    if y_ < 0.0 {
        sn = -sn;
    }
    return vec2<real>(y_ / (2.0 * r * sn), sn);
}

// ln(1 + u) without cancellation for small u: w = 1 + u = m 2^e with m near 1 (e from the
// f32 logarithm, m exact by ldexp), ln m = 2 atanh(s) = 2 sum_k s^(2k+1) / (2k+1) with
// s = (m - 1) / (m + 1), |s| < 0.18, to 1e-18 in 12 terms.
fn ln_1p(u: real) -> real {
    let w = 1.0 + u;
    if w == 1.0 {
        return u;
    }
    let e = i32(round(log2(f32(min(w, 1e38)))));
    let m = ldexp(w, -e);
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    var term = s;
    var sum = s;
    for (var k = 1; k < 12; k++) {
        term *= s2;
        sum += term / real(2 * k + 1);
    }
    return (real(e) * LN_2 + 2.0 * sum) * u / (w - 1.0);
}
