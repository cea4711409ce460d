//! The local step's buffers, kept between calls so that a local step at the scene's size
//! allocates nothing.

use nalgebra::Vector3;

use super::super::barrier_push::BarrierPush;
use super::super::broad_phase::ContactMesh;
use super::live_pairs::LivePairs;
use super::rest_gaps::SavedRestGaps;
use crate::geometry::distance::Closest;
use crate::symmetric::SymmetricMatrix3;

/// The local step's buffers, owned by the caller and kept between calls (one per body list):
/// once they have grown to the scene's size, a local step allocates nothing.
#[derive(Default)]
pub struct Workspace {
    pub(super) live: LivePairs,
    /// `y^k`, the target of the proximal term.
    pub(super) target: Vec<Vector3<f64>>,
    /// Per vertex: total distance moved by the descent (m).
    pub(super) drift: Vec<f64>,
    /// Per vertex: `sum_c |alpha_c^i|` of eq. 53.
    pub(super) alpha: Vec<f64>,
    /// Per vertex: the barrier curvature `K_i` of [`super::DescentStep::Curvature`].
    pub(super) curvature: Vec<SymmetricMatrix3<f64>>,
    /// Per vertex: moved since the last CCD.
    pub(super) changed: Vec<bool>,
    /// Per vertex: moved since its pairs' closest points were last evaluated.
    pub(super) unmeasured: Vec<bool>,
    /// Per pair: its closest points were evaluated afresh at the last evaluation.
    pub(super) fresh: Vec<bool>,
    /// Per vertex: smallest time of impact.
    pub(super) vertex_toi: Vec<f64>,
    /// Per vertex: clamped by the final guarantee pass.
    pub(super) clamped: Vec<bool>,
    /// Per pair: time of impact.
    pub(super) toi: Vec<Option<f64>>,
    /// Per pair: within `(1 + 4 eps) xi` at the last distance evaluation.
    pub(super) near: Vec<bool>,
    /// Per pair: closest points.
    pub(super) closest: Vec<Closest>,
    /// Per pair: separation floor of the guarantee pass (m), 0 where it needs no CCD.
    pub(super) floors: Vec<f64>,
    /// Per vertex: `|y_i^k - z_i^{k-1}|` (m), how far the global step took it from safety.
    pub(super) motion: Vec<f64>,
    /// Per vertex: the barrier push of eq. 49 at the current iterate (m), at the returned
    /// positions once [`super::resolve_contacts`] returns (see [`Workspace::push`]).
    pub(super) push: Vec<Vector3<f64>>,
    /// Per vertex: the warm start of the next local step ([`super::ContactParams::warm_start`]), m.
    pub(super) warm: Vec<Vector3<f64>>,
    /// Per vertex: the last descent move of this local step that it took (m).
    pub(super) last_move: Vec<Vector3<f64>>,
    /// Per vertex: the factor on its descent moves, halved at each reversal (see
    /// [`super::resolve_contacts`]).
    pub(super) damping: Vec<f64>,
    /// The barrier's terms per pair and their sums per vertex, kept between iterations.
    pub(super) barrier_push: BarrierPush,
    /// Per vertex: the metric `W_i` of the last [`super::resolve_contacts`]
    /// ([`super::ProximalWeights`]).
    pub(super) weights: Vec<SymmetricMatrix3<f64>>,
    /// Per vertex: its position at the start of the time step (m), for friction.
    pub(super) step_start: Vec<Vector3<f64>>,
    /// Per vertex: its body's friction coefficient; empty where every body is frictionless.
    pub(super) friction: Vec<f64>,
    /// Per vertex: the friction move of the last [`super::resolve_contacts`] (m; see
    /// `friction.rs`), empty where none moved.
    pub(super) friction_move: Vec<Vector3<f64>>,
}

impl Workspace {
    /// At the start of a time step, with the start positions `y_t` (m): arms the rest gaps
    /// of the pairs within the barrier's reach on the first call, ratchets them on later ones
    /// (see `rest_gaps.rs`; the start is taken as the rest gap, so it holds no barrier energy).
    /// `friction` holds each vertex's friction coefficient against membranes (see
    /// `friction.rs`): where one is positive, the local steps of the time step apply
    /// Coulomb friction to the slips since `start`.
    pub fn start_step(&mut self, start: &[Vector3<f64>], friction: &[f64]) {
        self.live.gaps.start_step(start);
        self.friction.clear();
        self.step_start.clear();
        if friction.iter().any(|&mu| mu > 0.0) {
            self.friction.extend_from_slice(friction);
            self.step_start.extend_from_slice(start);
        }
    }

