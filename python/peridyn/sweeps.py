"""Parameter sweeps: one function run per parameter set, in processes here or on Ray or Dask.

:func:`sweep` takes a function (typically: build a scene from keyword arguments, run it,
return numbers, statistics or file paths) and a grid of parameter sets, runs every set once
and returns the results in grid order. A set that raises is reported as failed, with its
exception and traceback, and the other sets go on. The function is shipped to the workers with
cloudpickle, so a function defined in a notebook works on every backend.

Backends:

- ``"local"``: worker processes on this machine (``concurrent.futures``, spawned, so no
  thread pool of the parent is inherited);
- ``"ray"``: Ray tasks on the cluster ``ray.init`` connected to (``ray.init(address=...)``),
  or on a local Ray started for the sweep if none is;
- ``"dask"``: Dask futures on the ``dask.distributed.Client`` passed as ``client``, or the
  current default client.

Ray and Dask come with the optional extra ``peridyn[distributed]``.
"""

from __future__ import annotations

import itertools
import os
import traceback
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass
from typing import Any, Callable, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple, Union

__all__ = ["sweep", "SweepResult", "expand_grid"]

Grid = Union[Sequence[Mapping[str, Any]], Mapping[str, Sequence[Any]]]


@dataclass(frozen=True)
class SweepResult:
    """The outcome of one parameter set.

    Attributes
    ----------
    index : int
        Position of the set in the grid.
    params : dict
        The keyword arguments the function was called with.
    value : Any
        What the function returned (None when it failed).
    error : str or None
        ``"ExceptionType: message"`` when the function raised (or its worker died), else None.
    traceback : str or None
        The worker's formatted traceback when the function raised.
    """

    index: int
    params: Dict[str, Any]
    value: Any = None
    error: Optional[str] = None
    traceback: Optional[str] = None

    @property
    def ok(self) -> bool:
        """True when the function returned."""
        return self.error is None


def expand_grid(grid: Grid) -> List[Dict[str, Any]]:
    """The parameter sets of ``grid``: a list of dicts as given, or for a dict of lists every
    combination (``itertools.product`` order: the last key varies fastest).

    Raises ``ValueError`` naming the offending entry: a set that is not a dict with string
    keys, or a dict value that is not a non-empty list or tuple.
    """
    if isinstance(grid, Mapping):
        keys = list(grid)
        for key in keys:
            if not isinstance(key, str):
                raise ValueError(f"sweep: grid key {key!r} is not a string")
            values = grid[key]
            if isinstance(values, (str, bytes)) or not isinstance(values, Sequence) or len(values) == 0:
                raise ValueError(f"sweep: grid[{key!r}] must be a non-empty list of values, got {values!r}")
        return [dict(zip(keys, combo)) for combo in itertools.product(*(grid[k] for k in keys))]
    if isinstance(grid, (str, bytes)) or not isinstance(grid, Sequence):
        raise ValueError(f"sweep: grid must be a list of dicts or a dict of lists, got {type(grid).__name__}")
    sets = []
    for i, params in enumerate(grid):
        if not isinstance(params, Mapping) or not all(isinstance(k, str) for k in params):
            raise ValueError(f"sweep: grid[{i}] must be a dict of keyword arguments, got {params!r}")
        sets.append(dict(params))
    return sets


def _call(payload: bytes, params: Dict[str, Any]) -> Tuple[Any, Optional[str], Optional[str]]:
    """Runs in a worker: the function unpickled, called with ``params``; ``(value, error,
    traceback)``, the exception caught so that one set's failure reaches the caller as data."""
    import cloudpickle

    fn = cloudpickle.loads(payload)
    try:
        return fn(**params), None, None
    except Exception as err:  # noqa: BLE001 - every failure of a set is reported, none lost
        return None, f"{type(err).__name__}: {err}", traceback.format_exc()


def _local(payload: bytes, sets: List[Dict[str, Any]], workers: Optional[int]) -> Iterator[Tuple[int, Any]]:
    import multiprocessing

    n = workers or os.cpu_count() or 1
    with ProcessPoolExecutor(max_workers=min(n, len(sets)), mp_context=multiprocessing.get_context("spawn")) as pool:
        pending = {pool.submit(_call, payload, params): i for i, params in enumerate(sets)}
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                i = pending.pop(fut)
                try:
                    yield i, fut.result()
                except Exception as err:  # noqa: BLE001 - the worker process died
                    yield i, (None, f"{type(err).__name__}: {err}", None)


