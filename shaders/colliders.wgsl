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

// Unit outward normal of the collider at the end of the step.
fn collider_normal(k: Collider, x: vec3<real>) -> vec3<real> {
    return shape_normal(k, x - k.offset);
}

// x itself when it is at least `margin` outside (`distance`: its signed distance), else the
// point at distance `margin` along the normal (project_at in src/contact/collider.rs).
fn collider_project(k: Collider, x: vec3<real>, distance: real, margin: real) -> vec3<real> {
    let gap = distance - margin;
    if gap < 0.0 {
        let local = x - k.offset;
        return local - shape_normal(k, local) * gap + k.offset;
    }
    return x;
}

// A point `margin` (m) or less outside (`distance`: its signed distance) moved to the nearest
// point p of the offset surface d = margin in the metric inverse^-1: p = x + lambda A n(p),
// with the normal at p itself (push_out in src/collider/shape.rs, the same rounds in the same
// order): from p_0 = x, each round moves along A n_k to the surface linearised at p_k, until
// the normal no longer changes or a round moves p by PUSH_SETTLE_ULPS units of round-off;
// where PUSH_ROUNDS rounds do not settle, the first round's point. lambda is 0 (and p = x)
// where x is outside or A has no positive curvature along n.
struct Push {
    p: vec3<real>,
    lambda: real,
    normal: vec3<real>,
}

// The point x + lambda A n on the surface linearised at `at` (signed distance d there), and
// lambda (w; 0 where A has no positive curvature along n).
fn push_towards(inverse: mat3x3<real>, n: vec3<real>, x: vec3<real>, at: vec3<real>, d: real, margin: real) -> vec4<real> {
    let along = inverse * n;
    let reach = dot(n, along);
    if reach <= 0.0 {
        return vec4<real>(x, 0.0);
    }
    let lambda = (margin - d - dot(n, x - at)) / reach;
    return vec4<real>(x + along * lambda, lambda);
}

fn collider_push_out(k: Collider, x: vec3<real>, distance: real, inverse: mat3x3<real>, margin: real) -> Push {
    if distance - margin >= 0.0 {
        return Push(x, 0.0, vec3<real>(0.0));
    }
    var n = collider_normal(k, x);
    let first = push_towards(inverse, n, x, x, distance, margin);
    if first.w == 0.0 {
        return Push(x, 0.0, n);
    }
    var p = first.xyz;
    var lambda = first.w;
    for (var attempt = 0u; attempt < PUSH_ROUNDS; attempt++) {
        let normal = collider_normal(k, p);
        if all(normal == n) {
            return Push(p, lambda, n);
        }
        let next = push_towards(inverse, normal, x, p, shape_distance(k, p - k.offset), margin);
        if next.w == 0.0 {
            break;
        }
        let settled = length(next.xyz - p) <= REAL_EPSILON * PUSH_SETTLE_ULPS * (length(p) + 1.0);
        p = next.xyz;
        lambda = next.w;
        n = normal;
        if settled {
            return Push(p, lambda, n);
        }
    }
    return Push(first.xyz, first.w, collider_normal(k, x));
}

// A move that would cross a collider in one go (src/contact/collider/crossing.rs, the same
// decisions in the same order; every shape here is an exact, convex distance): sphere tracing
// along the straight path from `origin` (outside) to `to`, at most TRACE_STEPS steps each as
// long as the signed distance, touching where it falls to TRACE_TOLERANCE of its value at
// `origin` or to TOUCH_DISTANCE (m) if that is smaller, and ending early where the rest of the
// path is shorter than the distances at its two ends together, or where a step brings the
// path no closer. TRACE_STEPS, TRACE_TOLERANCE and TOUCH_DISTANCE are the CPU's, prepended by
// src/gpu/pipelines.rs.

