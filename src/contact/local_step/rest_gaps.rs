//! The rest gaps of pairs that start within the barrier's reach (not in the paper; the start
//! taken as the rest gap, as IPC does with its initial distances).
//!
//! The local step's barrier (eq. 47, 50-51) is an energy `d mu B / h^2` (J, see
//! [`super::ProximalMetric::Jacobi`]): a pair of primitives closer than the reach
//! `xi + d_hat` holds barrier energy, and implicit Euler turns it into motion within a step or
//! two. A scene that starts with primitives within the reach (a coarse or thick membrane whose
//! own non-adjacent primitives lie closer than the reach, layers stacked closer than it) then
//! starts with energy that no one put in, and the local step launches the layers apart at about
//! `d_hat / h`.
//!
//! So a pair within the reach `R` at the start, at distance `g < R` (m), gets the barrier
//! scaled to reach `g`: with `s = g / R` its energy is `s^2 B(f(d / s) - xi)` (m^2; eq. 3 and
//! 51 in lengths scaled by `s`), zero at `d >= g`, the same shape, curvature `B'' f'` at
//! `d / s`, and still rising steeply as the pair closes. The start then holds no barrier
//! energy, and nothing is launched. Between bodies, or between distant parts of one body, the
//! rest gap is ratcheted up at the start of every step to the pair's distance then (while it is
//! below `R`), so layers pulled apart get the full barrier back; each raise happens where the
//! pair's barrier is zero before and after, so it changes no energy. A body's own pairs keep
//! their start distance as their rest gap for good: the body's start is taken as its rest shape
//! (in-plane pairs of a flat sheet return there, and must feel nothing there).

use std::collections::HashMap;

use nalgebra::Vector3;

use super::super::broad_phase::ContactMesh;
use super::super::primitive_pairs::Pair;

/// A pair's rest gap as a saved simulation holds it (see [`RestGaps::saved`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SavedRestGap {
    /// An edge-edge pair (`vertices`: the two ends of one edge, then of the other), or a
    /// point-triangle pair (the point, then the triangle's corners).
    pub edge_edge: bool,
    /// The pair's vertices, in the solver's global numbering of the membranes' vertices.
    pub vertices: [u32; 4],
    /// The distance (m) at which its barrier starts.
    pub distance: f64,
}

/// The rest gaps as a saved simulation holds them: what a solver needs to continue with the
/// same barriers (see [`RestGaps::saved`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SavedRestGaps {
    /// The reach `R` (m) of the last local step, by which the gaps are scaled.
    pub reach: f64,
    /// The gaps, in the order of their pairs (sorted, so a save is the same for the same gaps).
    pub gaps: Vec<SavedRestGap>,
}

/// A pair's rest gap.
#[derive(Debug, Clone, Copy)]
struct Gap {
    /// The distance (m) at which its barrier starts.
    distance: f64,
    /// Both primitives belong to one body: kept for good, never ratcheted.
    own: bool,
}

/// The rest gaps of the pairs that started within the barrier's reach, keyed by the pair's
/// vertices in a canonical order.
#[derive(Debug, Default)]
pub(super) struct RestGaps {
    gaps: HashMap<Pair, Gap>,
    /// The reach `R` (m) of the last local step: a gap's scale is `g / R`.
    reach: f64,
    /// Set by the first [`RestGaps::start_step`]: the next local step seeds the gaps.
    pending: bool,
    /// Seeded: later steps ratchet.
    seeded: bool,
    /// The gaps or the reach changed since the last [`RestGaps::take_changed`].
    changed: bool,
}

/// The pair with each primitive's vertices sorted and, for edge-edge pairs, the edges in
/// order: the same key however a build expanded it.
fn canonical(p: &Pair) -> Pair {
    let mut v = p.v;
    if p.edge_edge {
        v[..2].sort_unstable();
        v[2..].sort_unstable();
        if v[2..] < v[..2] {
            v = [v[2], v[3], v[0], v[1]];
        }
    } else {
        v[1..].sort_unstable();
    }
    Pair {
        edge_edge: p.edge_edge,
        v,
    }
}

