"""The solver, its step statistics, and the GPU adapter it would use."""

from typing import Dict, Literal, Optional, Tuple, Union

import numpy as np

from ._options import (
    ArrayLike,
    Vec3,
    Method,
    Preconditioner,
    Acceleration,
    Backend,
    GlobalSolver,
    Precision,
)
from ._bodies import Membrane, Particles
from ._colliders import Collider, Contact

class StepStats:
    """What one time step did."""

    @property
    def iterations(self) -> int: ...
    @property
    def last_move(self) -> float:
        """The last iteration's max_i |y_i^k - y_i^(k-1)| in m (the convergence measure of
        Algorithm 1): the last of ``moves``."""
    @property
    def converged(self) -> bool:
        """True when ``residual`` fell below ``tol`` (always False when tol == 0)."""
    @property
    def moves(self) -> np.ndarray:
        """Largest vertex move of each iteration (m)."""
    @property
    def residual(self) -> float:
        """max_i |r_i| / m_i (m) for the residual r = m (y* - y) + h^2 f at the last evaluated
        iterate, without the contact reactions (the colliders' reaction to the vertex's Jacobi
        move, normal and Coulomb friction within the cone, and the part of the contact local
        step's move that its barrier push and the normals of the colliders the vertex rests on
        explain): an upper bound on the mass-weighted RMS distance to the exact implicit Euler
        solution where the energy is convex. The last of ``residuals``."""
    @property
    def residuals(self) -> np.ndarray:
        """``residual`` after each iteration (m): whether a step that ran to max_iters was
        still converging or had stalled. With contact the first one measures the whole
        residual (no local step has run before it) and cannot decide convergence."""
    @property
    def energies(self) -> np.ndarray:
        """Total variational energy E(y^k) (J) of every iterate k = 0..iterations; empty unless
        the solver records it (``record_energy=True``)."""
    @property
    def linear_products(self) -> int:
        """``method="newton"``: Hessian products of its conjugate-gradient solves in the step
        (0 for the other methods)."""
    @property
    def newton(self) -> dict:
        """``method="newton"``: milliseconds per phase of its iterations, summed over the step:
        'jacobi' (SISSM's systems and residual), 'models' (the Hessian models),
        'coarse_assembly', 'coarse_factor', 'cg', 'line_search'; counts 'factorizations' (of
        the coarse matrix) and 'trials' (line-search kernel passes). Zeros for the other
        methods."""
    @property
    def timings(self) -> dict:
        """Milliseconds per phase: 'predict', 'global' (of which 'kernel': the vertex kernel, CPU SISSM only, else 0; a granular body's return within the iterations is part of its kernel passes), 'colliders', 'finish' (of which 'plasticity': the plastic return stored at the step's end and the rest rebuild of plastic particle bodies, their share of 'neighbours': the search on deformed positions, and their share of 'density': the SPH density and stiffness of granular bodies; t_p, t_n and t_d of He et al. 2017, Table 1), and for fluids, outside 'predict' and 'finish': 'neighbours' (their searches at the step's start and before the projection), 'viscosity' (at the step's start), 'density' (the projection), 'redistribution'; 'coupling' (particles against membrane triangles), 'contact' (the membrane contact local steps whole: the broad phase, CCD and descent of `contact` and the rest, the proximal metric, set-up passes and realised reaction), 'total'."""
    @property
    def particles(self) -> dict:
        """The particle bodies' share of the step (zeros without them), from its start:
        milliseconds 'kernel_ms', 'residual_ms', 'solve_ms', 'line_search_ms', 'project_ms';
        'evaluations' (kernel passes, line search trials included), 'factorizations'
        (numeric, of the direct solver's matrix or the two-level correction's coarse matrix),
        'analyses' (symbolic: a new pattern, on the first step and after a plastic body's
        neighbourhoods changed; a change of values alone, such as a granular body's stiffness
        or a flowing body's re-anchored bonds, refactors on the pattern at hand, so that the
        direct solve stays exact), 'held_static' (granular particles held by static
        friction, eq. 28), 'density_passes' (the fluids' density projections) and
        'density_error' (the largest relative excess density rho / rho0 - 1 left);
        'roundoff_floor' (m: the largest round-off floor eps |y_i| D_i / m_i that the last
        convergence measure subtracted; it grows with the distance from the particle family's
        frame origin, near its bodies (the world origin when membranes share the step), and above
        ``tol`` "converged" means within ``tol`` of what the precision resolves there) and
        'worst_particle' ((body, index) of the particle holding that measure's largest term,
        None when every particle is within its floor)."""
    @property
    def contact(self) -> dict:
        """Contact figures (zeros when contact is off): 'candidate_pairs' (triangle pairs of
        the broad phase's last build, largest over the iterations), 'box_pairs' (the triangle
        pairs of that build whose inflated boxes overlap, before the distance test that leaves
        the candidates; largest), 'cached_pairs' (primitive pairs of that build and of the
        repairs since, which each filter chooses from; largest), 'primitive_pairs'
        (primitive pairs that may come within the barrier's reach, largest), 'active_pairs'
        (primitive pairs within the barrier's reach at the end), 'local_iterations' (descent
        iterations, summed), 'clamped' (vertices the final CCD clamp moved, summed),
        'ccd_queries' (primitive pair CCD queries, summed), 'broad_phase_builds' (summed; the
        other local steps reused the last build), 'cache_repairs' (summed; repairs of the last
        build for a few vertices that strayed beyond their skins, each instead of a build),
        'live_refreshes' (filterings of the cached pairs into the live list, summed),
        'sweeps' (those filterings that looked at every cached pair near enough afresh,
        summed; the others looked again only at the pairs that may have come nearer since the
        last sweep), 'broad_phase_ms', 'ccd_ms', 'descent_ms', and 'barrier_energy' (J, the
        barrier's energy d mu B / h^2 at the step's end)."""
    @property
    def time(self) -> float:
        """Simulation time after the step (s)."""
    @property
    def step(self) -> int:
        """Index of the step (0-based)."""

