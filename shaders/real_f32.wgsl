// The scalar type of the f32 kernels, and the functions whose f64 form needs care.

alias real = f32;
const REAL_EPSILON: real = 1.1920929e-7;
const REAL_MAX: real = 3.40282347e38;

// ln(x) for x > 0.
fn ln_real(x: real) -> real {
    return log(x);
}

// ln(1 + u) without cancellation for small u.
fn ln_1p(u: real) -> real {
    let w = 1.0 + u;
    if w == 1.0 {
        return u;
    }
    return log(w) * u / (w - 1.0);
}
