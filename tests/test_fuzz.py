"""Fuzzing the Python API (issue 43): random meshes, parameters and call sequences.

Hypothesis draws a small scene (a grid membrane of random size, material, thickness and
stiffness; a solver of random time step, precision, tolerance, acceleration and method; maybe a
collider; maybe contact) and a sequence of calls (steps, pins and unpins with valid and
invalid indices, settings of positions and velocities with good and bad arrays, saves and
loads of the state, mesh colliders of odd sizes). Every example asserts what peridyn promises (docs/model.md, "Bad input,
divergence and state files"):

- a call either succeeds or raises ``ValueError``, ``TypeError`` or ``peridyn.DivergenceError``;
  never anything else (a Rust panic reaches Python as ``RuntimeError``);
- the bodies' positions and velocities are finite after every call, whether it succeeded or
  raised (a diverging step leaves the last good state);
- save, continue, then load into a freshly built identical solver and continue the same
  steps: the two runs end bit for bit equal.

The examples are derandomised (the same ones on every run) and bounded so that the module
runs in about a minute on two cores.
"""

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import peridyn

ALLOWED = (ValueError, TypeError, peridyn.DivergenceError)

FUZZ = settings(
    max_examples=800,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


@st.composite
def scenes(draw):
    """Keyword arguments that build one scene (see :func:`build`)."""
    return {
        "nx": draw(st.integers(2, 7)),
        "ny": draw(st.integers(2, 7)),
        "size": draw(st.floats(0.05, 2.0)),
        "thickness": draw(st.sampled_from([1e-4, 1e-3, 5e-3])),
        "density": draw(st.floats(50.0, 2000.0)),
        "neo_hookean": draw(st.booleans()),
        "stiffness": draw(st.sampled_from([1e2, 1e4, 1e6, 1e8])),
        "bending": draw(st.sampled_from([0.0, 1e-6, 1e-3])),
        "dt": draw(st.sampled_from([1e-4, 1e-3, 1e-2, 1 / 30])),
        "precision": draw(st.sampled_from(["f64", "f32"])),
        "tol": draw(st.sampled_from([0.0, 1e-6, 1e-4])),
        "max_iters": draw(st.integers(1, 12)),
        "chebyshev": draw(st.booleans()),
        "descent": draw(st.booleans()),
        "collider": draw(st.sampled_from([None, "plane", "sphere"])),
        "contact": draw(st.booleans()),
        "pins": draw(st.lists(st.integers(0, 48), max_size=4)),
    }


def build(scene):
    """The scene's solver with its one membrane."""
    vertices, triangles = peridyn.grid(scene["nx"], scene["ny"], size=(scene["size"],) * 2)
    s = scene["stiffness"]
    material = peridyn.NeoHookean(s0=s, s1=s / 4) if scene["neo_hookean"] else peridyn.StretchA3(s0=s)
    cloth = peridyn.Membrane(vertices, triangles, thickness=scene["thickness"],
                             density=scene["density"], material=material,
                             bending=scene["bending"])
    pins = sorted({p for p in scene["pins"] if p < len(vertices)})
    if pins:
        cloth.pin(pins)
    contact = peridyn.Contact(thickness=scene["thickness"]) if scene["contact"] else None
    solver = peridyn.Solver(
        dt=scene["dt"], tol=scene["tol"], max_iters=scene["max_iters"],
        precision=scene["precision"], threads=1,
        acceleration="chebyshev" if scene["chebyshev"] else None,
        method="descent" if scene["descent"] and not scene["contact"] else "sissm",
        contact=contact,
    )
    solver.add(cloth)
    if scene["collider"] == "plane":
        solver.add_collider(peridyn.Plane(point=(0, 0, -0.05), normal=(0, 0, 1), friction=0.3))
    elif scene["collider"] == "sphere":
        solver.add_collider(peridyn.Sphere(center=(0.5 * scene["size"],) * 2 + (-0.3,),
                                           radius=0.25))
    return solver, cloth


def numbers(n):
    """Arrays a user might pass where an (n, 3) float array is meant: good and bad ones."""
    good = st.builds(lambda k: np.random.default_rng(k).normal(size=(n, 3)) * 0.1,
                     st.integers(0, 2**16))
    bad = st.sampled_from([
        np.full((n, 3), np.nan), np.full((n, 3), np.inf), np.zeros((n, 2)), np.zeros((n + 1, 3)),
        np.zeros((n, 3), dtype=complex), np.zeros((n, 3), dtype=bool), "abc", None,
        np.full((n, 3), 1e300), [[1, 2, 3]] * n,
    ])
    return st.one_of(good, bad)


def calls(n):
    """One call on a solver with one body of `n` vertices."""
    index = st.one_of(st.integers(-3, n + 3), st.sampled_from([2**31, 2**32, -(2**40)]))
    return st.one_of(
        st.tuples(st.just("step"), st.integers(1, 3)),
        st.tuples(st.just("pin"), st.lists(index, max_size=3)),
        st.tuples(st.just("unpin"), st.lists(index, max_size=3)),
        st.tuples(st.just("positions"), numbers(n)),
        st.tuples(st.just("velocities"), numbers(n)),
        st.tuples(st.just("dt"), st.sampled_from([1e-3, 0.0, -1.0, np.nan, 1e-40, 1e-45, 1e9])),
        st.tuples(st.just("mesh_collider"),
                  st.tuples(st.sampled_from([2, 3, 8, 0, -1]),
                            st.sampled_from([None, 0.0, 0.05, 1e30, -1.0, np.inf]))),
    )


def apply(solver, cloth, call):
    name, arg = call
    if name == "step":
        for _ in range(arg):
            solver.step()
    elif name == "pin":
        cloth.pin(arg)
    elif name == "unpin":
        cloth.unpin(arg)
    elif name == "positions":
        cloth.positions = cloth.positions + arg if isinstance(arg, np.ndarray) else arg
    elif name == "velocities":
        cloth.velocities = arg
    elif name == "dt":
        solver.dt = arg
    elif name == "mesh_collider":
        resolution, margin = arg
        box = trimesh.creation.box(extents=(0.2, 0.2, 0.1))
        solver.add_collider(peridyn.MeshCollider(box.vertices, box.faces,
                                                 resolution=resolution, margin=margin))


def assert_finite(cloth):
    assert np.all(np.isfinite(cloth.positions)), "non-finite positions without an exception"
    assert np.all(np.isfinite(cloth.velocities)), "non-finite velocities without an exception"


@FUZZ
@given(scene=scenes(), data=st.data())
def test_random_call_sequences_raise_only_documented_errors_and_stay_finite(scene, data):
    solver, cloth = build(scene)
    n = len(cloth.positions)
    for call in data.draw(st.lists(calls(n), min_size=1, max_size=6), label="calls"):
        try:
            apply(solver, cloth, call)
        except ALLOWED:
            pass
        except Exception as e:  # pragma: no cover - the assertion names what went wrong
            pytest.fail(f"{call[0]} raised {type(e).__name__}: {e}")
        assert_finite(cloth)


@FUZZ
@given(scene=scenes(), before=st.integers(0, 3), after=st.integers(1, 3))
def test_save_continue_and_restore_are_bit_exact(scene, before, after, tmp_path_factory):
    path = tmp_path_factory.mktemp("fuzz") / "state.npz"
    solver, cloth = build(scene)
    try:
        for _ in range(before):
            solver.step()
        peridyn.save_state(path, solver)
        for _ in range(after):
            solver.step()
    except peridyn.DivergenceError:
        return  # a scene too stiff for its time step: nothing to continue from
    fresh, fresh_cloth = build(scene)
    peridyn.load_state(path, fresh)
    for _ in range(after):
        fresh.step()
    assert np.array_equal(fresh_cloth.positions, cloth.positions)
    assert np.array_equal(fresh_cloth.velocities, cloth.velocities)
