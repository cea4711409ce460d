//! The two-level correction's sliding particles: which contacts slide, the prolongator rows,
//! and the coarse solution of the split frame against the dense Galerkin system `P^T A P`,
//! on a small block whose bottom layer slides on a tilted frictionless plane.

use nalgebra::{DMatrix, Vector3};

use super::{tangent, TwoLevel};
use crate::collider::{Collider, ColliderModel, Pose, Shape};
use crate::particles::ParticleRest;
use crate::solve::particles::tests::block;
use crate::solve::points::Points;

/// The plane's unit normal, tilted 0.3 rad about x.
fn tilted() -> Vector3<f64> {
    Vector3::new(0.0, 0.3f64.sin(), 0.3f64.cos())
}

/// A 4 x 4 x 3 block (0.1 m apart, E = 1e5 Pa), its bottom layer sliding on the tilted plane,
/// its first particle pinned (held whole), the rest free.
fn sliding_block() -> (ParticleRest<f64>, TwoLevel) {
    let body = block([4, 4, 3], 0.1, 1e5);
    let rest = ParticleRest::<f64>::of_bodies(&[&body]).unwrap();
    let n = rest.len();
    let mut two = TwoLevel::new(&rest, &vec![true; n]).unwrap();
    for i in 0..n {
        two.free[i] = i != 0;
        if i > 0 && i < 16 {
            two.normal[i] = tilted();
        }
    }
    two.share_normal();
    (rest, two)
}

/// The dense `P` (`3 n x 3 aggregates`): the block `I` of a free particle, `I - n n^T` of a
/// sliding one, none of a held one, in its aggregate's column.
fn dense_p(two: &TwoLevel) -> DMatrix<f64> {
    let (n, count) = (two.aggregate.len(), two.coarse.len());
    let mut p = DMatrix::zeros(3 * n, 3 * count);
    for i in 0..n {
        if two.free[i] {
            let a = two.aggregate[i];
            p.view_mut((3 * i, 3 * a), (3, 3))
                .copy_from(&tangent(&two.normal[i]));
        }
    }
    p
}

/// The dense `A = M + h^2 L` of eq. 12 for the three coordinates (`3 n x 3 n`).
fn dense_a(rest: &ParticleRest<f64>, h: f64) -> DMatrix<f64> {
    let n = rest.len();
    let mut a = DMatrix::zeros(3 * n, 3 * n);
    for i in 0..n {
        for c in 0..3 {
            a[(3 * i + c, 3 * i + c)] = rest.mass[i] + h * h * rest.stiffness[i];
            for b in rest.row(i) {
                let j = rest.indices[b] as usize;
                a[(3 * i + c, 3 * j + c)] -= h * h * rest.coupling[b];
            }
        }
    }
    a
}

/// A sliding particle's row `I - n n^T` takes nothing along `n` and keeps the tangential moves
/// (a projector: `T n = 0`, `T^2 = T`, `T t = t` for `t . n = 0`); a free particle's is `I`.
#[test]
fn a_sliding_row_projects_on_the_plane() {
    let n = tilted();
    let t = tangent(&n);
    assert!((t * n).norm() < 1e-15);
    assert!((t * t - t).norm() < 1e-15);
    let along = Vector3::new(1.0, 0.3f64.cos(), -(0.3f64.sin()));
    assert!((t * along - along).norm() < 1e-15);
    assert_eq!(tangent(&Vector3::zeros()), nalgebra::Matrix3::identity());
}

/// The coarse solution `e` of the split frame (the tangential coordinates with the sliding
/// particles free, the normal one with them held) solves the dense Galerkin system
/// `(P^T A P) e = P^T (r - A delta_J)` to 1e-10 relative, `P` with the rows `I - n n^T` of
/// the sliding particles; and the dense `P^T A P` is positive semi-definite, singular only
/// along the common normal of an aggregate of sliding particles alone.
#[test]
fn the_split_coarse_solution_solves_the_galerkin_system() {
    let (rest, mut two) = sliding_block();
    let (n, h) = (rest.len(), 1e-2);
    let residual: Vec<Vector3<f64>> = (0..n)
        .map(|i| Vector3::new((i as f64).sin(), (i as f64 * 0.7).cos(), -1.0) * 1e-3)
        .collect();
    let mut delta = vec![Vector3::new(1e-4, -2e-4, 3e-4); n];
    two.correct(&rest, &residual, &mut delta, h).unwrap();
    assert_eq!(two.take_counts(), (2, 2), "analyses and factorisations");
    let p = dense_p(&two);
    let galerkin = p.transpose() * dense_a(&rest, h) * &p;
    let remainder = nalgebra::DVector::from_iterator(
        3 * n,
        (0..n).flat_map(|i| {
            let r = if two.free[i] {
                two.remainder[i]
            } else {
                Vector3::zeros()
            };
            [r.x, r.y, r.z]
        }),
    );
    let b = p.transpose() * remainder;
    let count = two.coarse.len();
    let e = nalgebra::DVector::from_iterator(
        3 * count,
        two.coarse.iter().flat_map(|v| v.iter().copied()),
    );
    let off = (&galerkin * &e - &b).amax();
    assert!(off <= 1e-10 * b.amax(), "{off:e} against {:e}", b.amax());
    let least = galerkin.clone().symmetric_eigenvalues().min();
    assert!(least > -1e-12 * galerkin.amax(), "least eigenvalue {least}");
}

