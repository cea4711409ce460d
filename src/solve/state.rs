//! What a solver carries from one step to the next that changes results: the state a saved
//! simulation must hold, besides its bodies, clock and colliders' motion, to continue bit for
//! bit.

use nalgebra::Vector3;

use crate::contact::SavedRestGaps;
use crate::error::{invalid, Result};

/// What a solver carries from one step to the next, besides its bodies' state, its clock and
/// its colliders' motion, that changes the results of the steps to come: with those, all a
/// saved simulation needs to continue bit for bit in a solver set up the same way (same
/// bodies in the same order, parameters and colliders). Everything else the solver keeps
/// between steps is a cache (the families' working sets, the contact pairs and their index, the
/// Chebyshev history, the descent method's working set): results do not depend on it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SolverState {
    /// Per membrane vertex (the membranes in the order of the body list, each in its vertex
    /// order), the warm start of the first contact local step of the next step
    /// ([`crate::contact::ContactParams::warm_start`], m): the last local step's move where
    /// the barrier pushed. Empty: none (no contact yet, or contact off).
    pub contact_warm_start: Vec<Vector3<f64>>,
    /// The rest gaps of the membrane contact pairs that started within the barrier's reach
    /// (`src/contact/local_step/rest_gaps.rs`), their vertices numbered as the warm start's.
    /// `None`: not seeded yet (no contact step yet, or contact off): the next contact step
    /// seeds them from its start positions.
    pub contact_rest_gaps: Option<SavedRestGaps>,
    /// The accepted friction multipliers of the grains' contacts at the end of the last step
    /// ([`SavedGrainContact`]), each touching pair in both orders, the pairs `(i, j)` distinct;
    /// empty: none (the next step starts every contact's friction from 0).
    pub grain_contacts: Vec<SavedGrainContact>,
}

/// One ordered pair of touching grains and its accepted contact friction multiplier
/// `lambda_ij` (m; `src/solve/particles/grain_friction.rs`), which warm-starts the pair's
/// friction in the next step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SavedGrainContact {
    /// The pair's particles `(i, j)`, in the solver's global numbering of the particle bodies'
    /// particles (the particle bodies in the order of the body list, each in its own order).
    pub particles: [u32; 2],
    /// The multiplier `lambda_ij` (m), which moves `i` along it and `j` against it.
    pub multiplier: Vector3<f64>,
}

impl SolverState {
    /// Checks the values that do not depend on the bodies: finite warm start moves, finite
    /// positive rest gaps and reach.
    pub fn validate(&self) -> Result<()> {
        if let Some(i) = self
            .contact_warm_start
            .iter()
            .position(|w| !w.iter().all(|c| c.is_finite()))
        {
            return Err(invalid!(
                "the contact warm start of vertex {i} is not finite: {:?}",
                self.contact_warm_start[i]
            ));
        }
        if let Some(saved) = &self.contact_rest_gaps {
            if !(saved.reach.is_finite() && saved.reach > 0.0) {
                return Err(invalid!(
                    "the contact rest gaps' reach must be finite and > 0 m, got {}",
                    saved.reach
                ));
            }
            for (g, gap) in saved.gaps.iter().enumerate() {
                if !(gap.distance.is_finite() && gap.distance > 0.0) {
                    return Err(invalid!(
                        "contact rest gap {g} must be finite and > 0 m, got {}",
                        gap.distance
                    ));
                }
                let v = gap.vertices;
                if (0..4).any(|a| (a + 1..4).any(|b| v[a] == v[b])) {
                    return Err(invalid!(
                        "contact rest gap {g} must join four distinct vertices, got {v:?}"
                    ));
                }
            }
        }
        let mut pairs = Vec::with_capacity(self.grain_contacts.len());
        for (k, contact) in self.grain_contacts.iter().enumerate() {
            let [i, j] = contact.particles;
            if i == j {
                return Err(invalid!(
                    "grain contact {k} joins particle {i} to itself: a contact joins two"
                ));
            }
            if !contact.multiplier.iter().all(|c| c.is_finite()) {
                return Err(invalid!(
                    "the friction multiplier of grain contact {k} ({i}, {j}) is not finite: {:?}",
                    contact.multiplier
                ));
            }
            pairs.push(((i, j), k));
        }
        pairs.sort_unstable();
        if let Some(w) = pairs.windows(2).find(|w| w[0].0 == w[1].0) {
            let ((i, j), (a, b)) = (w[0].0, (w[0].1.min(w[1].1), w[0].1.max(w[1].1)));
            return Err(invalid!(
                "grain contacts {a} and {b} both join particles ({i}, {j}): a pair is saved once"
            ));
        }
        Ok(())
    }

