"""The time stepper, with a Python ``run`` loop: progress bar, callbacks and a summary.

:class:`Solver` is the Rust :class:`peridyn._core.Solver` (same keyword-only constructor,
same ``step()``), extended in Python by :meth:`Solver.run`.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, field
from typing import Any, Callable, Optional

import numpy as np

from . import _core

__all__ = ["Solver", "RunSummary", "gravity_tolerance"]

#: Standard gravity (m/s^2).
G = 9.81


def gravity_tolerance(dt: float, fraction: float = 0.1) -> float:
    """A ``Solver(tol=)`` (m) for a scene driven by gravity: ``fraction * g * dt**2``.

    ``g dt^2`` is how far gravity moves a point within one step. A ``tol`` above it lets a
    step stop at its first iterate, before the forces have moved anything, and a passive
    scene gain energy; a tenth of it only dissipates and gives the converged motion
    (``benches/tolerance_energy.py``; docs/performance.md, "Tolerance and energy").

    Parameters
    ----------
    dt : float
        Time step in s (> 0).
    fraction : float
        Share of ``g dt^2`` (> 0).
    """
    if not dt > 0.0:
        raise ValueError(f"gravity_tolerance: dt must be > 0 s, got {dt!r}")
    if not fraction > 0.0:
        raise ValueError(f"gravity_tolerance: fraction must be > 0, got {fraction!r}")
    return fraction * G * dt * dt


@dataclass(frozen=True)
class RunSummary:
    """What a :meth:`Solver.run` call did.

    Attributes
    ----------
    steps : int
        Time steps taken by this call (fewer than asked when a callback stopped the run).
    steps_requested : int
        Time steps asked for.
    wall_seconds : float
        Wall-clock time of the whole call in s (callbacks and progress bar included).
    ms_per_step_median, ms_per_step_mean : float
        Wall-clock milliseconds per ``step()`` call (callbacks excluded); NaN when no step ran.
    mean_iterations : float
        Mean number of global iterations per step.
    max_iterations : int
        Largest number of global iterations in one step.
    converged_fraction : float
        Fraction of steps whose residual (``StepStats.residual``) fell below the solver's ``tol``.
    final_move : float
        Last move of the last step in m (``StepStats.last_move``: the largest vertex move of its
        last iteration).
    time : float
        Simulation time at the end of the call in s.
    iterations : numpy.ndarray
        (steps,) int64 global iterations of each step.
    moves : numpy.ndarray
        (steps,) float64 last move of each step in m (``StepStats.last_move``).
    ms_per_step : numpy.ndarray
        (steps,) float64 wall-clock milliseconds of each ``step()`` call.
    """

    steps: int
    steps_requested: int
    wall_seconds: float
    ms_per_step_median: float
    ms_per_step_mean: float
    mean_iterations: float
    max_iterations: int
    converged_fraction: float
    final_move: float
    time: float
    iterations: np.ndarray = field(repr=False, compare=False)
    moves: np.ndarray = field(repr=False, compare=False)
    ms_per_step: np.ndarray = field(repr=False, compare=False)

    @property
    def stopped_early(self) -> bool:
        """True when a callback stopped the run before ``steps_requested`` steps."""
        return self.steps < self.steps_requested

    def __str__(self) -> str:
        lines = [
            f"steps            {self.steps}"
            + (f" of {self.steps_requested} (stopped by callback)" if self.stopped_early else ""),
            f"simulated time   {self.time:.4g} s",
            f"wall time        {self.wall_seconds:.3f} s",
            f"ms per step      {self.ms_per_step_median:.2f} median, {self.ms_per_step_mean:.2f} mean",
            f"iterations/step  {self.mean_iterations:.2f} mean, {self.max_iterations} max",
            f"converged        {100.0 * self.converged_fraction:.1f} % of steps",
            f"final move       {self.final_move:.3g} m",
        ]
        return "\n".join(lines)


Callback = Callable[["Solver", Any], Optional[bool]]


class Solver(_core.Solver):
    """Implicit Euler time stepping of membranes by projective peridynamics (SISSM).

    Constructed exactly like :class:`peridyn._core.Solver` (all arguments keyword-only):

    Parameters
    ----------
    dt : float
        Time step in s (> 0).
    gravity : (3,) float
        Acceleration in m/s^2; default ``(0, 0, -9.81)``.
    tol : float
        Convergence tolerance in m on the error bound ``StepStats.residual`` (largest
        residual over mass); 0 always runs ``max_iters`` iterations. Default 1e-4. A step's
        velocity error is up to ``tol / dt``: keep ``tol <= 0.1 * g * dt**2`` (1e-6 m at
        ``dt = 1e-3`` s; :func:`gravity_tolerance`), or a step may stop before the forces have
        moved anything and a passive scene gain energy (docs/performance.md, "Tolerance and
        energy").
    max_iters : int
        Cap on global iterations per step. Default 100.
    threads : int or None
        Worker threads (None: all cores). Results are identical for any count.
    step_length : bool
        Use the per-vertex step length (recommended). Default True.
    backend : str
        "cpu" (default) or "gpu": the same step as wgpu compute shaders with the state on the
        device, in f32 (default) or f64 where the adapter has it (see :func:`peridyn.gpu_info`;
        RuntimeError when there is no adapter). A GPU step leaves the bodies' positions and
        velocities on the device; reading them (or anything that needs them) reads them back.
        Every collider works on the GPU; contact, ``method="descent"`` or ``"newton"`` and
        ``inner_iters > 1`` raise ValueError there.

    Notes
    -----
    This Python class adds :meth:`run`; ``add``, ``add_collider``, ``step`` and the
    properties come from the Rust core. It defines no ``__init__``: the core's constructor
    receives the keyword arguments directly.
    """

    def run(
        self,
        steps: int,
        *,
        progress: bool = False,
        callback: Optional[Callback] = None,
    ) -> RunSummary:
        """Take ``steps`` time steps.

        Parameters
        ----------
        steps : int
            Number of steps (>= 0).
        progress : bool
            Show a tqdm progress bar whose postfix gives the mean iterations per step and the
            mean wall-clock milliseconds per step so far.
        callback : callable, optional
            ``callback(solver, stats)`` after each step, ``stats`` being that step's
            :class:`peridyn.StepStats`. Returning ``False`` (exactly) stops the run after
            that step; any other return value continues.

        Returns
        -------
        RunSummary

        Raises
        ------
        DivergenceError
            If a step produced non-finite positions (the bodies keep their last good state).
        """
        if isinstance(steps, bool) or int(steps) != steps or steps < 0:
            raise ValueError(f"Solver.run: steps must be an integer >= 0, got {steps!r}")
        steps = int(steps)
        iterations = np.zeros(steps, dtype=np.int64)
        moves = np.zeros(steps, dtype=np.float64)
        converged = np.zeros(steps, dtype=bool)
        ms = np.zeros(steps, dtype=np.float64)

        bar = None
        if progress:
            import warnings

            from tqdm import TqdmWarning

            with warnings.catch_warnings():
                # In Jupyter without ipywidgets tqdm.auto falls back to the text bar and warns.
                warnings.simplefilter("ignore", TqdmWarning)
                from tqdm.auto import tqdm

            bar = tqdm(total=steps, unit="step", desc="peridyn", dynamic_ncols=True)
        done = 0
        t_start = _time.perf_counter()
        try:
            for k in range(steps):
                t0 = _time.perf_counter()
                stats = self.step()
                ms[k] = 1e3 * (_time.perf_counter() - t0)
                iterations[k] = stats.iterations
                moves[k] = stats.last_move
                converged[k] = stats.converged
                done = k + 1
                if bar is not None:
                    bar.update(1)
                    bar.set_postfix(
                        it=f"{iterations[:done].mean():.1f}", ms=f"{ms[:done].mean():.1f}", refresh=False
                    )
                if callback is not None and callback(self, stats) is False:
                    break
        finally:
            if bar is not None:
                bar.close()
        wall = _time.perf_counter() - t_start

        iterations, moves, converged, ms = iterations[:done], moves[:done], converged[:done], ms[:done]
        nan = float("nan")
        return RunSummary(
            steps=done,
            steps_requested=steps,
            wall_seconds=wall,
            ms_per_step_median=float(np.median(ms)) if done else nan,
            ms_per_step_mean=float(ms.mean()) if done else nan,
            mean_iterations=float(iterations.mean()) if done else nan,
            max_iterations=int(iterations.max()) if done else 0,
            converged_fraction=float(converged.mean()) if done else nan,
            final_move=float(moves[-1]) if done else nan,
            time=float(self.time),
            iterations=iterations,
            moves=moves,
            ms_per_step=ms,
        )
