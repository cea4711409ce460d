// The scalar type of the f32 kernels, and the functions whose f64 form needs care.

alias real = f32;
const REAL_MAX: real = 3.40282347e38;

// (cos theta, sin theta) for theta = atan2(y, x) / 2, with atan2(0, 0) = 0 as in Rust: the
// right singular vector angle of the 2x2 metric (an isotropic metric has y = 0 and x = 0).
fn half_angle(y_: real, x: real) -> vec2<real> {
    var theta: real = 0.0;
    if x != 0.0 || y_ != 0.0 {
        theta = 0.5 * atan2(y_, x);
    }
    return vec2<real>(cos(theta), sin(theta));
}

// ln(1 + u) without cancellation for small u.
fn ln_1p(u: real) -> real {
    let w = 1.0 + u;
    if w == 1.0 {
        return u;
    }
    return log(w) * u / (w - 1.0);
}
