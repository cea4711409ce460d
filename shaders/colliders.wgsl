// Analytic colliders (src/contact/collider.rs, same arithmetic in the same order): exact signed
// distance (m, positive outside), the outward normal as its gradient, and the projection that
// keeps a vertex `margin` (half the thickness) out. A collider moving at constant velocity is
// evaluated at the end of the step: every shape function sees x - offset.
//
//   plane:   d = x . n - offset
//   sphere:  d = |x - c| - R
//   box:     q = |A^T (x - c)| - e,  d = |max(q, 0)| + min(max_k q_k, 0)
//   capsule: d = |x - closest point of the segment a-b| - R

const PLANE: u32 = 0u;
const SPHERE: u32 = 1u;
const BOX: u32 = 2u;
const CAPSULE: u32 = 3u;

// v / |v|, or +z for the zero vector.
fn unit_or_z(v: vec3<real>) -> vec3<real> {
    let n = length(v);
    if n > 0.0 {
        return v / n;
    }
    return vec3<real>(0.0, 0.0, 1.0);
}

// The point of the segment a-b closest to x.
fn closest_on_segment(x: vec3<real>, a: vec3<real>, b: vec3<real>) -> vec3<real> {
    let ab = b - a;
    let len2 = dot(ab, ab);
    var t: real = 0.0;
    if len2 > 0.0 {
        t = min(max(dot(x - a, ab) / len2, 0.0), 1.0);
    }
    return a + ab * t;
}

fn max3(v: vec3<real>) -> real {
    return max(v.x, max(v.y, v.z));
}

// Signed distance of the shape at its pose of time 0, at the local point x.
fn shape_distance(k: Collider, x: vec3<real>) -> real {
    if k.kind == PLANE {
        return dot(x, k.a) - k.b;
    }
    if k.kind == SPHERE {
        return length(x - k.a) - k.b;
    }
    if k.kind == BOX {
        let q = abs(transpose(k.axes) * (x - k.a)) - k.c;
        return length(max(q, vec3<real>(0.0))) + min(max3(q), 0.0);
    }
    return length(x - closest_on_segment(x, k.a, k.c)) - k.b;
}

// Unit outward normal of the shape at its pose of time 0 (a fixed choice on the medial axis).
fn shape_normal(k: Collider, x: vec3<real>) -> vec3<real> {
    if k.kind == PLANE {
        return k.a;
    }
    if k.kind == SPHERE {
        return unit_or_z(x - k.a);
    }
    if k.kind == BOX {
        let p = transpose(k.axes) * (x - k.a);
        let q = abs(p) - k.c;
        let sign = select(vec3<real>(1.0), vec3<real>(-1.0), p < vec3<real>(0.0));
        if max3(q) > 0.0 {
            let out = max(q, vec3<real>(0.0)) * sign;
            return k.axes * (out / length(out));
        }
        // inside: the face whose plane is nearest, the first largest q_k
        var local = vec3<real>(0.0, 0.0, sign.z);
        if q.x >= q.y && q.x >= q.z {
            local = vec3<real>(sign.x, 0.0, 0.0);
        } else if q.y >= q.z {
            local = vec3<real>(0.0, sign.y, 0.0);
        }
        return k.axes * local;
    }
    let d = x - closest_on_segment(x, k.a, k.c);
    let len = length(d);
    if len > 0.0 {
        return d / len;
    }
    return any_orthogonal_unit(unit_or_z(k.c - k.a)); // kernel.wgsl
}

// Signed distance (m) of the collider at the end of the step.
fn collider_distance(k: Collider, x: vec3<real>) -> real {
    return shape_distance(k, x - k.offset);
}

// Unit outward normal of the collider at the end of the step.
fn collider_normal(k: Collider, x: vec3<real>) -> vec3<real> {
    return shape_normal(k, x - k.offset);
}

// x itself when it is at least `margin` outside, else the point at distance `margin` along
// the normal.
fn collider_project(k: Collider, x: vec3<real>, margin: real) -> vec3<real> {
    let local = x - k.offset;
    let gap = shape_distance(k, local) - margin;
    if gap < 0.0 {
        return local - shape_normal(k, local) * gap + k.offset;
    }
    return x;
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
