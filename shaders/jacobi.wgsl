// The SISSM Jacobi update of one vertex k (src/solve/sissm.rs, Lu et al. 2023 eq. 25 in
// residual form with the step length of eq. 31-33):
//
//   f_k = sum_j (t_kj - t_jk)                        gathered via reverse[] (N), no atomics
//   r   = m (y* - y) + h^2 f                         (kg m)
//   D   = m I + h^2 (n_k C_k + sum_j C_j)            (kg)
//   delta = D^-1 r, scaled by alpha = E h^2 / (h^2 f . delta) where the linearised elastic
//           energy E = E_k + sum_j E_j would drop below zero and the release is significant
//   y_next = push_out_with_friction(y + delta) in the D-metric, then Chebyshev where no
//            collider acted: y_next = omega (y_next - y_prev) + y_prev
//
// and measure.residual = |r + D c| / m (m) with c the colliders' reaction to the whole move
// y + D^-1 r.

// See PointSystem::step_length in src/solve/point_system.rs.
const STEP_LENGTH_SIGNIFICANCE: real = 0.1;

// D^-1 by cofactors; 1/m I if D is singular.
fn inverse_or(d: mat3x3<real>, mass: real) -> mat3x3<real> {
    let c0 = cross(d[1], d[2]);
    let c1 = cross(d[2], d[0]);
    let c2 = cross(d[0], d[1]);
    let det = dot(d[0], c0);
    if det == 0.0 {
        return mat3x3<real>(vec3<real>(1.0 / mass, 0.0, 0.0), vec3<real>(0.0, 1.0 / mass, 0.0), vec3<real>(0.0, 0.0, 1.0 / mass));
    }
    // Rows of the inverse are the cofactor columns over det; transpose into column form.
    return transpose(mat3x3<real>(c0, c1, c2)) * (1.0 / det);
}

// Keeps a move from `origin` (the iterate, outside) to `moved` out of the colliders in the
// metric of D, with Coulomb friction (push_out_with_friction in src/collider/friction.rs); a move that would cross
// a collider ends on the side it came from (collider_keep_side). Where y ends closer than
// `margin` to a collider it moves along D^-1 n to the offset surface, n the normal where it
// ends, by the normal reaction lambda (N s^2; collider_push_out). With friction, the slip of the
// vertex relative to the collider over the step, s = (y - y_t) - displacement, tangential part
// s_t, is removed when the reaction that takes, k |s_t| with k = |s_t|^2 / (s_t . D^-1 s_t),
// is within friction * lambda (sticking), and shortened by friction * lambda / k otherwise.
fn push_out_with_friction(origin: vec3<real>, moved: vec3<real>, start: vec3<real>, inverse: mat3x3<real>, margin: real) -> vec3<real> {
    var y = moved;
    for (var c = 0u; c < params.n_colliders; c++) {
        let k = colliders[c];
        let kept = collider_keep_side(k, origin, y);
        y = kept.xyz;
        let push = collider_push_out(k, y, kept.w, inverse, margin);
        if push.lambda == 0.0 {
            continue;
        }
        y = push.p;
        let n = push.normal;
        let reaction = push.lambda;
        if k.friction > 0.0 {
            let slip = (y - start) - k.displacement;
            let slip_t = slip - n * dot(n, slip);
            let compliance = dot(slip_t, inverse * slip_t);
            if compliance > 0.0 {
                let needed = dot(slip_t, slip_t) * length(slip_t) / compliance;
                let budget = k.friction * reaction;
                var cut: real = 1.0;
                if needed > budget {
                    cut = budget / needed;
                }
                y -= slip_t * cut;
            }
        }
    }
    return y;
}

@compute @workgroup_size(64)
fn jacobi(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= params.n || !live() {
        return;
    }
    let yk = y[k].xyz;
    if pinned[k] != 0u {
        y_next[k] = vec4<real>(yk, 0.0);
        measure[k].residual = 0.0;
        return;
    }
    let c = vertices[k];
    let mass = c.mass;
    let h2 = params.h * params.h;
    var force = vec3<real>(0.0);
    let first = offsets[k];
    let last = offsets[k + 1u];
    for (var b = first; b < last; b++) {
        force += bond_grad[b].xyz - bond_grad[reverse[b]].xyz;
    }
    let residual = (y_star[k].xyz - yk) * mass + force * h2;
    var stiffness = precond_of(k) * real(last - first);
    var energy = response[k].energy;
    for (var b = first; b < last; b++) {
        let j = indices[b];
        stiffness += precond_of(j);
        energy += response[j].energy;
    }
    let system = mat3x3<real>(vec3<real>(mass, 0.0, 0.0), vec3<real>(0.0, mass, 0.0), vec3<real>(0.0, 0.0, mass)) + stiffness * h2;
    let inverse = inverse_or(system, mass);
    let whole = inverse * residual;
    var delta = whole;
    if params.step_length != 0u {
        let energy_h2 = energy * h2;
        let descent = dot(force * h2, delta);
        let significant = descent > STEP_LENGTH_SIGNIFICANCE * mass * dot(delta, delta);
        if descent > energy_h2 && significant {
            delta *= max(energy_h2, 0.0) / descent;
        }
    }
    let start = y_start[k].xyz;
    let free_move = yk + delta;
    var next = push_out_with_friction(yk, free_move, start, inverse, c.half_thickness);
    // The colliders' reaction to the whole move counts as balancing the residual
    // (free_residual in src/solve/jacobi.rs).
    var reaction = next - free_move;
    if any(delta != whole) {
        reaction = push_out_with_friction(yk, yk + whole, start, inverse, c.half_thickness) - (yk + whole);
    }
    let free = residual + system * reaction;
    if iter.extrapolate != 0u && all(next == free_move) {
        let prev = y_prev[k].xyz;
        next = (next - prev) * iter.omega + prev;
    }
    y_next[k] = vec4<real>(next, 0.0);
    measure[k].residual = length(free) / mass;
}