/// Per vertex of `mesh`'s triangles, the index of its body.
fn body_of_vertices(mesh: &ContactMesh) -> Vec<u32> {
    let mut body_of = Vec::new();
    for (t, &b) in mesh.triangles.iter().zip(mesh.body) {
        for &v in t {
            let v = v as usize;
            if body_of.len() <= v {
                body_of.resize(v + 1, u32::MAX);
            }
            body_of[v] = b;
        }
    }
    body_of
}

impl RestGaps {
    /// At the start of a time step, with the positions `y_t` (m): the first call arms the
    /// seeding by the next local step; later calls raise every gap between bodies to the
    /// pair's distance at `y_t`, dropping those that reach `R`.
    pub(super) fn start_step(&mut self, start: &[Vector3<f64>]) {
        if !self.seeded {
            self.pending = true;
            return;
        }
        let reach = self.reach;
        self.changed |= !self.gaps.is_empty();
        self.gaps.retain(|pair, gap| {
            if gap.own {
                return true;
            }
            gap.distance = gap.distance.max(pair.distance_and_fade(start, 0.0).0);
            gap.distance < reach
        });
    }

    /// Whether the next local step seeds the gaps.
    pub(super) fn pending(&self) -> bool {
        self.pending
    }

    /// Seeds the gaps from `pairs` and their `distances` (m) at the step's start: every pair
    /// closer than `reach` (m) gets its distance as its rest gap.
    pub(super) fn seed(
        &mut self,
        pairs: &[Pair],
        distances: &[f64],
        mesh: &ContactMesh,
        reach: f64,
    ) {
        self.pending = false;
        self.seeded = true;
        self.changed = true;
        self.reach = reach;
        let body_of = body_of_vertices(mesh);
        for (pair, &d) in pairs.iter().zip(distances) {
            if d < reach {
                let own = body_of[pair.v[0] as usize] == body_of[pair.v[2] as usize];
                // A zero start distance would scale the barrier away; a tiny one keeps its
                // shape at a scale below any separation the CCD keeps.
                let gap = Gap {
                    distance: d.max(f64::MIN_POSITIVE),
                    own,
                };
                self.gaps.insert(canonical(pair), gap);
            }
        }
    }

    /// The gaps to save with a simulation; `None` before they are seeded (a solver restored
    /// with `None` seeds them at its next step, as this one would).
    pub(super) fn saved(&self) -> Option<SavedRestGaps> {
        if !self.seeded {
            return None;
        }
        let mut gaps: Vec<SavedRestGap> = self
            .gaps
            .iter()
            .map(|(pair, gap)| SavedRestGap {
                edge_edge: pair.edge_edge,
                vertices: pair.v,
                distance: gap.distance,
            })
            .collect();
        gaps.sort_unstable_by_key(|g| (g.edge_edge, g.vertices));
        Some(SavedRestGaps {
            reach: self.reach,
            gaps,
        })
    }

    /// Replaces the gaps by saved ones, as seeded, for the triangles of `mesh` (whose bodies
    /// tell a body's own pairs, kept for good, from the pairs between bodies). Every vertex of a
    /// saved pair must be a vertex of `mesh`.
    pub(super) fn restore(&mut self, saved: &SavedRestGaps, mesh: &ContactMesh) {
        let body_of = body_of_vertices(mesh);
        self.gaps.clear();
        for gap in &saved.gaps {
            let pair = canonical(&Pair {
                edge_edge: gap.edge_edge,
                v: gap.vertices,
            });
            let body = |v: u32| body_of.get(v as usize).copied();
            let own = body(pair.v[0]) == body(pair.v[2]);
            let distance = gap.distance;
            self.gaps.insert(pair, Gap { distance, own });
        }
        self.reach = saved.reach;
        self.pending = false;
        self.seeded = true;
        self.changed = true;
    }

