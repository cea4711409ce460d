//! The settled move against the projection that ends an iteration
//! ([`crate::collider::push_out_with_friction`] in the isotropic Jacobi metric), for a
//! particle in a corner of two frictional planes.

use nalgebra::Vector3;

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
        let settled = out_of_colliders(&y, &y, delta, margin, d, &colliders, |k, phi| {
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
