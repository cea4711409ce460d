//! The affine coarse space against the global matrix built densely on a small body: the
//! operator is `P^T (M + h^2 L) P`, an affine residual is removed in one coarse step, and the
//! coarse step leaves a residual with no affine part.

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

use crate::particles::Particles;
use crate::solve::particles::coarse::correct;
use crate::solve::particles::directions::jacobi;
use crate::solve::particles::system::ParticleSystem;
use crate::solve::particles::tests::block;

/// The squared step (s^2) of h = 1/30 s.
const H2: f64 = 1.0 / 900.0;

/// A deterministic value in `[-1, 1]` of `k`.
fn wave(k: usize) -> f64 {
    (k as f64 * 12.9898 + 0.3).sin()
}

/// A 3 x 4 x 5 block of E 1e5 Pa, its positions stretched and sheared away from its
/// reference and jittered by 5 % of the spacing (so that no lever or bond is special), with
/// its working set loaded and the affine space assembled.
fn system() -> ParticleSystem<f64> {
    let mut body = block([3, 4, 5], 0.01, 1e5);
    let moved: Vec<Vector3<f64>> = body
        .reference()
        .iter()
        .enumerate()
        .map(|(i, x)| {
            let jitter = Vector3::new(wave(3 * i), wave(3 * i + 1), wave(3 * i + 2)) * 5e-4;
            Vector3::new(x.x * 1.02 + 0.1 * x.z, x.y * 0.99, x.z * 1.01) + jitter
        })
        .collect();
    body.set_positions(moved).unwrap();
    let bodies: [&mut Particles; 1] = [&mut body];
    let mut sys = ParticleSystem::<f64>::build(&bodies).unwrap();
    sys.points.load(&bodies);
    let (points, rest, solid) = (&sys.points, &sys.rest, &sys.coarse.solid);
    sys.affine.assemble(points, rest, solid, H2);
    sys
}

/// The global matrix `M + h^2 L` (kg), 3n x 3n, from the rest data's weights.
fn global_matrix(sys: &ParticleSystem<f64>) -> DMatrix<f64> {
    let rest = &sys.rest;
    let n = rest.len();
    let mut g = DMatrix::zeros(3 * n, 3 * n);
    for i in 0..n {
        for k in 0..3 {
            g[(3 * i + k, 3 * i + k)] += rest.mass[i] + H2 * rest.stiffness[i];
        }
        for b in rest.row(i) {
            let j = rest.indices[b] as usize;
            for k in 0..3 {
                g[(3 * i + k, 3 * j + k)] -= H2 * rest.coupling[b];
            }
        }
    }
    g
}

/// The affine prolongation `P` (3n x 12): columns `t_k` (k = 0..3), then `A_kl` at
/// `3 + 3 k + l`, with the levers from the step's start positions' mass centre, computed here.
fn prolongation(sys: &ParticleSystem<f64>) -> DMatrix<f64> {
    let (y, mass) = (&sys.points.y_start, &sys.points.mass);
    let total: f64 = mass.iter().sum();
    let centre = y
        .iter()
        .zip(mass)
        .map(|(y, m)| y * *m)
        .sum::<Vector3<f64>>()
        / total;
    let mut p = DMatrix::zeros(3 * y.len(), 12);
    for (i, y) in y.iter().enumerate() {
        let lever = y - centre;
        for k in 0..3 {
            p[(3 * i + k, k)] = 1.0;
            for l in 0..3 {
                p[(3 * i + k, 3 + 3 * k + l)] = lever[l];
            }
        }
    }
    p
}

/// `(t, A)` as the 12 coarse unknowns of [`prolongation`].
fn unknowns(t: &Vector3<f64>, a: &Matrix3<f64>) -> DVector<f64> {
    DVector::from_fn(12, |c, _| {
        if c < 3 {
            t[c]
        } else {
            a[((c - 3) / 3, (c - 3) % 3)]
        }
    })
}

fn stacked(v: &[Vector3<f64>]) -> DVector<f64> {
    DVector::from_fn(3 * v.len(), |r, _| v[r / 3][r % 3])
}

fn unstacked(v: &DVector<f64>) -> Vec<Vector3<f64>> {
    (0..v.len() / 3)
        .map(|i| Vector3::new(v[3 * i], v[3 * i + 1], v[3 * i + 2]))
        .collect()
}

#[test]
fn operator_is_the_galerkin_projection_of_the_global_matrix() {
    let sys = system();
    let p = prolongation(&sys);
    let dense = p.transpose() * global_matrix(&sys) * &p;
    let mass: f64 = sys.points.mass.iter().sum();
    let k = sys.affine.stiffness[0];
    let mut expected = DMatrix::zeros(12, 12);
    for c in 0..3 {
        expected[(c, c)] = mass;
        for l in 0..3 {
            for m in 0..3 {
                expected[(3 + 3 * c + l, 3 + 3 * c + m)] = k[(l, m)];
            }
        }
    }
    let scale = dense.amax();
    let off = (&dense - &expected).amax();
    assert!(
        off <= 1e-10 * scale,
        "off by {off:e} of {scale:e}:\n{dense}\n{expected}"
    );
    // The bonds stiffen the affine block: `h^2 S` is no round-off beside `J`.
    let inertia: Matrix3<f64> = (0..sys.points.y.len())
        .map(|i| sys.affine.lever[i] * sys.affine.lever[i].transpose() * sys.points.mass[i])
        .sum();
    assert!((k - inertia).amax() > 0.1 * inertia.amax());
}

#[test]
fn an_affine_residual_is_removed_in_one_coarse_step() {
    let mut sys = system();
    let p = prolongation(&sys);
    let t = Vector3::new(1e-3, -2e-3, 5e-4);
    let a = Matrix3::new(0.01, -0.02, 0.005, 0.015, -0.01, 0.002, -0.004, 0.03, 0.02);
    let wanted = &p * unknowns(&t, &a);
    sys.current.residual = unstacked(&(global_matrix(&sys) * &wanted));
    sys.delta.fill(Vector3::zeros());
    correct(&mut sys, &[], &[], H2);
    let off = (stacked(&sys.delta) - &wanted).amax();
    assert!(off <= 1e-10 * wanted.amax(), "off by {off:e} m");
}

#[test]
fn after_a_sweep_the_coarse_step_leaves_no_affine_residual() {
    let mut sys = system();
    let p = prolongation(&sys);
    let n = sys.points.y.len();
    let r: Vec<Vector3<f64>> = (0..n)
        .map(|i| Vector3::new(wave(7 * i), wave(7 * i + 1), wave(7 * i + 2)) * 1e-4)
        .collect();
    sys.current.residual = r.clone();
    jacobi(&mut sys, H2, 1);
    let g = global_matrix(&sys);
    let projected = |delta: &[Vector3<f64>]| p.transpose() * (stacked(&r) - &g * stacked(delta));
    let before = projected(&sys.delta).amax();
    correct(&mut sys, &[], &[], H2);
    let after = projected(&sys.delta).amax();
    assert!(
        after <= 1e-10 * before,
        "P^T (r - G delta): {after:e} after the coarse step, {before:e} before"
    );
}
