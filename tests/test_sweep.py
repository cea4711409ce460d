"""Parameter sweeps (peridyn.sweep) on local processes, a local Ray and a local Dask cluster.

Ray and Dask are the optional extra ``peridyn[distributed]``; the test extra installs them, so
these tests run in CI (missing, this module fails). Each backend runs the same real, tiny
simulations; the solver is deterministic, so every backend must return the very same numbers
as a call in this process.
"""

import pytest

import peridyn
from peridyn.sweeps import expand_grid


def hanging_cloth():
    """The sweep function: a 6 x 6 cloth pinned along one edge hangs for 40 steps; returns
    its sag (m) and mean iterations. Defined in a factory, so cloudpickle ships it by value
    (a Ray or Dask worker cannot import this test module)."""

    def run(s0, dt):
        import numpy as np

        import peridyn

        if s0 <= 0.0:
            raise ValueError(f"s0 must be > 0, got {s0}")
        V, F = peridyn.grid(6, 6, size=(0.3, 0.3))
        cloth = peridyn.Membrane(V, F, thickness=1e-3, density=200.0, material=peridyn.StretchA3(s0=s0))
        cloth.pin(np.flatnonzero(np.isclose(V[:, 1], 0.3)))
        solver = peridyn.Solver(dt=dt, threads=1)
        solver.add(cloth)
        summary = solver.run(40)
        return {"sag": float(-cloth.positions[:, 2].min()), "iterations": summary.mean_iterations}

    return run


GRID = {"s0": [2e3, -1.0, 2e4], "dt": [2e-3, 4e-3]}


@pytest.fixture(scope="module")
def expected():
    run = hanging_cloth()
    out = []
    for params in expand_grid(GRID):
        try:
            out.append(run(**params))
        except ValueError as err:
            out.append(str(err))
    return out


def check(results, expected):
    """Grid order, the failing sets reported with their message, the others' exact values."""
    assert [r.index for r in results] == list(range(6))
    assert [r.params for r in results] == expand_grid(GRID)
    for r, want in zip(results, expected):
        if isinstance(want, str):
            assert not r.ok and r.value is None and r.error == f"ValueError: {want}"
            assert "s0 must be > 0" in r.traceback
        else:
            assert r.ok and r.value == want


def test_the_grid_is_the_product_in_order_and_bad_grids_are_refused():
    assert expand_grid({"a": [1, 2], "b": ["x", "y"]}) == [
        {"a": 1, "b": "x"}, {"a": 1, "b": "y"}, {"a": 2, "b": "x"}, {"a": 2, "b": "y"}]
    assert expand_grid([{"a": 1}, {"b": 2}]) == [{"a": 1}, {"b": 2}]
    with pytest.raises(ValueError, match=r"grid\['a'\]"):
        expand_grid({"a": []})
    with pytest.raises(ValueError, match=r"grid\[1\]"):
        expand_grid([{"a": 1}, 5])
    with pytest.raises(ValueError, match="backend"):
        peridyn.sweep(hanging_cloth(), GRID, backend="spark")
    with pytest.raises(ValueError, match="workers"):
        peridyn.sweep(hanging_cloth(), GRID, workers=0)


def test_the_physics_differs_across_the_grid(expected):
    """The sweep measures something: a softer cloth sags more, a longer step reaches further
    (160 ms of fall, not 80 ms) and a stiffer cloth sags less."""
    soft_fine, soft_coarse, _, _, stiff_fine, stiff_coarse = expected
    assert soft_coarse["sag"] > soft_fine["sag"] > 0.0
    assert soft_fine["sag"] > stiff_fine["sag"] and soft_coarse["sag"] > stiff_coarse["sag"]


def test_local_processes(expected):
    check(peridyn.sweep(hanging_cloth(), GRID, backend="local", workers=2, progress=False), expected)


def test_a_local_ray(expected):
    import ray

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        check(peridyn.sweep(hanging_cloth(), GRID, backend="ray", progress=False), expected)
    finally:
        ray.shutdown()


def test_a_local_dask_cluster(expected):
    from dask.distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster, Client(cluster) as client:
        check(peridyn.sweep(hanging_cloth(), GRID, backend="dask", client=client, progress=False), expected)