// The end of the move from `origin` to `to` (local points; `distance` is the signed distance at
// `to`) to take out of the shape: `to`, unless its path reaches the surface at e and `to` is not
// inside on that side (the normal at `to` within 90 degrees of the normal n at e); then
// e + (I - n n^T)(to - e) where that is outside, else e.
fn shape_keep_side(k: Collider, origin: vec3<real>, to: vec3<real>, distance: real) -> vec3<real> {
    let path = to - origin;
    if distance >= 0.0 && distance * distance >= dot(path, path) {
        return to;
    }
    let start = shape_distance(k, origin);
    if !(start > 0.0) {
        return to;
    }
    let len = length(path);
    if !(len > 0.0) {
        return to;
    }
    let direction = path / len;
    let beyond = select(0.0, distance, distance > 0.0);
    let close = min(start * TRACE_TOLERANCE, TOUCH_DISTANCE);
    var along: real = 0.0;
    var last = start;
    var touched = false;
    var entry = to;
    for (var s = 0u; s < TRACE_STEPS; s++) {
        if len - along < last + beyond {
            return to;
        }
        along += last;
        let x = origin + direction * along;
        let here = shape_distance(k, x);
        if here <= close {
            touched = true;
            entry = x;
            break;
        }
        if here >= last {
            return to;
        }
        last = here;
    }
    if !touched {
        if len - along < last + beyond {
            return to;
        }
        entry = origin + direction * along;
    }
    let n = shape_normal(k, entry);
    if distance < 0.0 && dot(shape_normal(k, to), n) > 0.0 {
        return to;
    }
    let rest = to - entry;
    let slide = entry + (rest - n * dot(n, rest));
    if shape_distance(k, slide) >= 0.0 {
        return slide;
    }
    return entry;
}

// The end of the move from `origin` to `to` (at the end of the step) kept on the side of the
// collider the move came from (xyz), and its signed distance (w).
fn collider_keep_side(k: Collider, origin: vec3<real>, to: vec3<real>) -> vec4<real> {
    let local_to = to - k.offset;
    let distance = shape_distance(k, local_to);
    let end = shape_keep_side(k, origin - k.offset, local_to, distance);
    if all(end == local_to) {
        return vec4<real>(to, distance);
    }
    return vec4<real>(end + k.offset, shape_distance(k, end));
}

// Vertex i at x, the end of a move from `origin` (outside the colliders), kept outside every
// collider, in order, on the side it came from (pinned vertices stay where they are). With
// `of_step`, `origin` is the position at the start of the step, which each collider's motion
// carries by its displacement.
fn feasible(i: u32, origin: vec3<real>, of_step: bool, x: vec3<real>) -> vec3<real> {
    var out = x;
    if pinned[i] == 0u {
        let margin = vertices[i].half_thickness;
        for (var c = 0u; c < params.n_colliders; c++) {
            let k = colliders[c];
            var start = origin;
            if of_step {
                start += k.displacement;
            }
            let kept = collider_keep_side(k, start, out);
            out = collider_project(k, kept.xyz, kept.w, margin);
        }
    }
    return out;
}

// Vertex i's move from y_t to `next` (finite) would set a non-finite velocity, or, for a free
// vertex, is longer than max_move (the speed limit), unless it is within ROUNDOFF_MOVES ulps of
// the coordinates (a tiny h must not turn one rounding into a divergence): the test of
// Points::first_bad_velocity (src/solve/points.rs), made on every iterate.
const ROUNDOFF_MOVES: real = 8.0;
fn runaway(i: u32, next: vec3<real>) -> bool {
    let d = next - y_start[i].xyz;
    if !finite3(d * (1.0 / params.h)) {
        return true;
    }
    let largest = max(max(abs(d.x), abs(d.y)), abs(d.z));
    let scale = max(max(max(abs(next.x), abs(next.y)), abs(next.z)), max(max(abs(y_start[i].x), abs(y_start[i].y)), abs(y_start[i].z)));
    if pinned[i] != 0u || params.max_move >= REAL_MAX || largest <= ROUNDOFF_MOVES * REAL_EPSILON * scale {
        return false;
    }
    // scaled, so that the length of a finite move does not overflow
    return largest > params.max_move || length(d / largest) > params.max_move / largest;
}

// The local step: y_next <- the projection of the free vertices out of every collider, in order,
// then the per-vertex measure for the convergence and divergence tests:
// moved_i = |y_i^{k+1} - y_i^k|, bad_i = y_i^{k+1} not finite or a runaway (the residual comes
// from jacobi).
@compute @workgroup_size(64)
fn project(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= params.n || !live() {
        return;
    }
    let next = feasible(i, y[i].xyz, false, y_next[i].xyz);
    y_next[i] = vec4<real>(next, 0.0);
    let ok = finite3(next);
    var moved: real = 0.0;
    if ok {
        moved = length(next - y[i].xyz);
    }
    measure[i].moved = moved;
    measure[i].bad = select(1u, 0u, ok && !runaway(i, next));
}
