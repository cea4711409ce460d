// Reductions in two stages: a workgroup of REDUCE_GROUP threads folds its vertices into one
// Partial in shared memory, then a single workgroup folds the partials and writes the result
// into ctrl. Fixed tree order, so the result does not depend on timing.
//
// - the convergence measure (after an iteration): max_i |r_i| / m_i (m), max_i |y^{k+1} - y^k|
//   (m) and the first non-finite vertex; sets ctrl.limit when converged (residual < tol) or
//   diverged, which stops every later command of the step;
// - the variational energy E(y) = sum_i m_i |y_i - y*_i|^2 / (2 h^2) + E_i(y) (J) (eq. 2).

var<workgroup> scratch: array<Partial, REDUCE_GROUP>;
var<workgroup> running: u32;

// live(), made workgroup-uniform so that the barriers below are allowed.
fn workgroup_live(t: u32) -> bool {
    if t == 0u {
        running = select(0u, 1u, live());
    }
    return workgroupUniformLoad(&running) != 0u;
}

fn fold(a: Partial, b: Partial) -> Partial {
    return Partial(max(a.residual, b.residual), max(a.moved, b.moved), min(a.first_bad, b.first_bad), a.energy + b.energy);
}

fn fold_workgroup(t: u32) -> Partial {
    for (var stride = REDUCE_GROUP / 2u; stride > 0u; stride /= 2u) {
        workgroupBarrier();
        if t < stride {
            scratch[t] = fold(scratch[t], scratch[t + stride]);
        }
    }
    workgroupBarrier();
    return scratch[0];
}

const EMPTY: Partial = Partial(0.0, 0.0, NONE, 0.0);

// Stage 1 of the convergence measure.
@compute @workgroup_size(256)
fn reduce_measure(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    if !workgroup_live(lid.x) {
        return;
    }
    let i = wid.x * REDUCE_GROUP + lid.x;
    var mine = EMPTY;
    if i < params.n {
        let m = measure[i];
        mine = Partial(m.residual, m.moved, select(NONE, i, m.bad != 0u), 0.0);
    }
    scratch[lid.x] = mine;
    let total = fold_workgroup(lid.x);
    if lid.x == 0u {
        partials[wid.x] = total;
    }
}

// Stage 1 of the energy.
@compute @workgroup_size(256)
fn reduce_energy(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    if !workgroup_live(lid.x) {
        return;
    }
    let i = wid.x * REDUCE_GROUP + lid.x;
    var mine = EMPTY;
    if i < params.n {
        let d = y[i].xyz - y_star[i].xyz;
        let inertia = dot(d, d) * vertices[i].mass * (0.5 / (params.h * params.h));
        mine.energy = inertia + response[i].energy;
    }
    scratch[lid.x] = mine;
    let total = fold_workgroup(lid.x);
    if lid.x == 0u {
        partials[wid.x] = total;
    }
}

fn fold_partials(t: u32) -> Partial {
    var mine = EMPTY;
    for (var g = t; g < params.groups; g += REDUCE_GROUP) {
        mine = fold(mine, partials[g]);
    }
    scratch[t] = mine;
    return fold_workgroup(t);
}

// Stage 2 of the convergence measure, one workgroup: history[slot].xy and the stopping rule.
@compute @workgroup_size(256)
fn finish_measure(@builtin(local_invocation_id) lid: vec3<u32>) {
    if !workgroup_live(lid.x) {
        return;
    }
    let total = fold_partials(lid.x);
    if lid.x == 0u {
        ctrl.history[iter.slot].x = total.moved;
        ctrl.history[iter.slot].y = total.residual;
        if total.first_bad != NONE {
            ctrl.bad_vertex = total.first_bad;
            ctrl.bad_iteration = iter.iteration;
            ctrl.limit = iter.iteration;
        } else if params.tol > 0.0 && total.residual < params.tol {
            ctrl.limit = iter.iteration + 1u;
        }
    }
}

// Stage 2 of the energy, one workgroup: history[slot][lane].
@compute @workgroup_size(256)
fn finish_energy(@builtin(local_invocation_id) lid: vec3<u32>) {
    if !workgroup_live(lid.x) {
        return;
    }
    let total = fold_partials(lid.x);
    if lid.x == 0u {
        ctrl.history[iter.slot][iter.lane] = total.energy;
    }
}
