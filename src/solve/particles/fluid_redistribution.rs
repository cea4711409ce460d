//! The redistribution of a fluid stage ([`super`], He et al. 2017, eq. 21-24, with
//! [`crate::particles::redistribution`] for the passes themselves), after the density
//! projection, and the density hold that keeps its moves a position correction.
//!
//! **Redistribution is a position correction only.** It evens the particles' spacing; it is
//! no force. Its displacement `s_i` (with the push out of colliders and the density hold that
//! follow it) is kept, and once `finish` has taken the velocities `(y - y_t) / h`, `s_i / h` is
//! subtracted from them: the velocity is the one the step took without it, the position keeps
//! it. Pinned members and partners neither move in it nor are pushed out of colliders (a
//! ghost below a floor stays there).
//!
//! **The redistribution held to the density constraints (beyond the paper).** Its moves
//! raise some particles' densities above what the projection left; the next step's projection
//! then pushes them apart again as velocity, and the moves become a force after all (a dam
//! break's `sum ||grad rho||^2` ended 4 % above the run without). So after it the density
//! constraints are projected again with each member's density bounded by its *ceiling*
//! `max(rho0_i, rho_i)`, `rho_i` its density before the redistribution: only what the
//! redistribution added is taken back, as part of the position correction, and the violation
//! the projection left (at its cap) stays for the next step as without redistribution.

use rayon::prelude::*;

use crate::collider::{push_out_of_colliders, ColliderModel, MoveStart};
use crate::error::Result;
use crate::particles::DensitySolver;
use crate::real::Real;
use crate::solve::points::Points;

use super::FluidStage;

impl<T: Real> FluidStage<T> {
    /// The redistribution passes on `self.y` over the step's neighbour lists (pinned members
    /// and partners fixed), the others out of the colliders from where each was, then held to
    /// the density constraints ([`Self::hold_densities`]); the displacement is kept in
    /// `self.shift` for [`Self::end_step`].
    pub(super) fn redistribute(
        &mut self,
        points: &Points<T>,
        colliders: &[ColliderModel<T>],
    ) -> Result<()> {
        self.fixed.clear();
        self.fixed.extend(
            (self.members.iter().zip(&self.partner)).map(|(&k, &p)| p || points.pinned[k as usize]),
        );
        self.shift.clone_from(&self.y);
        self.redistributor.run(
            &self.sph,
            &mut self.y,
            &self.offsets,
            &self.indices,
            &self.mass,
            &self.rest_density,
            &self.fixed,
            self.redistribution,
            self.redistribution_iterations,
        )?;
        let (before, members, fixed) = (&self.shift, &self.members, &self.fixed);
        self.y.par_iter_mut().enumerate().for_each(|(i, y)| {
            if fixed[i] {
                return;
            }
            let k = members[i] as usize;
            *y = push_out_of_colliders(
                Points::colliders_of(&points.collides, k, colliders),
                MoveStart::Now(before[i]),
                *y,
                points.margin[k],
                None,
            );
        });
        self.hold_densities(points, colliders);
        for (shift, y) in self.shift.iter_mut().zip(&self.y) {
            *shift = y - *shift;
        }
        Ok(())
    }

    /// The density constraints projected again after the redistribution (see the module's
    /// doc), each member's density bounded by its ceiling `max(rho*_i, rho_i)` (`rho*_i` its
    /// constraint's target, [`Self::find_targets`]), `rho_i` as the
    /// last [`Self::violation`] left it (before the redistribution; an adhered member's
    /// two-sided constraint holds it at `rho~_i`, so the hold does not do adhesion's work as a
    /// position correction): the ceilings stand in for the rest densities during these
    /// passes, so the constraints are the projection's. The passes are Jacobi's whatever the
    /// stage's solver: the bound is one-sided, and what the redistribution added is local
    /// (within a kernel support of its moves), so each member over its ceiling is pushed off
    /// its neighbours along its own gradient and nothing is pulled; the conjugate gradients
    /// hold their active set as equalities, so their hold pulled members back to their
    /// ceilings and gave back the spacing the redistribution had evened (a dam break's
    /// `sum ||grad rho||^2` rose over some steps' redistribution and hold;
    /// docs/particles/fluids.md). At most `redistribution_iterations` passes (one linearisation
    /// each), no more than `density_iterations`, to the density tolerance; the passes add to
    /// `self.passes`, and `self.error` is then the violation of the rest densities again.
    fn hold_densities(&mut self, points: &Points<T>, colliders: &[ColliderModel<T>]) {
        let mut ceiling = std::mem::take(&mut self.ceiling);
        ceiling.clear();
        let adhered = &self.adhered;
        ceiling.extend((self.density.iter().zip(&self.target)).zip(adhered).map(
            |((&rho, &rho0), &two_sided)| {
                if two_sided || rho > rho0 {
                    rho
                } else {
                    rho0
                }
            },
        ));
        std::mem::swap(&mut self.target, &mut ceiling);
        let projected = std::mem::replace(&mut self.passes, 0);
        let linearisations = self.redistribution_iterations;
        self.project_passes(
            points,
            colliders,
            linearisations,
            DensitySolver::Jacobi,
            false,
        );
        std::mem::swap(&mut self.target, &mut ceiling);
        self.ceiling = ceiling;
        self.passes += projected;
        self.error = self.violation();
    }

    /// The redistribution's displacement taken out of the velocities the step took.
    pub fn end_step(&mut self, points: &mut Points<T>) {
        let inv_h = T::one() / self.h;
        for (s, &k) in self.shift.iter().zip(&self.members) {
            points.velocity[k as usize] -= s * inv_h;
        }
    }
}

#[cfg(test)]
#[path = "fluid_redistribution_tests.rs"]
mod tests;