    /// Checks the state against a body list whose membranes have `vertices` vertices in all
    /// and whose particle bodies have `particles` particles: a warm start for each vertex or
    /// none, rest gaps between the vertices, grain contacts between the particles.
    pub fn check_against(&self, vertices: usize, particles: usize) -> Result<()> {
        if let Some((k, contact)) = self
            .grain_contacts
            .iter()
            .enumerate()
            .find(|(_, c)| c.particles.iter().any(|&i| i as usize >= particles))
        {
            return Err(invalid!(
                "grain contact {k} joins particles {:?}, but the particle bodies have {particles}",
                contact.particles
            ));
        }
        let warm = self.contact_warm_start.len();
        if warm != 0 && warm != vertices {
            return Err(invalid!(
                "the restored contact warm start holds {warm} vertices, the membranes {vertices}"
            ));
        }
        let gaps = self.contact_rest_gaps.as_ref().map_or(&[][..], |s| &s.gaps);
        if let Some((g, gap)) = gaps
            .iter()
            .enumerate()
            .find(|(_, gap)| gap.vertices.iter().any(|&v| v as usize >= vertices))
        {
            return Err(invalid!(
                "contact rest gap {g} joins vertices {:?}, but the membranes have {vertices}",
                gap.vertices
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::SavedRestGap;

    fn with_gap(vertices: [u32; 4], distance: f64, reach: f64) -> SolverState {
        SolverState {
            contact_warm_start: vec![Vector3::zeros(); 8],
            contact_rest_gaps: Some(SavedRestGaps {
                reach,
                gaps: vec![SavedRestGap {
                    edge_edge: false,
                    vertices,
                    distance,
                }],
            }),
            grain_contacts: Vec::new(),
        }
    }

    /// A state is refused, naming the culprit, for non-finite moves, a bad reach or gap, a
    /// pair that repeats a vertex, and counts or indices that do not fit the membranes.
    #[test]
    fn bad_saved_states_are_refused_with_the_culprit() {
        assert!(with_gap([0, 1, 2, 3], 1e-3, 5e-3).validate().is_ok());
        let mut nan = with_gap([0, 1, 2, 3], 1e-3, 5e-3);
        nan.contact_warm_start[5].y = f64::NAN;
        let message = |s: &SolverState| s.validate().unwrap_err().to_string();
        assert!(message(&nan).contains("vertex 5"));
        assert!(message(&with_gap([0, 1, 2, 3], 1e-3, 0.0)).contains("reach"));
        assert!(message(&with_gap([0, 1, 2, 3], f64::INFINITY, 5e-3)).contains("gap 0"));
        assert!(message(&with_gap([0, 1, 2, 1], 1e-3, 5e-3)).contains("distinct"));
        let state = with_gap([0, 1, 2, 9], 1e-3, 5e-3);
        assert!(state.validate().is_ok());
        let against = |s: &SolverState, n| s.check_against(n, 0).unwrap_err().to_string();
        assert!(against(&state, 8).contains("[0, 1, 2, 9]"));
        assert!(against(&with_gap([0, 1, 2, 3], 1e-3, 5e-3), 9).contains("holds 8 vertices"));
        assert!(with_gap([0, 1, 2, 3], 1e-3, 5e-3)
            .check_against(8, 0)
            .is_ok());
    }

    fn with_contacts(pairs: &[[u32; 2]]) -> SolverState {
        SolverState {
            grain_contacts: pairs
                .iter()
                .map(|&particles| SavedGrainContact {
                    particles,
                    multiplier: Vector3::new(1e-6, 0.0, 0.0),
                })
                .collect(),
            ..SolverState::default()
        }
    }

    /// Grain contacts are refused, naming the culprit, for a particle joined to itself, a
    /// pair saved twice, a non-finite multiplier and a particle beyond the bodies'.
    #[test]
    fn bad_grain_contacts_are_refused_with_the_culprit() {
        let message = |s: &SolverState| s.validate().unwrap_err().to_string();
        assert!(with_contacts(&[[0, 1], [1, 0]]).validate().is_ok());
        assert!(message(&with_contacts(&[[0, 1], [2, 2]])).contains("contact 1 joins particle 2"));
        assert!(message(&with_contacts(&[[0, 1], [1, 0], [0, 1]])).contains("contacts 0 and 2"));
        let mut nan = with_contacts(&[[0, 1], [3, 4]]);
        nan.grain_contacts[1].multiplier.z = f64::NAN;
        assert!(message(&nan).contains("grain contact 1 (3, 4)"));
        let state = with_contacts(&[[0, 1], [1, 5]]);
        assert!(state.check_against(0, 6).is_ok());
        let refused = state.check_against(0, 5).unwrap_err().to_string();
        assert!(refused.contains("grain contact 1 joins particles [1, 5]"));
    }
}
