//! Cost of one time step of the CPU solver on a pinned, hanging cloth, by precision.
//!
//! `cargo bench --bench step_cost -- [n] [iterations] [steps] [threads] [f32|f64]` prints a
//! JSON record: median milliseconds per step and per phase for an n x n cloth (default 120,
//! 14.4K vertices) with exactly `iterations` global iterations per step (tol = 0), no contact,
//! on `threads` workers (default: one per core), in both precisions or the one named. With one thread the whole step runs on the pool's single
//! worker, which suits instruction counting (`valgrind --tool=callgrind`; valgrind does not decode
//! AVX-512, so build for it with `RUSTFLAGS="-C target-cpu=x86-64-v3"` on a CPU that has it,
//! since this tree builds for the native CPU by default, see `.cargo/config.toml`).

use std::time::Instant;

use peridyn::material::Material;
use peridyn::membrane::{Membrane, MembraneParams};
use peridyn::mesh::TriangleMesh;
use peridyn::real::Real;
use peridyn::solve::{Solver, SolverParams, StepStats};

fn cloth(n: usize) -> Membrane {
    let params = MembraneParams {
        thickness: 1e-3,
        density: 300.0,
        material: Material::stretch_a3(2e4).unwrap(),
        bending: 1e-6,
        hourglass: MembraneParams::DEFAULT_HOURGLASS,
        neighbors: 1,
    };
    let mut body = Membrane::new(TriangleMesh::grid(n, n, 1.0, 1.0).unwrap(), params).unwrap();
    let top: Vec<i64> = ((n * (n - 1))..(n * n)).map(|i| i as i64).collect();
    body.pin(&top, None).unwrap();
    body
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

fn run<T: Real>(n: usize, iterations: usize, steps: usize, threads: Option<usize>) -> String {
    let mut body = cloth(n);
    let params = SolverParams {
        dt: 1e-3,
        tol: 0.0,
        max_iters: iterations,
        ..SolverParams::default()
    };
    let mut solver = Solver::<T>::new(params, threads).unwrap();
    solver.step(&mut [(&mut body).into()]).unwrap();
    let mut all: Vec<StepStats> = Vec::new();
    let start = Instant::now();
    for _ in 0..steps {
        all.push(solver.step(&mut [(&mut body).into()]).unwrap());
    }
    let wall = start.elapsed().as_secs_f64() * 1e3 / steps as f64;
    let pick = |f: fn(&StepStats) -> f64| median(all.iter().map(f).collect());
    format!(
        "{{\"precision\": \"{}\", \"vertices\": {}, \"iterations\": {}, \"threads\": {}, \"ms_per_step\": {:.3}, \"ms_global\": {:.3}, \"ms_kernel\": {:.3}, \"ms_predict\": {:.3}, \"ms_finish\": {:.3}, \"ms_per_iteration\": {:.4}, \"wall_ms_per_step_mean\": {:.3}}}",
        T::NAME,
        n * n,
        iterations,
        solver.threads(),
        pick(|s| s.timings.total),
        pick(|s| s.timings.global),
        pick(|s| s.timings.kernel),
        pick(|s| s.timings.predict),
        pick(|s| s.timings.finish),
        pick(|s| s.timings.global) / iterations as f64,
        wall
    )
}

fn main() {
    let words: Vec<String> = std::env::args().skip(1).collect();
    let args: Vec<usize> = words.iter().filter_map(|a| a.parse().ok()).collect();
    let wanted = |name: &str| {
        let named = words.iter().any(|w| w == "f32" || w == "f64");
        !named || words.iter().any(|w| w == name)
    };
    let n = args.first().copied().unwrap_or(120);
    let iterations = args.get(1).copied().unwrap_or(10);
    let steps = args.get(2).copied().unwrap_or(30);
    let threads = args.get(3).copied();
    let mut records = Vec::new();
    if wanted(f32::NAME) {
        records.push(run::<f32>(n, iterations, steps, threads));
    }
    if wanted(f64::NAME) {
        records.push(run::<f64>(n, iterations, steps, threads));
    }
    println!("[{}]", records.join(",\n "));
}
