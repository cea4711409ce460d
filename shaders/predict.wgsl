// Start and end of a time step (src/solve/sissm.rs: predict, initial_guess, finish).

// Inertial target y* = y_t + h v_t + h^2 g for free vertices (pinned ones keep their target,
// uploaded by the host); the iterate starts at y*.
@compute @workgroup_size(64)
fn predict(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= params.n {
        return;
    }
    if pinned[i] == 0u {
        let h = params.h;
        y_star[i] = vec4<real>(y_start[i].xyz + velocity[i].xyz * h + params.gravity * (h * h), 0.0);
    }
    y[i] = y_star[i];
}

// y <- y_t (pinned vertices: their target), kept out of the colliders: the other candidate of
// the initial guess.
@compute @workgroup_size(64)
fn use_previous(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= params.n {
        return;
    }
    y[i] = vec4<real>(feasible(i, y_start[i].xyz, true, select(y_start[i], y_star[i], pinned[i] != 0u).xyz), 0.0);
}

// y <- y*, kept out of the colliders.
@compute @workgroup_size(64)
fn use_prediction(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= params.n {
        return;
    }
    y[i] = vec4<real>(feasible(i, y_start[i].xyz, true, y_star[i].xyz), 0.0);
}

// The initial iterate: y_t where its variational energy (history[0].x) is below that of y*
// (history[0].y), else y* (which y holds when this runs).
@compute @workgroup_size(64)
fn choose_initial(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= params.n {
        return;
    }
    if ctrl.history[0].x < ctrl.history[0].y {
        y[i] = vec4<real>(feasible(i, y_start[i].xyz, true, select(y_start[i], y_star[i], pinned[i] != 0u).xyz), 0.0);
    }
}

// After iteration k: y_prev <- y (Chebyshev only), y <- y_next.
@compute @workgroup_size(64)
fn commit(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= params.n || !live() {
        return;
    }
    if params.accelerated != 0u {
        y_prev[i] = y[i];
    }
    y[i] = y_next[i];
}

// v_{t+1} = (y_{t+1} - y_t) / h (m/s), y_t <- y_{t+1}.
@compute @workgroup_size(64)
fn finish(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= params.n {
        return;
    }
    let yi = y[i].xyz;
    velocity[i] = vec4<real>((yi - y_start[i].xyz) * (1.0 / params.h), 0.0);
    y_start[i] = vec4<real>(yi, 0.0);
}
