//! The direct solver after a change of the rest data's values on the same pattern: it
//! refactors numerically on its symbolic analysis and solves exactly (to rounding) with the
//! current matrix; a change of pattern (a plastic body's neighbourhoods) builds it anew.

use nalgebra::{DMatrix, Vector3};

use crate::collider::{Collider, Shape};
use crate::particles::{Elastic, Granular, ParticleParams, ParticleRest, Particles};
use crate::solve::{BodyMut, GlobalSolver, Solver, SolverParams};

use super::DirectSolver;

/// A body of `n` particles a side on a lattice of 1 cm, its lowest layer at `z0` (m), of
/// density `density` (kg/m^3) and material `material`.
fn lattice(n: [usize; 3], z0: f64, density: f64, material: Elastic) -> Particles {
    let params = ParticleParams {
        spacing: 0.01,
        density,
        horizon: None,
        material,
    };
    let x = (0..n[0] * n[1] * n[2])
        .map(|k| {
            let (i, j, l) = (k % n[0], k / n[0] % n[1], k / (n[0] * n[1]));
            Vector3::new(i as f64 * 0.01, j as f64 * 0.01, z0 + l as f64 * 0.01)
        })
        .collect();
    Particles::new(x, params).unwrap()
}

/// `B = blockdiag(A_FF, D_H)` of the module's doc, dense (one coordinate), for the rest data
/// `rest`, the time step `h` (s) and the held set `held`.
fn dense_b(rest: &ParticleRest<f64>, h: f64, held: &[bool]) -> DMatrix<f64> {
    let (n, h2) = (rest.len(), h * h);
    let mut b = DMatrix::zeros(n, n);
    for i in 0..n {
        b[(i, i)] = rest.diagonal(i, h2);
        for bond in rest.row(i) {
            let j = rest.indices[bond] as usize;
            if !held[i] && !held[j] {
                b[(i, j)] -= h2 * rest.coupling[bond];
            }
        }
    }
    b
}

/// `max |B delta - r| / max |r|` over the three coordinates after `direct` solved `B delta =
/// r` for a fixed right-hand side (kg m).
fn relative_residual(
    direct: &mut DirectSolver,
    rest: &ParticleRest<f64>,
    h: f64,
    held: &[bool],
) -> f64 {
    let n = rest.len();
    let r: Vec<Vector3<f64>> = (0..n)
        .map(|i| Vector3::new((i as f64).sin(), (0.7 * i as f64).cos(), 0.3) * 1e-3)
        .collect();
    let mut delta = vec![Vector3::zeros(); n];
    direct.solve(&r, &mut delta);
    let b = dense_b(rest, h, held);
    let (mut worst, mut scale) = (0.0f64, 0.0f64);
    for c in 0..3 {
        let x = DMatrix::from_fn(n, 1, |i, _| delta[i][c]);
        let bx = &b * x;
        for i in 0..n {
            worst = worst.max((bx[i] - r[i][c]).abs());
            scale = scale.max(r[i][c].abs());
        }
    }
    worst / scale
}

/// A 5 x 4 x 4 elastic block's direct solver, factored and solving to rounding (1e-13); its
/// couplings then stiffened by half on the same bonds (as a granular body's density or a
/// re-anchored return changes them): without being told, the solver keeps its factor (no
/// refactorisation) and solves the old matrix (off by more than 1e-2); told
/// ([`DirectSolver::values_changed`]), it refactors once, numerically on its analysis (no new
/// one), and solves the new matrix to rounding again.
#[test]
fn a_change_of_values_refactors_on_the_pattern_and_solves_exactly() {
    let body = lattice([5, 4, 4], 0.0, 1000.0, Elastic::Young { e: 1e6, nu: 0.25 });
    let mut rest = ParticleRest::<f64>::of_bodies(&[&body]).unwrap();
    let (h, mut held) = (1e-2, vec![false; rest.len()]);
    held[0] = true;
    let mut direct = DirectSolver::new(&rest).unwrap();
    direct.factor(&rest, h, &held).unwrap();
    assert_eq!(direct.take_counts(), (1, 1));
    let fresh = relative_residual(&mut direct, &rest, h, &held);
    assert!(fresh < 1e-13, "{fresh:e}");
    for c in &mut rest.coupling {
        *c *= 1.5;
    }
    for s in &mut rest.stiffness {
        *s *= 1.5;
    }
    direct.factor(&rest, h, &held).unwrap();
    assert_eq!(direct.take_counts(), (0, 0));
    let stale = relative_residual(&mut direct, &rest, h, &held);
    assert!(stale > 1e-2, "{stale:e}");
    direct.values_changed();
    direct.factor(&rest, h, &held).unwrap();
    assert_eq!(direct.take_counts(), (0, 1));
    let refactored = relative_residual(&mut direct, &rest, h, &held);
    assert!(refactored < 1e-13, "{refactored:e}");
}

/// A 5 x 5 x 6 column of dry sand (30 degrees, 1 cm, 1600 kg/m^3) settling on a frictional
/// plane for 40 steps of 2 ms with the direct solver: after every step whose neighbourhoods
/// stayed (the stiffness `lam` of eq. 25-27 changed with the density on the same bonds) the
/// solver is kept and its next factorisation, for the step's time step and held set, solves
/// the new rest data's matrix to rounding (1e-12; the factor kept before this change solved
/// the last step's matrix, off by up to 0.4: docs/particles/granular.md); after every step
/// whose neighbourhoods changed it is built anew, and the next step reports one analysis
/// (`ParticleTimings::analyses`), else none. Both kinds of step occur.
#[test]
fn a_settling_sand_column_refactors_its_direct_solver_as_its_stiffness_changes() {
    let mut body = lattice(
        [5, 5, 6],
        0.005,
        1600.0,
        Elastic::Paper { mu: 0.0, lam: 1e5 },
    );
    body.set_granular(Granular::new(30.0, 0.0)).unwrap();
    let p = SolverParams {
        dt: 2e-3,
        global_solver: GlobalSolver::Direct,
        max_iters: 10,
        tol: 0.0,
        ..SolverParams::default()
    };
    let mut solver = Solver::<f64>::new(p, Some(1)).unwrap();
    let plane = Shape::plane([0.0; 3], [0.0, 0.0, 1.0]).unwrap();
    solver
        .add_collider(Collider::new(plane, 0.3, [0.0; 3]).unwrap())
        .unwrap();
    let (mut kept, mut rebuilt, mut analysed) = (0, 0, true);
    for step in 0..40 {
        let stats = solver.step(&mut [BodyMut::from(&mut body)]).unwrap();
        assert_eq!(
            stats.particles.analyses,
            usize::from(analysed),
            "step {step}"
        );
        let sys = solver.particle_system().unwrap();
        let Some(direct) = sys.direct.as_mut() else {
            rebuilt += 1;
            analysed = true;
            continue;
        };
        analysed = false;
        kept += 1;
        direct.factor(&sys.rest, p.dt, &sys.held).unwrap();
        assert_eq!(direct.take_counts(), (0, 1), "step {step}");
        let residual = relative_residual(direct, &sys.rest, p.dt, &sys.held);
        assert!(residual < 1e-12, "step {step}: {residual:e}");
    }
    assert!(kept > 0 && rebuilt > 0, "{kept} kept, {rebuilt} rebuilt");
}
