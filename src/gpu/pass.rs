//! The kernels of one step recorded into a compute pass, in the order of the CPU solver's
//! phases.

use super::layout;
use super::pipelines::Pipelines;

/// `Iter` records: the two candidates of the initial guess, the energy after the loop, then
/// one per iteration.
pub(super) const RECORD_PREVIOUS: usize = 0;
pub(super) const RECORD_PREDICTION: usize = 1;
pub(super) const RECORD_FINAL: usize = 2;
pub(super) const RECORD_FIRST_ITERATION: usize = 3;

/// A compute pass recording the kernels of a step.
pub(super) struct Pass<'a> {
    pub(super) pass: wgpu::ComputePass<'a>,
    pub(super) pipelines: &'a Pipelines,
    pub(super) bind_group: &'a wgpu::BindGroup,
    pub(super) vertex_groups: u32,
    pub(super) reduce_groups: u32,
}

impl Pass<'_> {
    pub(super) fn run(&mut self, pipeline: &wgpu::ComputePipeline, record: usize, groups: u32) {
        self.pass.set_pipeline(pipeline);
        let offset = (record as u64 * layout::ITER_STRIDE) as u32;
        self.pass.set_bind_group(0, self.bind_group, &[offset]);
        self.pass.dispatch_workgroups(groups, 1, 1);
    }

    pub(super) fn per_vertex(
        &mut self,
        pipeline: fn(&Pipelines) -> &wgpu::ComputePipeline,
        record: usize,
    ) {
        let p = pipeline(self.pipelines);
        self.run(p, record, self.vertex_groups);
    }

    /// The variational energy of `y` into the history slot of `record` (after the kernel
    /// when `evaluate`).
    pub(super) fn energy(&mut self, record: usize, evaluate: bool) {
        if evaluate {
            self.per_vertex(|p| &p.evaluate, record);
        }
        let p = self.pipelines;
        self.run(&p.reduce_energy, record, self.reduce_groups);
        self.run(&p.finish_energy, record, 1);
    }

    /// `y* = y_t + h v + h^2 g`, then the lower-energy of `y_t` and `y*` as first iterate,
    /// evaluated.
    pub(super) fn initial_guess(&mut self) {
        self.per_vertex(|p| &p.predict, RECORD_PREVIOUS);
        self.per_vertex(|p| &p.use_previous, RECORD_PREVIOUS);
        self.energy(RECORD_PREVIOUS, true);
        self.per_vertex(|p| &p.use_prediction, RECORD_PREDICTION);
        self.energy(RECORD_PREDICTION, true);
        self.per_vertex(|p| &p.choose_initial, RECORD_PREDICTION);
        self.per_vertex(|p| &p.evaluate, RECORD_PREDICTION);
    }

    /// Global iteration `k`: kernel (k > 0), energy, Jacobi update, colliders, convergence
    /// measure, commit.
    pub(super) fn iteration(&mut self, k: usize, record_energy: bool) {
        let record = RECORD_FIRST_ITERATION + k;
        if k > 0 {
            self.per_vertex(|p| &p.evaluate, record);
            if record_energy {
                self.energy(record, false);
            }
        }
        self.per_vertex(|p| &p.jacobi, record);
        self.per_vertex(|p| &p.project, record);
        let p = self.pipelines;
        self.run(&p.reduce_measure, record, self.reduce_groups);
        self.run(&p.finish_measure, record, 1);
        self.per_vertex(|p| &p.commit, record);
    }

    /// `v = (y - y_t) / h`, `y_t <- y`.
    pub(super) fn finish(&mut self) {
        self.per_vertex(|p| &p.finish, RECORD_PREVIOUS);
    }
}