class Solver:
    """Implicit Euler time stepping by the semi-implicit successive substitution method (SISSM).

    Parameters
    ----------
    dt : time step h in s (> 0), such that ``dt^2`` is a normal number and ``1/dt`` finite in the
        chosen precision (f32: about 1.1e-19 s <= dt <= 1.8e19 s; f64: 1.5e-154 s to 1.3e154 s);
        ValueError otherwise, here and in the ``dt`` setter.
    gravity : acceleration (m/s^2).
    tol : stop when the error bound ``StepStats.residual`` < tol (m): the mass-weighted RMS
        distance to the exact implicit Euler solution is then below tol; 0 runs exactly
        ``max_iters`` iterations.
    max_iters : cap on global iterations per step (>= 1).
    threads : worker threads, 1 to 1024 (None: all cores). Results are bit-identical for any count.
    step_length : apply the per-vertex step length of eq. 31-33.
    precision : "f64" (reference) or "f32" (fast path); None: "f64" on the CPU, "f32" on the GPU.
    preconditioner : "tangent" (curvature bounds of the energy: convergent at any stiffness and
        time step) or "paper" (the P+/lambda split of eq. 24-26: cheaper, can diverge when stiff).
    acceleration : None (plain SISSM iterations) or "chebyshev" (Wang 2015 semi-iterative
        acceleration: 5-9x fewer iterations to a given error on benches/convergence.py; in f32
        it amplifies round-off near the precision floor). With contact (method "sissm" only)
        it extrapolates the local step's result; the local step keeps the intersection-free
        positions and a step always ends on them. Pick rho near the plain iteration's
        per-iteration decay of ``StepStats.residuals`` (about 0.8 on stacked layers
        landing, where rho = 0.85 saved a fifth of the iterations).
    chebyshev_rho : spectral-radius estimate in (0, 1) for Chebyshev (higher: stronger, riskier);
        None: 0.99. A value given applies to membranes with ``acceleration="chebyshev"`` and
        to particle bodies with ``global_solver="chebyshev"`` or an acceleration; given with
        neither, ValueError.
    chebyshev_delay : plain iterations before extrapolating (>= 1); None: 3. Like
        ``chebyshev_rho``, a value given applies to membranes with ``acceleration="chebyshev"``
        and to particle bodies with ``global_solver="chebyshev"`` or an acceleration; given
        with neither, ValueError.
    record_energy : record the variational energy of every iterate in ``StepStats.energies``.
    method : "sissm" (the paper's method) or "descent" (the baseline of Fig. 13, Wang and Yang
        2016: gradient descent preconditioned by the diagonal of the energy's Hessian, with a
        step length halved whenever the energy would rise and Chebyshev restarted then; the
        Hessian diagonal is taken by finite differences, so an iteration costs tens of SISSM
        iterations) or "newton" (Newton steps on the implicit Euler energy: a projected Hessian
        solved by conjugate gradients preconditioned with SISSM's blocks, then a line search
        that never lets the energy rise; colliders, contact and the convergence test as SISSM;
        no Chebyshev, ValueError; for fine or stiff cloth asked to converge, see
        docs/performance.md) or "auto" (per step: Newton where ``0 < tol <= 1e-5`` m and the
        cloth is stiff and fine enough that SISSM's slowest error would need more than 100
        iterations, ``min(h^2 k / m, N / pi^2) > 100`` over the N membrane vertices; else SISSM,
        with the acceleration asked for; SISSM with particle bodies and on the GPU).
    inner_iters : Jacobi sweeps on the linear system of eq. 25 per global iteration (Fig. 6).
    backend : "cpu" (Rust, rayon threads) or "gpu" (wgpu compute shaders, state on the device;
        f32 by default, f64 where the adapter has SHADER_F64; raises RuntimeError naming what
        is missing when there is no adapter, see :func:`gpu_info`). The adapter follows
        WGPU_BACKEND, WGPU_POWER_PREF and WGPU_ADAPTER_NAME. The GPU runs SISSM (optionally
        Chebyshev) with every collider (friction and motion included) and leaves the bodies'
        positions and velocities on the device until they are read; it refuses contact,
        method="descent" or "newton" and inner_iters > 1 (ValueError).
    global_solver : how particle bodies solve the linear system of their global step (He et
        al. 2017, Fig. 7; membranes ignore it): "direct" (a sparse Cholesky factor of
        ``M + h^2 L``, computed when dt, the pins or a body's bonds change; an exact solve per
        iteration, then the bodies' coarse correction at collider contact), "jacobi" (``inner_iters`` Jacobi sweeps),
        "chebyshev" (Jacobi with Chebyshev acceleration, ``chebyshev_rho`` when given, else
        0.99) or "position" (position-based averaging over
        bonds). Every one has the implicit Euler solution as its fixed point; each iteration's
        step length is chosen by Armijo backtracking (eq. 13) on the residual of eq. 12.
        ``method="descent"`` and the GPU backend refuse particle bodies.
    contact : a ``Contact`` to keep every body's triangles apart from the other bodies' (and
        its own, unless built with ``self_contact=False``); None: no contact between membranes.
    particle_tol : particle bodies only (> 0, m/s^2; default 0.0981, a hundredth of g): a step
        stops once every particle's force imbalance per unit mass ``|r_i| / (m_i dt^2)``
        (Newton's law at the step's accelerations, colliders' reactions taken out, less its
        round-off floor) is below it and its distance measure below ``tol``: particle steps
        stop at ``min(tol, particle_tol * dt^2)`` m, so that a short step is not "converged"
        before it has moved (docs/particles/solids.md, "Convergence measure").
    two_level : particle bodies with ``global_solver`` "jacobi" or "chebyshev" only (default
        True): add a two-level correction on aggregates of about 30 particles to every sweep
        (issue 38): fewer iterations where a body's slow elastic modes hold the step (a
        landing, a stretched or pinned body), for a sparse Cholesky factor of the coarse
        matrix whenever the time step or the held set (pins, contacts) changes and two passes
        over the bonds per iteration. Steps whose move is round-off (at rest, free fall) skip
        it. False: the paper's one-level sweep.
    max_speed : the fastest a free point may end a step (> 0 m/s, or ``inf`` to leave speeds
        unchecked; default 1e4, 10 km/s): a faster one raises ``DivergenceError`` naming it
        and its speed, and the bodies keep their last good state. A blown-up step can leave
        positions finite but absurd (1e129 m has been seen), which the finiteness check alone
        misses; pinned points (their motion prescribed) are exempt, but the free points a
        teleported pin target or collider pose drags along are not: raise it for such scenes.
        A move within a few ulps of the coordinates is never too fast (a tiny ``dt``). The
        CPU checks the step's end; the GPU backend checks every iterate of the step (an
        iterate that far from the step's start is already a blow-up), so it stops a runaway
        step at its first such iteration.
    """

    def __init__(
        self,
        *,
        dt: float,
        gravity: Vec3 = (0.0, 0.0, -9.81),
        tol: float = 1e-4,
        max_iters: int = 100,
        threads: Optional[int] = None,
        step_length: bool = True,
        precision: Optional[Precision] = None,
        preconditioner: Preconditioner = "tangent",
        acceleration: Optional[Acceleration] = None,
        chebyshev_rho: Optional[float] = None,
        chebyshev_delay: Optional[int] = None,
        record_energy: bool = False,
        method: Method = "sissm",
        inner_iters: int = 1,
        backend: Backend = "cpu",
        contact: Optional[Contact] = None,
        global_solver: GlobalSolver = "chebyshev",
        particle_tol: float = 0.0981,
        two_level: bool = True,
        max_speed: float = 1e4,
    ) -> None: ...
    def add(self, body: Union[Membrane, Particles]) -> None: ...
    def add_collider(self, collider: Collider) -> None: ...
    def set_collider_pose(self, index: int, *, rotation: Optional[ArrayLike] = None, translation: Optional[Vec3] = None) -> None:
        """Sets the pose collider ``index`` (in the order added) reaches at the end of the next
        step: its geometry as given, turned by ``rotation`` (3x3, orthonormal within 1e-6,
        re-orthonormalised; det +1; default
        identity) and moved by ``translation`` (m; default 0). During the step it moves rigidly
        from its pose at the start; friction drags each contact along with the collider's own
        material point there, so a turning collider carries a membrane around. Afterwards a
        ``velocity`` carries it on from that pose. Call it before every step to drive a
        collider (a pose not set leaves it moving at its velocity). CPU backend only."""
    def collider_pose(self, index: int) -> Tuple[np.ndarray, np.ndarray]:
        """Current pose of collider ``index``: ``(rotation, translation)``, a point ``b`` of the
        geometry as given is now at ``rotation @ b + translation``; the distance to the
        collider where it is now is ``collider.signed_distance((x - translation) @ rotation)``."""
    def collider_motion(self, index: int) -> Tuple[Tuple[np.ndarray, np.ndarray], Optional[Tuple[np.ndarray, np.ndarray]]]:
        """What the motion of collider ``index`` depends on besides its velocity and the clock,
        for saving a simulation (:func:`peridyn.save_state`): ``(base, target)``, the pose at
        time 0 its velocity carries on from and the pose set with :meth:`set_collider_pose` for
        the end of the next step (None when none is pending), each ``(rotation, translation)``."""
    def set_collider_motion(self, index: int, *, base_rotation: ArrayLike, base_translation: Vec3, target_rotation: Optional[ArrayLike] = None, target_translation: Optional[Vec3] = None) -> None:
        """Restores a motion read with :meth:`collider_motion` (both parts of the target, or
        neither)."""
    def internal_state(self) -> Dict[str, np.ndarray]:
        """What the next steps depend on besides the bodies, the clock, ``dt`` and the
        colliders' motion, as named arrays (:func:`peridyn.save_state` saves them as entries
        ``internal_<name>``): ``contact_warm_start`` (N, 3) m, the contact local step's warm
        start per membrane vertex (the bodies in order; (0, 3) before the first contact step);
        the rest gaps of the contact pairs that started within the barrier's reach:
        ``contact_rest_gaps_seeded`` (bool), ``contact_rest_gap_reach`` (m),
        ``contact_rest_gap_vertices`` (G, 4) int64, ``contact_rest_gap_edge_edge`` (G,) bool,
        ``contact_rest_gap_distances`` (G,) m; the friction at the grains' contacts the next
        step starts from: ``grain_contact_pairs`` (P, 2) int64, particle indices over the
        particle bodies in order (each touching pair in both orders), and
        ``grain_contact_multipliers`` (P, 3) m (none at a body whose positions were set
        since the last step, which starts them at 0). The GPU backend has no contact: all
        empty."""
    def set_internal_state(self, state: Dict[str, ArrayLike]) -> None:
        """Restores a dict read with :meth:`internal_state` into a solver set up the same way
        (same bodies in the same order, parameters and colliders); the next step takes it.
        Checked whole before anything changes (``ValueError`` naming the entry); an empty dict
        resets it (the next contact step starts afresh); a dict without the two
        ``grain_contact_`` entries (saved before them) starts the grains' friction from 0."""
    def step(self) -> StepStats: ...
    @property
    def dt(self) -> float: ...
    @dt.setter
    def dt(self, value: float) -> None: ...
    @property
    def gravity(self) -> np.ndarray: ...
    @property
    def tol(self) -> float: ...
    @tol.setter
    def tol(self, value: float) -> None: ...
    @property
    def max_iters(self) -> int: ...
    @max_iters.setter
    def max_iters(self, value: int) -> None: ...
    @property
    def backend(self) -> Backend: ...
    @property
    def threads(self) -> int: ...
    @property
    def bytes_per_iteration(self) -> Optional[int]:
        """Bytes the GPU kernels load and store per global iteration (None on the CPU)."""
    @property
    def step_length(self) -> bool: ...
    @property
    def precision(self) -> Precision: ...
    @property
    def preconditioner(self) -> Preconditioner: ...
    @property
    def acceleration(self) -> Optional[Literal["chebyshev"]]: ...
    @property
    def record_energy(self) -> bool: ...
    @property
    def method(self) -> Method: ...
    @property
    def inner_iters(self) -> int: ...
    @property
    def global_solver(self) -> GlobalSolver:
        """How particle bodies solve their global step."""
    @property
    def particle_tol(self) -> float:
        """The particles' force-imbalance tolerance (m/s^2)."""
    @particle_tol.setter
    def particle_tol(self, value: float) -> None: ...
    @property
    def max_speed(self) -> float:
        """The fastest a free point may end a step (m/s; inf: unchecked); settable."""
    @max_speed.setter
    def max_speed(self, value: float) -> None: ...
    @property
    def contact(self) -> Optional[Contact]:
        """The contact parameters, or None when contact is off. Settable to another Contact
        between steps (re-tuning), but contact cannot be switched on or off (ValueError)."""
    @contact.setter
    def contact(self, contact: Contact) -> None: ...
    @property
    def time(self) -> float: ...
    @property
    def steps_taken(self) -> int: ...
    def set_clock(self, time: float, steps_taken: int) -> None:
        """Sets the simulation time (s) and step count, e.g. when restoring a saved state."""
    @property
    def bodies(self) -> list: ...
    @property
    def colliders(self) -> list: ...

def gpu_info() -> dict:
    """The adapter the GPU backend would use: ``name``, ``backend`` (e.g. "vulkan"),
    ``device_type`` (e.g. "Cpu" for lavapipe), ``driver``, ``f64`` (SHADER_F64 offered, so
    ``Solver(backend="gpu", precision="f64")`` works) and ``limits`` (dict). Raises RuntimeError naming what is
    missing when there is no adapter."""
