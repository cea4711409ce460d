//! The settled move against the projection that ends an iteration
//! ([`crate::collider::push_out_with_friction`] in the isotropic Jacobi metric), for a
//! particle in a corner of two frictional planes, and the coarse problem started from the
//! reactions it reports ([`super::super::coarse`], "Fixed point").

use nalgebra::Vector3;

use super::super::coarse_problem::{Coarse, Contact, Friction};
use super::out_of_colliders;
use crate::collider::{push_out_with_friction, Collider, ColliderModel, Pose, Shape};
use crate::real::Real;
use crate::symmetric::SymmetricMatrix3;

/// A fixed plane through the origin with outward `normal` and Coulomb `friction`.
fn plane<T: Real>(normal: [f64; 3], friction: f64) -> ColliderModel<T> {
    let shape = Shape::plane([0.0; 3], normal).unwrap();
    let collider = Collider::new(shape, friction, [0.0; 3]).unwrap();
    ColliderModel::new(&collider, &Pose::IDENTITY, &Pose::IDENTITY)
}

/// The wall `x = 0` and the floor `z = 0` (friction 0.5 each) in `order` (true: wall first),
/// a particle at rest in their corner at the margin `0.0125` m from both (`y = y_start`,
/// Jacobi diagonal 0.2 kg), and sweep moves into the corner: the settled move is the
/// projection's move within round-off (`8 eps (1 + |y|)` a coordinate). Where the sweep's move
/// goes into the wall by `a` and down by `b > mu a` (wall friction sliding, floor friction
/// sticking), the projection takes it back whole (the fixed point `y_next = y`), and so must
/// the settled move; measuring the floor's gap at the sweep's end left it `mu a` upward.
fn agrees_in_the_corner<T: Real>(wall_first: bool) {
    let (wall, floor) = (
        plane::<T>([1.0, 0.0, 0.0], 0.5),
        plane::<T>([0.0, 0.0, 1.0], 0.5),
    );
    let colliders = if wall_first {
        [wall, floor]
    } else {
        [floor, wall]
    };
    let margin = T::of(0.0125);
    let d = T::of(0.2);
    let y = Vector3::new(margin, T::of(0.3), margin);
    let inverse = SymmetricMatrix3::from_diagonal(&Vector3::repeat(T::one() / d));
    let tolerance = T::default_epsilon() * T::of(8.0) * (T::one() + y.norm());
    let moves = [
        // Into the wall 2e-4, along it 1e-4 and down 5e-4: the fixed point.
        ([-2e-4, 1e-4, -5e-4], true),
        ([-2e-4, 0.0, -5e-4], true),
        // Down alone (no wall push, no wall friction) and a move out of the corner.
        ([0.0, 3e-4, -4e-4], false),
        ([3e-4, -1e-4, 2e-4], false),
        // Into the wall more than down: the wall's friction holds the fall.
        ([-9e-4, -2e-4, -1e-4], true),
    ];
    for (delta, fixed_point) in moves {
        let delta = Vector3::from(delta.map(T::of));
        let projected = push_out_with_friction(&y, y + delta, &y, &inverse, margin, &colliders) - y;
        let mut reactions = [Vector3::zeros(); 2];
        let settled = out_of_colliders(&y, &y, delta, margin, d, &colliders, |k, _, phi| {
            reactions[k] = phi
        });
        let off = (settled - projected).amax();
        assert!(
            off <= tolerance,
            "{delta:?}: settled {settled:?} projected {projected:?}"
        );
        if fixed_point {
            assert!(
                settled.amax() <= tolerance,
                "{delta:?}: settled {settled:?}"
            );
        }
        // Each friction reaction is tangential to its own collider.
        for (c, phi) in colliders.iter().zip(reactions) {
            assert!(c.normal(&y).dot(&phi).abs() <= tolerance * d);
        }
    }
}

#[test]
fn the_settled_move_in_a_frictional_corner_is_the_projections() {
    for wall_first in [true, false] {
        agrees_in_the_corner::<f64>(wall_first);
        agrees_in_the_corner::<f32>(wall_first);
    }
}