    /// Per vertex, the friction move the last [`super::resolve_contacts`] made (m; empty where
    /// none moved): a contact reaction like the barrier's push.
    pub fn friction_move(&self) -> &[Vector3<f64>] {
        &self.friction_move
    }

    /// Per vertex, the barrier push `p_i = -mu sum_c m_c B'(f(d_c) - xi) alpha_c^i n_c` (m) of eq.
    /// 49 at the positions the last [`super::resolve_contacts`] returned: where the descent has
    /// converged, `W_i (z_i - y_i^k) = p_i`, so `W_i^-1 p_i` is the displacement by which contact
    /// holds each vertex back from the global step's target (zero away from contact; empty before
    /// any call).
    pub fn push(&self) -> &[Vector3<f64>] {
        &self.push
    }

    /// Per vertex, the metric `W_i` the last [`super::resolve_contacts`] used (`None`: the
    /// identity, or no pair was within reach and nothing moved).
    pub fn weights(&self) -> Option<&[SymmetricMatrix3<f64>]> {
        (!self.weights.is_empty()).then_some(&self.weights[..])
    }

    /// Per vertex, the warm start the next [`super::resolve_contacts`] takes
    /// ([`super::ContactParams::warm_start`], m; empty: none). Unlike the rest of the
    /// workspace it changes the next local step's result: a saved simulation keeps it.
    pub fn warm_start(&self) -> &[Vector3<f64>] {
        &self.warm
    }

    /// Replaces the warm start (see [`Workspace::warm_start`]; empty: none).
    pub fn set_warm_start(&mut self, warm: &[Vector3<f64>]) {
        self.warm.clear();
        self.warm.extend_from_slice(warm);
    }

    /// The rest gaps of the pairs that started within the barrier's reach (see
    /// `rest_gaps.rs`; `None` before the first local step seeds them). Like the warm start they
    /// change the results of the steps to come: a saved simulation keeps them.
    pub fn rest_gaps(&self) -> Option<SavedRestGaps> {
        self.live.gaps.saved()
    }

    /// Replaces the rest gaps by saved ones (see [`Workspace::rest_gaps`]) for the triangles of
    /// `mesh`; every vertex of a saved pair must be one of `mesh`'s.
    pub fn set_rest_gaps(&mut self, saved: &SavedRestGaps, mesh: &ContactMesh) {
        self.live.gaps.restore(saved, mesh);
    }
}

/// A piece of the state a [`Workspace`] carries from one local step to the next (and from one
/// time step to the next), for the tests that tell the caches from the state that results
/// depend on ([`Workspace::forget`]).
#[cfg(test)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Piece {
    /// The warm start of the next local step ([`super::ContactParams::warm_start`]).
    WarmStart,
    /// The live pairs and the positions they were filtered for: the next local step filters
    /// afresh (from the cached pairs, with the carried allowances).
    LiveList,
    /// The live pairs and the deviations the next local step's allowances are carried from.
    Allowances,
    /// The cached pairs, and with them the live ones: the next local step builds afresh (the
    /// rest gaps kept).
    PairCache,
    /// The barrier's terms and their index by vertex.
    BarrierIndex,
}

#[cfg(test)]
impl Workspace {
    /// Drops `piece` as if this workspace had never held it.
    pub fn forget(&mut self, piece: Piece) {
        match piece {
            Piece::WarmStart => self.warm.clear(),
            Piece::LiveList => self.live.filtered_safe.clear(),
            Piece::Allowances => {
                self.live.filtered_safe.clear();
                self.live.deviation.clear();
            }
            Piece::PairCache => {
                // The version keeps counting, so that no index is taken for the new list; the
                // rest gaps are state, not cache, and stay.
                let version = self.live.version + 1;
                let gaps = std::mem::take(&mut self.live.gaps);
                self.live = LivePairs::default();
                self.live.version = version;
                self.live.gaps = gaps;
            }
            Piece::BarrierIndex => self.barrier_push = BarrierPush::default(),
        }
    }
}
