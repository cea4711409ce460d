"""Shells and rods as particles from Python: layout, ghosts, pins, free fall, bad input (the
physics, bending against plate and beam theory, is tested in Rust: src/solve/particles/)."""

from __future__ import annotations

import numpy as np
import pytest

import peridyn as pd

PLATE = ([[0, 0, 0], [0.03, 0, 0], [0.03, 0.02, 0], [0, 0.02, 0]], [[0, 1, 2], [0, 2, 3]])


def shell(**kw):
    args = dict(spacing=0.005, thickness=0.004, density=1000.0, material=pd.Elastic.from_young(1e6, 0.25))
    args.update(kw)
    return pd.Particles.shell(PLATE, **args)


def rod(points=((0, 0, 0), (0.03, 0, 0)), **kw):
    args = dict(spacing=0.005, radius=0.003, density=1000.0, material=pd.Elastic.from_young(1e6, 0.25))
    args.update(kw)
    return pd.Particles.rod(np.array(points, float), **args)


def test_a_shell_has_its_real_layer_first_and_two_ghost_layers():
    body = shell()
    n = body.num_real
    assert body.num_particles == 3 * n
    x = body.positions
    assert np.allclose(body.real_positions, x[:n])
    assert np.array_equal(body.ghost_owner, np.concatenate([np.arange(n), np.arange(n)]))
    assert np.allclose(x[n:2 * n, 2], 0.004 / np.sqrt(8), atol=1e-15)
    assert np.allclose(x[2 * n:, 2], -0.004 / np.sqrt(8), atol=1e-15)
    mass = body.particle_mass * body.num_particles
    assert mass == pytest.approx(1000.0 * 0.03 * 0.02 * 0.004, rel=1e-12)


def test_a_rod_has_four_ghosts_per_particle_and_pinning_pins_them():
    body = rod()
    n = body.num_real
    assert n == 7 and body.num_particles == 5 * n
    assert np.array_equal(body.ghost_owner, np.repeat(np.arange(n), 4))
    body.pin([0])
    assert list(body.pinned) == [0, n, n + 1, n + 2, n + 3]
    body.unpin([0])
    assert len(body.pinned) == 0


def test_a_rod_falls_freely_exactly():
    body = rod()
    start = body.positions
    solver = pd.Solver(dt=0.01)
    solver.add(body)
    for _ in range(3):
        solver.step()
    assert np.allclose(body.positions - start, [0, 0, -9.81 * 0.01**2 * 6], atol=1e-12)


@pytest.mark.parametrize("thickness", [0.0, -1e-3, float("nan"), 0.0101])
def test_a_bad_thickness_is_refused_by_name(thickness):
    with pytest.raises(ValueError, match="thickness"):
        shell(thickness=thickness)


@pytest.mark.parametrize(
    "points, radius, match",
    [
        ([(0, 0, 0)], 0.003, "at least 2 points"),
        ([(0, 0, 0), (0, 0, 0), (0.02, 0, 0)], 0.003, "points 0 and 1 are equal"),
        ([(0, 0, 0), (0.02, 0, 0)], 0.0051, "radius"),
        ([(0, 0, 0), (0.02, 0, 0), (0, 0, 0)], 0.003, "turns back"),
    ],
)
def test_a_bad_rod_is_refused_by_name(points, radius, match):
    with pytest.raises(ValueError, match=match):
        rod(points, radius=radius)


def test_a_material_that_is_not_elastic_is_refused():
    with pytest.raises(ValueError, match="material"):
        shell(material=1.0)