    /// Notes the reach `R` (m) of this local step.
    pub(super) fn set_reach(&mut self, reach: f64) {
        self.changed |= reach != self.reach && !self.gaps.is_empty();
        self.reach = reach;
    }

    /// Whether the scales changed since the last call (they must then be taken again).
    pub(super) fn take_changed(&mut self) -> bool {
        std::mem::take(&mut self.changed)
    }

    /// No pair has a rest gap: every scale is 1.
    pub(super) fn is_empty(&self) -> bool {
        self.gaps.is_empty()
    }

    /// The scale `s = min(1, g / R)` of the pair's barrier (1 without a rest gap).
    pub(super) fn scale(&self, pair: &Pair) -> f64 {
        match self.gaps.get(&canonical(pair)) {
            Some(gap) => (gap.distance / self.reach).min(1.0),
            None => 1.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pair's key is the same in any vertex order, a gap between bodies rises with the
    /// pair's distance at each step's start and is dropped at the reach, and a body's own gap
    /// stays.
    #[test]
    fn rest_gaps_are_keyed_canonically_ratchet_between_bodies_and_stay_within_one() {
        // Two triangles 2 mm apart (body 0 and 1) and a third of body 0 beside the first.
        let triangles = [[0, 1, 2], [3, 4, 5], [6, 7, 8]];
        let body = [0, 1, 0];
        let mesh = ContactMesh {
            triangles: &triangles,
            body: &body,
            self_contact: &[true, true],
        };
        let mut x = vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, 1.0, 0.0),
        ];
        x.extend(x.clone().iter().map(|p| p + Vector3::new(0.0, 0.0, 2e-3)));
        x.extend([
            Vector3::new(0.0, 0.0, 3e-3),
            Vector3::new(1.0, 0.0, 3e-3),
            Vector3::new(0.0, 1.0, 3e-3),
        ]);
        let between = Pair {
            edge_edge: false,
            v: [3, 0, 1, 2],
        };
        let own = Pair {
            edge_edge: false,
            v: [6, 0, 1, 2],
        };
        let ee = Pair {
            edge_edge: true,
            v: [1, 0, 4, 3],
        };
        let reach = 5e-3;
        let mut gaps = RestGaps::default();
        gaps.start_step(&x);
        assert!(gaps.pending());
        let distances: Vec<f64> = [between, own, ee]
            .iter()
            .map(|p| p.distance_and_fade(&x, 0.0).0)
            .collect();
        gaps.seed(&[between, own, ee], &distances, &mesh, reach);
        assert!(gaps.take_changed() && !gaps.take_changed());
        let permuted = Pair {
            edge_edge: false,
            v: [3, 2, 0, 1],
        };
        assert!((gaps.scale(&permuted) - 0.4).abs() < 1e-12);
        assert!(
            (gaps.scale(&Pair {
                edge_edge: true,
                v: [3, 4, 0, 1]
            }) - 0.4)
                .abs()
                < 1e-12
        );
        assert!((gaps.scale(&own) - 0.6).abs() < 1e-12);
        // Apart by 4 mm, then 6 mm: the gaps between bodies follow, then go; body 0's stays.
        for (lift, scale) in [(2e-3, 0.8), (4e-3, 1.0)] {
            let mut y = x.clone();
            for p in &mut y[3..6] {
                p.z += lift;
            }
            for p in &mut y[6..9] {
                p.z += 2.0 * lift;
            }
            gaps.start_step(&y);
            assert!((gaps.scale(&between) - scale).abs() < 1e-12);
            assert!((gaps.scale(&own) - 0.6).abs() < 1e-12);
        }
        assert!(gaps.take_changed());
        // Closer again: no gap shrinks.
        gaps.start_step(&x);
        assert_eq!(gaps.scale(&between), 1.0);
    }
}
