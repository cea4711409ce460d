//! The walls of [`super`]: sliding on an edge, the walls a member touches at a step's start,
//! and the release of a wall the move leaves.

use nalgebra::Vector3;

use super::{add_wall, none, release, slide, touching, Walls};
use crate::collider::{Collider, ColliderModel, Pose, Shape};

fn held(walls: &Walls<f64>) -> usize {
    walls.iter().filter(|n| **n != Vector3::zeros()).count()
}

/// A plane collider through `point` with outward `normal`, fixed.
fn plane(point: [f64; 3], normal: [f64; 3]) -> ColliderModel<f64> {
    let collider = Collider::fixed(Shape::plane(point, normal).unwrap());
    ColliderModel::new(&collider, &Pose::IDENTITY, &Pose::IDENTITY)
}

/// A member pushed out of a floor and then out of a tilted side wall keeps both normals
/// (orthonormalised): its slid moves have no part along either wall's normal, keep the part
/// along the edge, and a third push along a direction already held adds nothing.
#[test]
fn a_member_on_an_edge_slides_along_both_walls() {
    let mut walls: Walls<f64> = none();
    let floor = Vector3::new(0.0, 0.0, 1.0);
    let side = Vector3::new(1.0, 0.0, 0.5).normalize();
    add_wall(&mut walls, floor * 2e-4);
    add_wall(&mut walls, side * 3e-4);
    add_wall(&mut walls, (floor + side) * 1e-4);
    assert_eq!(held(&walls), 2);
    let v = Vector3::new(-0.3, 0.7, -1.1);
    let slid = slide(&walls, v);
    assert!(
        slid.dot(&floor).abs() < 1e-12 && slid.dot(&side).abs() < 1e-12,
        "{slid}"
    );
    let edge = floor.cross(&side).normalize();
    assert!((slid - edge * edge.dot(&v)).norm() < 1e-12, "{slid}");
}

/// Without walls the slide is the identity to the bit (the Jacobi solver's moves pass through
/// it unchanged).
#[test]
fn no_walls_leave_a_move_as_it_is() {
    let v: Vector3<f64> = Vector3::new(-0.3, 1e-300, -0.0);
    let slid = slide(&none(), v);
    assert!(slid
        .iter()
        .zip(&v)
        .all(|(a, b): (&f64, &f64)| a.to_bits() == b.to_bits()));
}

/// In the corner of a floor (z = 0) and a side wall (x = 0), with margin 1 mm and probe depth
/// 0.1 mm: a member 1.05 mm from both holds both walls' normals; one 1.05 mm above the floor and
/// 1.2 mm from the side only the floor's; one 1.2 mm from both none.
#[test]
fn a_member_at_a_step_start_holds_the_walls_it_touches() {
    let colliders = [
        plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
        plane([0.0, 0.0, 0.0], [1.0, 0.0, 0.0]),
    ];
    let (margin, depth) = (1e-3, 1e-4);
    let at = |x: f64, z: f64| touching(&colliders, &Vector3::new(x, 0.5, z), margin, depth);
    let corner = at(1.05e-3, 1.05e-3);
    assert_eq!(held(&corner), 2);
    assert!(corner.contains(&Vector3::z()) && corner.contains(&Vector3::x()));
    let floor = at(1.2e-3, 1.05e-3);
    assert_eq!(held(&floor), 1);
    assert!(floor.contains(&Vector3::z()));
    assert_eq!(held(&at(1.2e-3, 1.2e-3)), 0);
}

/// A member held by a floor and a side wall whose move lifts it off the floor (and presses it
/// into the side) drops the floor's normal and keeps the side's: after the release its slid
/// move keeps the lift; a move along the floor releases nothing.
#[test]
fn a_move_that_leaves_a_wall_releases_it() {
    let mut walls: Walls<f64> = none();
    add_wall(&mut walls, Vector3::z());
    add_wall(&mut walls, Vector3::x());
    let lift = Vector3::new(-2e-4, 0.0, 3e-4);
    release(&mut walls, &lift);
    assert_eq!(held(&walls), 1);
    assert!(walls.contains(&Vector3::x()));
    assert_eq!(slide(&walls, lift), Vector3::new(0.0, 0.0, 3e-4));
    let mut walls: Walls<f64> = none();
    add_wall(&mut walls, Vector3::z());
    release(&mut walls, &Vector3::new(1e-4, -1e-4, 0.0));
    assert_eq!(held(&walls), 1);
}
