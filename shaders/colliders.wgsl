// Analytic colliders (src/contact/collider.rs): signed distance (m, positive outside), outward
// normal, and the Euclidean projection that keeps a vertex `margin` (half the thickness) out.
// Plane: d = x . n - offset. Sphere: d = |x - c| - R.

const PLANE: u32 = 0u;

fn collider_distance(k: Collider, x: vec3<real>) -> real {
    if k.kind == PLANE {
        return dot(x, k.a) - k.b;
    }
    return length(x - k.a) - k.b;
}

fn collider_normal(k: Collider, x: vec3<real>) -> vec3<real> {
    if k.kind == PLANE {
        return k.a;
    }
    let r = x - k.a;
    let d = length(r);
    if d > 0.0 {
        return r / d;
    }
    return vec3<real>(0.0, 0.0, 1.0);
}

// The closest point at distance >= margin from the surface.
fn collider_project(k: Collider, x: vec3<real>, margin: real) -> vec3<real> {
    if k.kind == PLANE {
        let d = dot(x, k.a) - k.b - margin;
        if d < 0.0 {
            return x - k.a * d;
        }
        return x;
    }
    let r = x - k.a;
    let dist = length(r);
    let reach = k.b + margin;
    if dist >= reach {
        return x;
    } else if dist > 0.0 {
        return k.a + r * (reach / dist);
    }
    return k.a + vec3<real>(0.0, 0.0, reach);
}

// Vertex i at x kept outside every collider, in order (pinned vertices stay where they are).
fn feasible(i: u32, x: vec3<real>) -> vec3<real> {
    var out = x;
    if pinned[i] == 0u {
        let margin = vertices[i].half_thickness;
        for (var c = 0u; c < params.n_colliders; c++) {
            out = collider_project(colliders[c], out, margin);
        }
    }
    return out;
}

// The local step: y_next <- the projection of the free vertices out of every collider, in order,
// then the per-vertex measure for the convergence and divergence tests:
// moved_i = |y_i^{k+1} - y_i^k|, bad_i = y_i^{k+1} not finite (the residual comes from jacobi).
@compute @workgroup_size(64)
fn project(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= params.n || !live() {
        return;
    }
    let next = feasible(i, y_next[i].xyz);
    y_next[i] = vec4<real>(next, 0.0);
    let ok = finite3(next);
    var moved: real = 0.0;
    if ok {
        moved = length(next - y[i].xyz);
    }
    measure[i].moved = moved;
    measure[i].bad = select(1u, 0u, ok);
}
