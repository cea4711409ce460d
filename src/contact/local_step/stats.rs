//! What one contact local step did: counts and times for the solver's step statistics.

/// What one local step did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ContactStats {
    /// Candidate triangle pairs of the broad phase's last build (see [`super::super::pair_cache`]).
    pub candidate_pairs: usize,
    /// Triangle pairs of that build whose inflated boxes overlap (before the distance test
    /// that leaves the candidates).
    pub box_pairs: usize,
    /// Primitive pairs of the broad phase's last build, with those repairs added since (the
    /// pairs each filter of the live list chooses from; largest).
    pub cached_pairs: usize,
    /// Primitive pairs that may come within the barrier's reach (the live pairs).
    pub primitive_pairs: usize,
    /// Primitive pair CCD queries (descent and guarantee pass).
    pub ccd_queries: usize,
    /// Broad phase builds (the others reused the last build's pairs).
    pub broad_phase_builds: usize,
    /// Repairs of the last build for a few vertices that strayed beyond their skins (see
    /// [`super::super::pair_cache`]), each instead of a build.
    pub cache_repairs: usize,
    /// Filterings of the cached pairs into the live list and additions to it (at the start of
    /// a local step unless the list is kept (`LivePairs::start`), and each time a vertex
    /// outgrows its allowance).
    pub live_refreshes: usize,
    /// Those of the filterings that were sweeps: each looked at every cached pair near
    /// enough afresh; the others looked again only at the pairs whose bound may have fallen
    /// below the reach since the last sweep (see [`super::super::sweep`]).
    pub sweeps: usize,
    /// Primitive pairs within the barrier's reach at the end (faded ones included).
    pub active_pairs: usize,
    /// Descent iterations.
    pub iterations: usize,
    /// The barrier term of eq. 47 at the end, `mu sum_c m_c s_c^2 B(f(d_c / s_c) - xi)` (m^2;
    /// `m_c` the fade, `s_c` the rest-gap scale).
    pub barrier: f64,
    /// The barrier's energy at the end (J): [`ContactStats::barrier`] times `d / h^2`, with
    /// `d` the mass scale of the proximal metric (kg; see [`super::ProximalMetric`]). Set
    /// by the solver.
    pub barrier_energy: f64,
    /// Vertices clamped by the final guarantee pass.
    pub clamped: usize,
    /// Milliseconds in the broad phase (with the live pairs' distances at the safe positions,
    /// which prune the CCD and the distances), the CCD and the descent (distances and
    /// updates).
    pub broad_phase_ms: f64,
    pub ccd_ms: f64,
    pub descent_ms: f64,
}

impl ContactStats {
    /// Sums the counts and times of two local steps (active pairs: the later one's; box,
    /// candidate, cached and primitive pairs: the larger).
    pub fn accumulate(&mut self, other: &ContactStats) {
        self.candidate_pairs = self.candidate_pairs.max(other.candidate_pairs);
        self.box_pairs = self.box_pairs.max(other.box_pairs);
        self.cached_pairs = self.cached_pairs.max(other.cached_pairs);
        self.primitive_pairs = self.primitive_pairs.max(other.primitive_pairs);
        self.ccd_queries += other.ccd_queries;
        self.broad_phase_builds += other.broad_phase_builds;
        self.cache_repairs += other.cache_repairs;
        self.live_refreshes += other.live_refreshes;
        self.sweeps += other.sweeps;
        self.active_pairs = other.active_pairs;
        self.barrier = other.barrier;
        self.barrier_energy = other.barrier_energy;
        self.iterations += other.iterations;
        self.clamped += other.clamped;
        self.broad_phase_ms += other.broad_phase_ms;
        self.ccd_ms += other.ccd_ms;
        self.descent_ms += other.descent_ms;
    }
}
