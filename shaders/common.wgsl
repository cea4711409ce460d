// Shared declarations of every peridyn compute kernel: the buffer layout and small helpers.
// The shader module is this file followed by the other files of shaders/ (see src/gpu/pipelines.rs),
// so every entry point sees the same bind group. SI units throughout. `real` is f32 or f64,
// declared by real_f32.wgsl or real_f64.wgsl, which the host puts first.
//
// Vertex-major struct-of-arrays: positions are vec4 (xyz, w unused) so that a vertex is one
// 16-byte load; bonds follow the CSR of the neighbourhood (`offsets`, `indices`), and
// `reverse[b]` is the bond j -> i of the bond b = i -> j.

struct Params {
    gravity: vec3<real>,     // m/s^2
    h: real,                 // time step (s)
    n: u32,                 // vertices
    n_colliders: u32,
    step_length: u32,       // 1: per-vertex step length of eq. 31-33
    preconditioner: u32,    // 0: tangent bound, 1: the paper's split
    tol: real,               // convergence threshold on max |r_i| / m_i (m); 0: never
    min_stretch: real,       // smallest principal stretch the material sees
    groups: u32,            // workgroups of the first reduction stage
    accelerated: u32,       // 1: Chebyshev acceleration keeps y_prev
    max_move: real,          // max_speed h: the farthest a free vertex may move in a step (m);
                             // REAL_MAX when unchecked (a finite sentinel: WGSL need not honour inf)
}

// One record per dispatch group, selected by a dynamic offset: which iteration the commands
// belong to (commands of iterations at or after `ctrl.limit` do nothing) and where a
// reduction writes its result (`ctrl.history[slot][lane]`).
struct Iter {
    iteration: u32,
    slot: u32,
    lane: u32,
    extrapolate: u32,       // 1: Chebyshev extrapolation with weight omega this iteration
    omega: real,
}

struct Vertex {
    t1: vec3<real>,          // rest frame: tangent plane t1, t2 and director nc
    volume: real,            // V_i (m^3)
    t2: vec3<real>,
    mass: real,              // m_i (kg)
    nc: vec3<real>,
    half_thickness: real,    // colliders keep the mid-surface this far (m)
    k_iso: real,             // 2 / sum_j |xi_j|^2 (1/m^2)
    k_bound: real,           // lambda_max(sum_j beta_j beta_j^T) (1/m^2)
    kappa_t: real,           // hourglass stiffness (N/m)
    kappa_n: real,           // bending bound lambda_max(sum_j c_j c_j^T) (N/m)
    s0: real,                // material constants (Pa)
    s1: real,
    model: u32,             // 0: StretchA3, 1: NeoHookean
    pad: u32,
}

struct Bond {
    xi: vec3<real>,          // rest bond x_j - x_i (m)
    beta1: real,             // a_k = sum_j beta_jk (y_j - y_i) (1/m)
    curvature: vec3<real>,   // least-squares curvature column c_j (sqrt(J)/m)
    beta2: real,
}

// Response of the vertex kernel: preconditioner block C_i (N/m) and energy E_i (J).
struct Response {
    c_diag: vec3<real>,      // C_00, C_11, C_22
    energy: real,
    c_off: vec3<real>,       // C_01, C_02, C_12
    pad: real,
}

// A collider during one step (src/contact/collider.rs, ColliderModel): its shape at time 0,
// translated by `offset` at the end of the step.
struct Collider {
    a: vec3<real>,           // plane: unit normal; sphere, box: centre; capsule: end a (m)
    b: real,                 // plane: offset normal . point (m); sphere, capsule: radius (m)
    c: vec3<real>,           // box: half extents (m); capsule: end b (m)
    friction: real,          // Coulomb coefficient (1)
    axes: mat3x3<real>,      // box: rotation, its columns the box's axes
    offset: vec3<real>,      // translation from the pose of time 0 at the end of the step (m)
    kind: u32,              // 0: plane, 1: sphere, 2: box, 3: capsule
    displacement: vec3<real>, // translation during the step (m)
}

// Per-vertex outcome of one iteration, reduced by reduce.wgsl.
struct Measure {
    residual: real,          // |r_i| / m_i without contact reactions (m)
    moved: real,             // |y_i^{k+1} - y_i^k| (m)
    bad: u32,               // 1: y_i^{k+1} or its velocity not finite, or a free vertex's move
                            // from y_t longer than max_move (src/solve/points.rs, first_bad_velocity)
    pad: u32,
}

struct Partial {
    residual: real,
    moved: real,
    first_bad: u32,
    energy: real,
}

// Read back by the host every few iterations (the header) and once per step (the history).
// history[0] = (E at y_t, E at y*, -, -); history[1 + k] = (moved_k, residual_k, E(y^k), -).
struct Control {
    limit: u32,             // first iteration that must not run (converged or diverged)
    bad_vertex: u32,
    bad_iteration: u32,
    pad: u32,
    history: array<vec4<real>>,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<uniform> iter: Iter;
@group(0) @binding(2) var<storage, read> vertices: array<Vertex>;
@group(0) @binding(3) var<storage, read> bonds: array<Bond>;
@group(0) @binding(4) var<storage, read> offsets: array<u32>;
@group(0) @binding(5) var<storage, read> indices: array<u32>;
@group(0) @binding(6) var<storage, read> reverse: array<u32>;
@group(0) @binding(7) var<storage, read> colliders: array<Collider>;
@group(0) @binding(8) var<storage, read> pinned: array<u32>;
@group(0) @binding(9) var<storage, read_write> y_start: array<vec4<real>>;
@group(0) @binding(10) var<storage, read_write> velocity: array<vec4<real>>;
@group(0) @binding(11) var<storage, read_write> y_star: array<vec4<real>>;
@group(0) @binding(12) var<storage, read_write> y: array<vec4<real>>;
@group(0) @binding(13) var<storage, read_write> y_next: array<vec4<real>>;
@group(0) @binding(14) var<storage, read_write> y_prev: array<vec4<real>>;
@group(0) @binding(15) var<storage, read_write> bond_grad: array<vec4<real>>;
@group(0) @binding(16) var<storage, read_write> response: array<Response>;
@group(0) @binding(17) var<storage, read_write> measure: array<Measure>;
@group(0) @binding(18) var<storage, read_write> partials: array<Partial>;
@group(0) @binding(19) var<storage, read_write> ctrl: Control;

const VERTEX_GROUP: u32 = 64u;
const REDUCE_GROUP: u32 = 256u;
const NONE: u32 = 0xffffffffu;

// False once the iteration of the current commands is at or past the stopping point.
fn live() -> bool {
    return iter.iteration < ctrl.limit;
}

// Finite test (NaN fails every comparison; no fast-math here).
fn finite3(v: vec3<real>) -> bool {
    return all(abs(v) <= vec3<real>(REAL_MAX));
}

fn outer(a: vec3<real>, b: vec3<real>) -> mat3x3<real> {
    return mat3x3<real>(a * b.x, a * b.y, a * b.z);
}

fn precond_of(k: u32) -> mat3x3<real> {
    let r = response[k];
    return mat3x3<real>(
        vec3<real>(r.c_diag.x, r.c_off.x, r.c_off.y),
        vec3<real>(r.c_off.x, r.c_diag.y, r.c_off.z),
        vec3<real>(r.c_off.y, r.c_off.z, r.c_diag.z),
    );
}