/// The correction moves a sliding particle along its plane only, leaves a held particle
/// where the sweep put it, and a second call at the same state refactors nothing.
#[test]
fn the_correction_slides_along_the_plane_and_holds_the_held() {
    let (rest, mut two) = sliding_block();
    let n = rest.len();
    let residual: Vec<Vector3<f64>> = (0..n)
        .map(|i| Vector3::new((i as f64).sin(), (i as f64 * 0.7).cos(), -1.0) * 1e-3)
        .collect();
    let before = vec![Vector3::new(1e-4, -2e-4, 3e-4); n];
    let mut delta = before.clone();
    two.correct(&rest, &residual, &mut delta, 1e-2).unwrap();
    two.correct(&rest, &residual, &mut before.clone(), 1e-2)
        .unwrap();
    assert_eq!(two.take_counts(), (2, 2), "analyses and factorisations");
    assert_eq!(delta[0], before[0]);
    let mut slid = 0.0f64;
    for i in 1..16 {
        let moved = delta[i] - before[i];
        assert!(
            moved.dot(&tilted()).abs() <= 1e-12 * moved.norm(),
            "particle {i}"
        );
        slid = slid.max(moved.norm());
    }
    assert!(slid > 0.0);
}

/// Which contacts slide ([`TwoLevel::hold`]): the bottom layer of a 4 x 4 x 3 block resting
/// at its margin on a frictionless plane or on the top face of a box slides, with the
/// collider's unit normal; on a frictional plane, a sphere, or at a box's edge (within the
/// contact reach of it) it is held whole, no normal is set and the correction takes the
/// scalar coarse matrix (the iterates of a correction without sliding rows).
#[test]
fn only_flat_frictionless_contacts_slide() {
    let mut body = block([4, 4, 3], 0.1, 1e5);
    let rest = ParticleRest::<f64>::of_bodies(&[&body]).unwrap();
    let n = rest.len();
    let margin = rest.margin[0];
    let mut points = Points::new(&[&mut body], rest.mass.clone(), rest.margin.clone());
    points.load(&[&mut body]);
    points.y = points.y_start.clone();
    let residual = vec![Vector3::new(1e-3, 0.0, -1e-3); n];
    let (touched, delta) = (vec![false; n], vec![Vector3::zeros(); n]);
    let hold = |shape: Shape, friction: f64| {
        let collider = Collider::new(shape, friction, [0.0; 3]).unwrap();
        let (start, end) = (&Pose::IDENTITY, &Pose::IDENTITY);
        let model = ColliderModel::<f64>::in_frame(&collider, start, end, &points.origin);
        let mut two = TwoLevel::new(&rest, &vec![true; n]).unwrap();
        let (h, colliders) = (1e-2, [model]);
        two.hold(
            &rest,
            &residual,
            h,
            &points,
            &touched,
            &delta,
            &colliders,
            &[],
            None,
        );
        two
    };
    let identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let floor = || Shape::plane([0.0, 0.0, -margin], [0.0, 0.0, 1.0]).unwrap();
    let under = |x: f64| Shape::cuboid([x, 0.15, -margin - 1.0], [1.0, 1.0, 1.0], identity);
    let bottom = |i: usize| i < 16;
    for (name, two) in [
        ("plane", hold(floor(), 0.0)),
        ("box", hold(under(0.15).unwrap(), 0.0)),
    ] {
        assert_eq!(two.slide_normal, Vector3::z(), "{name}");
        for i in 0..n {
            let expected = if bottom(i) {
                Vector3::z()
            } else {
                Vector3::zeros()
            };
            assert_eq!(two.normal[i], expected, "{name}: particle {i}");
            assert!(two.free[i], "{name}: particle {i}");
        }
    }
    // A sphere of radius 2 m whose top is 2 cm above the plane's place: every bottom
    // particle is within reach of it, none slides.
    let sphere = Shape::sphere([0.15, 0.15, 0.02 - margin - 2.0], 2.0).unwrap();
    for (name, two) in [
        ("rough plane", hold(floor(), 0.5)),
        ("sphere", hold(sphere, 0.0)),
    ] {
        assert_eq!(two.slide_normal, Vector3::zeros(), "{name}");
        assert!(two.normal.iter().all(|n| *n == Vector3::zeros()), "{name}");
        assert!((0..n).all(|i| two.free[i] != bottom(i)), "{name}");
    }
    // The box's edge at x = 0.1 m: the bottom layer's column there is held whole, the one
    // at x = 0 (0.1 m inside the face) slides, those beyond the box are free.
    let edge = hold(under(-0.9).unwrap(), 0.0);
    assert_eq!(edge.slide_normal, Vector3::z());
    for i in 0..16 {
        let (slides, held) = (edge.normal[i] == Vector3::z(), !edge.free[i]);
        assert_eq!((slides, held), (i % 4 == 0, i % 4 == 1), "particle {i}");
    }
}
