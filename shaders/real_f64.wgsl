// The scalar type of the f64 kernels (adapters with SHADER_F64). SPIR-V and the other shading
// languages offer log in 32 bits only, so ln_real and ln_1p are written with ldexp and a series
// instead, to f64 accuracy.

alias real = f64;
const REAL_EPSILON: real = 2.220446049250313e-16;
const REAL_MAX: real = 1.7976931348623157e308;
const LN_2: real = 0.6931471805599453;

// ln(x) for x > 0 (normal in f32): x = m 2^e with m near 1 (e from the f32 logarithm, m exact
// by ldexp), ln m = 2 atanh(s) = 2 sum_k s^(2k+1) / (2k+1) with s = (m - 1) / (m + 1),
// |s| < 0.18, to 1e-18 in 12 terms.
fn ln_real(x: real) -> real {
    let e = i32(round(log2(f32(min(x, 1e38)))));
    let m = ldexp(x, -e);
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    var term = s;
    var sum = s;
    for (var k = 1; k < 12; k++) {
        term *= s2;
        sum += term / real(2 * k + 1);
    }
    return real(e) * LN_2 + 2.0 * sum;
}

// ln(1 + u) without cancellation for small u.
fn ln_1p(u: real) -> real {
    let w = 1.0 + u;
    if w == 1.0 {
        return u;
    }
    return ln_real(w) * u / (w - 1.0);
}