def _ray(payload: bytes, sets: List[Dict[str, Any]], workers: Optional[int]) -> Iterator[Tuple[int, Any]]:
    import ray

    if not ray.is_initialized():
        ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
    remote = ray.remote(_call)
    ref = ray.put(payload)
    pending = {remote.remote(ref, params): i for i, params in enumerate(sets)}
    while pending:
        done, _ = ray.wait(list(pending), num_returns=1)
        for obj in done:
            i = pending.pop(obj)
            try:
                yield i, ray.get(obj)
            except Exception as err:  # noqa: BLE001 - the task or its worker died
                yield i, (None, f"{type(err).__name__}: {err}", None)


def _dask(payload: bytes, sets: List[Dict[str, Any]], client: Any) -> Iterator[Tuple[int, Any]]:
    from dask.distributed import as_completed, get_client

    client = client if client is not None else get_client()
    futures = [client.submit(_call, payload, params, pure=False) for params in sets]
    index = {fut.key: i for i, fut in enumerate(futures)}
    for fut in as_completed(futures):
        i = index[fut.key]
        try:
            yield i, fut.result()
        except Exception as err:  # noqa: BLE001 - the task or its worker died
            yield i, (None, f"{type(err).__name__}: {err}", None)


def sweep(
    run: Callable[..., Any],
    grid: Grid,
    *,
    backend: str = "local",
    workers: Optional[int] = None,
    client: Any = None,
    progress: bool = True,
) -> List[SweepResult]:
    """Run ``run(**params)`` once per parameter set of ``grid``, in parallel.

    Parameters
    ----------
    run : callable
        Takes one set's parameters as keyword arguments and returns something picklable
        (numbers, a dict of statistics, file paths). Each call runs in its own worker: give
        the solver ``threads=1`` (or a few) so that the workers do not oversubscribe the cores.
    grid : list of dicts, or dict of lists
        The parameter sets (see :func:`expand_grid`; a dict of lists means their product).
    backend : {"local", "ray", "dask"}
        Where the sets run (see the module notes).
    workers : int, optional
        ``"local"``: worker processes (default: the number of cores); ``"ray"``: CPUs of the
        local Ray started when none is connected (default: all).
    client : dask.distributed.Client, optional
        ``"dask"`` only: the cluster to run on (default: the current client).
    progress : bool
        Show a tqdm progress bar over the sets.

    Returns
    -------
    list of SweepResult
        One per set, in grid order; ``result.ok`` tells whether it returned, ``result.error``
        why not. A failed set never stops the others.

    Raises
    ------
    ValueError
        For a bad grid (naming the entry), an unknown backend, ``workers < 1``, or a ``client``
        with a backend other than ``"dask"``.
    ImportError
        For ``"ray"`` or ``"dask"`` without the extra (``pip install "peridyn[distributed]"``).
    """
    import cloudpickle

    if not callable(run):
        raise ValueError(f"sweep: run must be callable, got {run!r}")
    if backend not in ("local", "ray", "dask"):
        raise ValueError(f"sweep: backend must be 'local', 'ray' or 'dask', got {backend!r}")
    if workers is not None and (isinstance(workers, bool) or int(workers) != workers or workers < 1):
        raise ValueError(f"sweep: workers must be an integer >= 1, got {workers!r}")
    if client is not None and backend != "dask":
        raise ValueError(f"sweep: client is for backend='dask', not {backend!r}")
    sets = expand_grid(grid)
    results: List[Optional[SweepResult]] = [None] * len(sets)
    if not sets:
        return []
    payload = cloudpickle.dumps(run)
    if backend == "local":
        stream = _local(payload, sets, workers)
    elif backend == "ray":
        stream = _ray(payload, sets, workers)
    else:
        stream = _dask(payload, sets, client)
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(sets), desc=f"sweep ({backend})", unit="set")
    try:
        for i, (value, error, tb) in stream:
            results[i] = SweepResult(i, sets[i], value, error, tb)
            if bar is not None:
                bar.update(1)
                failed = sum(r is not None and not r.ok for r in results)
                if failed:
                    bar.set_postfix(failed=failed)
    finally:
        if bar is not None:
            bar.close()
    return [r for r in results if r is not None]