/// The coarse problem of one particle alone in a body of mass 0.05 kg (Jacobi diagonal
/// 0.2 kg) at `y`, between `colliders`, at a fixed point of the sweep's move `delta` (the
/// settled move zero within round-off, `1e-16` m: measured 2e-17): its net residual is the sweep's `D delta`, and its
/// contacts (normal and gap at the sweep's position `y + delta`) and frictions start from
/// the reactions [`out_of_colliders`] reports. Returns `|t| / |t0|`, `t0 = F / M`.
fn coarse_move_at_a_fixed_point(
    colliders: &[ColliderModel<f64>],
    y: Vector3<f64>,
    delta: Vector3<f64>,
) -> f64 {
    let (mass, d, margin) = (0.05, 0.2, 0.0125);
    let mut reactions = vec![(0.0, Vector3::zeros()); colliders.len()];
    let settled = out_of_colliders(&y, &y, delta, margin, d, colliders, |k, push, phi| {
        reactions[k] = (d * push, phi)
    });
    assert!(settled.amax() <= 1e-16, "{delta:?}: settled {settled:?}");
    let mut coarse = Coarse::new(vec![true]);
    coarse.inverse_mass[0] = 1.0 / mass;
    coarse.force[0] = delta * d;
    coarse.translation[0] = delta * (d / mass);
    let t0 = coarse.translation[0].norm();
    let at = y + delta;
    for (c, (lambda, phi)) in colliders.iter().zip(reactions) {
        if c.signed_distance(&at) >= margin {
            continue;
        }
        let n = c.normal(&at);
        let slip = settled - n * n.dot(&settled);
        let normal = coarse.contacts.len();
        coarse
            .contacts
            .push(Contact::new(0, None, n, 0.0).starting_from(lambda));
        coarse
            .frictions
            .push(Friction::new(0, normal, &n, &slip, c.friction, &phi));
    }
    coarse.solve();
    coarse.translation[0].norm() / t0
}

/// At fixed points of a frictional corner and wedge the coarse solve started from the
/// reactions of [`out_of_colliders`] starts at its solution and translates the body by
/// round-off (`1e-13` of `t0`; measured 1e-16 to 4e-16 in a Python replica of the solve,
/// zero sweeps). Started from `D (margin - gap)` with the gap at the sweep's position, the
/// multiplier of a collider that an earlier one's push or friction moved the particle in or
/// out of was off the projection's: the right-angle corner's floor `5e-4 D` against its push's
/// `4.02e-4 D` (wall first), and the wedge's floor (a wall of normal `(1, 0, -0.5)`, whose
/// push goes into the floor, friction 0.8) `1.537e-4 D` and `2.206e-4 D` against its push's
/// `1.0e-4 D` and `2.0e-4 D`: the replica's solve took 12 and 11 sweeps and left `7e-12` and
/// `1.7e-11` of `t0`.
#[test]
fn the_coarse_solve_started_from_the_reactions_moves_nothing_at_a_fixed_point() {
    let margin = 0.0125;
    let (wall, floor) = (
        plane::<f64>([1.0, 0.0, 0.0], 0.5),
        plane::<f64>([0.0, 0.0, 1.0], 0.5),
    );
    let y = Vector3::new(margin, 0.3, margin);
    for colliders in [[wall.clone(), floor.clone()], [floor, wall]] {
        for delta in [
            [-2e-4, 1e-4, -5e-4],
            [-2e-4, 0.0, -5e-4],
            [-9e-4, -2e-4, -1e-4],
        ] {
            let off = coarse_move_at_a_fixed_point(&colliders, y, Vector3::from(delta));
            assert!(off <= 1e-13, "corner, {delta:?}: |t| / |t0| {off}");
        }
    }
    let wedge = [
        plane::<f64>([1.0, 0.0, -0.5], 0.8),
        plane::<f64>([0.0, 0.0, 1.0], 0.8),
    ];
    let y = Vector3::new(margin * (1.25f64.sqrt() + 0.5), 0.3, margin);
    for delta in [
        [-3.0044e-4, 0.0, -1.5367e-4],
        [-2.221e-4, 1.3266e-4, -2.206e-4],
    ] {
        let off = coarse_move_at_a_fixed_point(&wedge, y, Vector3::from(delta));
        assert!(off <= 1e-13, "wedge, {delta:?}: |t| / |t0| {off}");
    }
}
