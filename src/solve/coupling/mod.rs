//! Couplings between body families: particles against membrane triangles (He et al. 2017,
//! section 8 and Fig. 18: a fluid, or any particle body, on a cloth).
//!
//! **Constraint.** A (non-ghost) particle `p` of radius `r_p` (its collider margin, m) and a
//! membrane triangle `t = (a, b, c)` of half thickness `tau_t` (the mean of its vertices', m)
//! keep `C = s n . (x_p - a) - d >= 0` with `d = r_p + tau_t` (m), `n` the triangle's unit
//! normal at the current positions and `s = +-1` the side of the triangle's plane the particle
//! was on at the start of the step, wherever the particle's projection on that plane falls
//! inside the triangle (barycentric coordinates `>= -`[`PRISM_SLACK`], so that the prisms of
//! neighbouring triangles overlap over a cloth's crease). A pair whose particle starts outside
//! that prism takes its side when its particle first enters it.
//!
//! **Projection.** A violated pair (`C < 0`) moves its four points in the metric of the global
//! move, the Jacobi blocks `D` of the families (a particle's `m + h^2 L_ii`, a vertex's
//! `m I + h^2 sum C` of Lu et al. 2023 eq. 25; zero inverse for a pinned point):
//! with `g_p = s n`, `g_k = -w_k s n` (`w` the clamped barycentric weights of the projection,
//! summing to 1) and the pair's impulse `J = lambda s n`,
//!
//! `lambda = -C / (n_p g_p' D_p^-1 g_p + sum_k n_k g_k' D_k^-1 g_k)` (kg m),
//! `dx_p = D_p^-1 J`, `dx_k = -w_k D_k^-1 J`,
//!
//! the minimal-`D`-norm move that closes the linearised gap. All pairs are projected at once
//! (Jacobi), with each point's inverse metric scaled by `n`, the number of violated pairs it
//! is in ("mass splitting", Tonge, Benevolenskiy and Voroshilov 2012), so that a particle over
//! a crease or a vertex under many particles is not pushed once per pair. After a global
//! iteration the projection is [`ITERATION_PASSES`] pass (the iterations repeat it); at the
//! end of the step, passes repeat until no pair is violated by more than [`PASS_TOLERANCE`] of
//! its gap, at most [`MAX_PASSES`].
//! `D dx` sums to `J (1 - sum_k w_k) = 0` over a pair: the reactions are equal and opposite,
//! so at the iteration's fixed point (where each move takes back the global move's `D^-1 r`)
//! the cloth carries exactly the particles' weight, and the iterations conserve momentum to
//! the solver's tolerance (the coupling adds none of its own).
//!
//! **The projection at the end of the step is in the mass metric** (`D = m`, `m I` for a
//! vertex): there `sum m dx = J (1 - sum_k w_k) = 0` per pair, so it conserves momentum to
//! round-off, and the velocities `(y - y_t) / h` taken after it carry no momentum the
//! coupling made. It closes only what the iterations left (a residual violation), so its
//! metric does not set how the weight is shared at the fixed point; in the Jacobi metric it
//! moved the total momentum by up to 3.5e-3 of it (tests/test_couplings.py). No friction.
//!
//! **With the direct solver** the particles' global move is the full solve `A^-1 r`, not the
//! Jacobi move `D^-1 r` the projection's metric assumes: at the fixed point the particles
//! would feel `A c` for a move `c`, the cloth `D c`, and a block fell through a soft cloth. So
//! a particle the projection moved is held by the direct solver from its next move on, as a
//! particle touching a collider is (`crate::solve::particles`, `direct`): its couplings are
//! taken out of the factor and it takes the Jacobi move, in the projection's metric.
//!
//! **Where in the step.** The pairs are found at the start of the step ([`pairs`]); the
//! projection runs after every global iteration (after the colliders, before the membrane
//! contact local step, on `y_next`), its moves counted as reactions in both families'
//! convergence measures, and once more after the fluids' density projection (which moves
//! particles without seeing the cloth), on the positions the velocities are taken from: every
//! step ends with each particle on its side of every triangle it is near.
//!
//! **Gaps.** A pair that closes by more than its candidate reach within one step (a time step
//! far too long for the bodies' speeds) can be missed; a particle that passes round a
//! triangle's edge and into its prism from the plane's other side in one step is kept on that
//! side; the last projection comes after the last membrane contact local step, and its cloth
//! moves are not checked against cloth-cloth intersections.

mod cloth;
mod pairs;
mod prism;
mod projection;

pub(crate) use cloth::ClothCoupling;

#[cfg(test)]
mod tests;

/// How far outside a triangle (in barycentric coordinates) a particle's projection still
/// counts as over it.
pub const PRISM_SLACK: f64 = 0.05;
/// A pass stops the projection when no pair is violated by more than this fraction of its
/// gap `d`.
pub const PASS_TOLERANCE: f64 = 1e-4;
/// Most passes of the projection at the end of a step.
pub const MAX_PASSES: usize = 64;
/// Passes of the projection after each global iteration.
pub const ITERATION_PASSES: usize = 1;
