"""The paper's contact scenes (Table 1 of Lu et al. 2023) at small sizes: at every checked step
no two triangles intersect, non-adjacent primitives stay eps * xi apart and no vertex is inside
a collider, and each scene does what it is for (layers stack on the ball, the antependium
hangs over the table's edge and stays on the table, the shell is stopped by the target).
"""

import numpy as np
import pytest

import peridyn
from contact_checks import assert_apart
from peridyn.checks import min_separation
from peridyn.paper_scenes import antependium, cloths_over_ball, shooting_shell


def run_checked(scene, steps, every=1):
    """Steps the scene, checking the contact promises every `every` steps; returns the
    largest number of active contact pairs seen."""
    contact = scene.solver.contact
    bodies, colliders = list(scene.bodies.values()), list(scene.colliders.values())
    active = 0
    for k in range(steps):
        stats = scene.solver.step()
        active = max(active, stats.contact["active_pairs"])
        if k % every == every - 1:
            assert_apart(bodies, colliders, contact.thickness, contact.eps)
    return active


@pytest.mark.parametrize("layers", [1, 3, 6])
def test_cloths_stack_on_the_ball(layers):
    """The paper's 1, 3 and 6 layers (at 9 x 9 vertices)."""
    scene = cloths_over_ball(layers=layers, n=9, size=0.5, dt=2e-3, max_iters=30, threads=1)
    assert list(scene.bodies) == [f"layer{k}" for k in range(layers)]
    assert len(scene.solver.bodies) == layers and len(scene.solver.colliders) == 2
    ball = scene.ball
    top = ball.center[2] + ball.radius
    start = [layer.positions[:, 2].max() for layer in scene.bodies.values()]
    assert top < start[0] and np.all(np.diff(start) > 0)
    active = run_checked(scene, 40)
    assert layers == 1 or active > 0, "the layers must have touched"
    # Each layer's centre vertex sits on the one below, the lowest on the ball.
    centre = [layer.positions[np.argmin(np.linalg.norm(layer.positions[:, :2], axis=1))]
              for layer in scene.bodies.values()]
    z = [c[2] for c in centre]
    assert np.all(np.diff(z) > 0), z
    assert top < z[0] < start[0], "the lowest layer rests on the ball"
    assert max(np.abs(c[:2]).max() for c in centre) < 0.05, "the stack did not slide off"


def test_antependium_hangs_over_the_edge_and_stays_on_the_table():
    scene = antependium(n=10, bending=0.03, dt=2e-3, max_iters=30, threads=1)
    cloth, table = scene.cloth, scene.table
    rest = cloth.rest_positions
    on_table = rest[:, 1] < -0.3
    front = np.isclose(rest[:, 1], rest[:, 1].max())
    run_checked(scene, 150, every=10)
    x = cloth.positions
    assert x[front, 2].max() < -0.15, "the free part must hang down the table's front"
    assert np.abs(x[on_table] - rest[on_table]).max() < 0.01, "the cloth slid on the table"
    assert table.signed_distance(x).min() > -1e-6


def test_shell_shot_into_the_target_is_stopped():
    scene = shooting_shell(subdivisions=1, n=8, radius=0.15, size=0.8, target_s0=4e4,
                           max_iters=30, threads=1)
    shell, target = scene.shell, scene.target
    assert scene.colliders == {} and shell.velocities[:, 2].mean() == pytest.approx(-15.0)
    active = run_checked(scene, 100, every=5)
    assert active > 0, "the shell must have hit the target"
    assert shell.velocities[:, 2].mean() > -0.8 * 15.0, "the target did not slow the shell down"
    # The target caught it: stretched into a pocket (the pinned border stays put).
    assert target.positions[:, 2].min() < -0.1
    pinned = target.pinned
    np.testing.assert_allclose(target.positions[pinned], target.rest_positions[pinned])


@pytest.mark.parametrize("build, kwargs", [
    (cloths_over_ball, dict(layers=3, n=30, size=0.5)),
    (antependium, dict(n=40)),
    (shooting_shell, dict(subdivisions=3, n=40, distance=0.2)),  # coarse: closer than 0.6 edges
])
def test_the_barrier_leaves_every_mesh_at_rest_alone(build, kwargs):
    """No two non-adjacent primitives of a body at rest are within the barrier's reach, so the
    first step starts with no active contact (the barrier would otherwise push a mesh's own
    triangles apart in its plane)."""
    scene = build(**kwargs, threads=1)
    contact = scene.solver.contact
    reach = contact.thickness + contact.d_hat
    for name, body in scene.bodies.items():
        gap = min_separation(body.positions, body.triangles, 2.0 * reach)
        assert gap > reach, f"{name}: primitives {gap} m apart, the barrier reaches {reach} m"
    scene.solver.dt = 1e-6
    for body in scene.bodies.values():
        body.velocities = np.zeros_like(body.velocities)
    assert scene.solver.step().contact["active_pairs"] == 0


@pytest.mark.parametrize("build, kwargs", [
    (cloths_over_ball, dict(layers=0)),
    (cloths_over_ball, dict(layer_gap=0.5)),
    (cloths_over_ball, dict(n=400, size=0.5)),  # too fine for xi = 1.5 mm
    (antependium, dict(overhang=2.0)),
    (antependium, dict(bending=-1.0)),
    (antependium, dict(books=5)),
    (shooting_shell, dict(subdivisions=0)),
    (shooting_shell, dict(radius=2.0)),
    (shooting_shell, dict(xi=-1.0)),
    (peridyn.colliding_sheets, dict(size=0.0)),
    (peridyn.colliding_sheets, dict(gap=-1e-3)),
    (peridyn.colliding_sheets, dict(gap=float("nan"))),
])
def test_scene_builders_refuse_bad_input(build, kwargs):
    with pytest.raises(ValueError):
        build(**kwargs)


def test_scene_names_its_bodies_and_colliders():
    scene = peridyn.default_scene(n=4)
    assert scene.cloth is scene.bodies["cloth"] and scene.sphere is scene.colliders["sphere"]
    with pytest.raises(AttributeError, match="no attribute, body or collider named 'table'"):
        scene.table


def test_colliding_sheets_start_apart_offset_and_closing_with_no_net_momentum():
    """The upper sheet starts `gap` above the lower one, shifted by half a spacing along x
    and y; the two close at `speed`, each at half of it, so equal densities carry no net
    momentum and unequal ones the difference of their masses times speed / 2."""
    scene = peridyn.colliding_sheets(n=5, size=0.2, gap=0.01, speed=0.6,
                                     densities=(500.0, 500.0))
    lower, upper = scene.lower, scene.upper
    np.testing.assert_allclose(upper.positions - lower.positions, [[0.025, 0.025, 0.01]] * 25)
    np.testing.assert_allclose(upper.velocities - lower.velocities, [[0.0, 0.0, -0.6]] * 25)
    momentum = lower.masses @ lower.velocities + upper.masses @ upper.velocities
    np.testing.assert_allclose(momentum, 0.0, atol=1e-15)
    heavy = peridyn.colliding_sheets(n=5, size=0.2, speed=0.6, densities=(500.0, 1500.0))
    light, dense = heavy.lower, heavy.upper
    momentum = light.masses @ light.velocities + dense.masses @ dense.velocities
    np.testing.assert_allclose(momentum[2], -light.masses.sum() * 0.3 * 2, rtol=1e-12)
    assert scene.colliders == {} and scene.solver.gravity == [0.0, 0.0, 0.0]
    assert scene.solver.contact is not None and scene.steps == 40
