"""State files: everything a solver's next steps depend on, saved to an ``.npz`` and loaded
back so that a run continues bit for bit (:func:`save_state`, :func:`load_state`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Dict, List, Optional

import numpy as np

from .io import PathLike, _write_npz

__all__ = ["save_state", "load_state", "STATE_FORMAT_VERSION"]

#: The version of the state file format :func:`save_state` writes (its ``format_version`` entry).
#: 0 is the format before versions (no ``format_version``, ``dt`` or ``self_contact_<b>``); 1
#: adds those; 2 adds each particle body's material state (``material_<name>_<b>``); 3 adds the
#: friction at the grains' contacts to the solver's internal state
#: (``internal_grain_contact_<name>``; from an earlier file it starts from 0).
#: :func:`load_state` reads versions 0 to 3.
STATE_FORMAT_VERSION = 3


class _StateError(ValueError):
    """A file that is not a valid peridyn state (for this solver); a ``ValueError``."""


def _invalid(path: Any, why: str) -> _StateError:
    return _StateError(f"load_state: {str(path)!r} is not a valid peridyn state file: {why}")


def _unfit(path: Any, why: str) -> _StateError:
    return _StateError(f"load_state: {str(path)!r} is not a valid peridyn state for this solver: {why}")


class _BodyState:
    """What one body's next steps depend on."""

    __slots__ = ("positions", "velocities", "pinned", "pin_targets", "self_contact", "bonds",
                 "material")

    def __init__(self, positions: np.ndarray, velocities: np.ndarray, pinned: np.ndarray,
                 pin_targets: np.ndarray, self_contact: Optional[bool],
                 bonds: Optional[Dict[str, np.ndarray]] = None,
                 material: Optional[Dict[str, np.ndarray]] = None) -> None:
        self.positions = positions
        self.velocities = velocities
        # a plastic particle body's current reference bonds (``Particles.rest_bonds``)
        self.bonds = bonds
        # a particle body's material as the run left it (``Particles.material_state``)
        self.material = material
        self.pinned = pinned
        self.pin_targets = pin_targets
        self.self_contact = self_contact


class _State:
    """What a solver's next steps depend on, as far as the Python API reaches it."""

    __slots__ = ("time", "steps_taken", "dt", "bodies", "colliders", "internal")

    def __init__(self, time: float, steps_taken: int, dt: Optional[float],
                 bodies: List[_BodyState], colliders: List[Any],
                 internal: Optional[Dict[str, np.ndarray]] = None) -> None:
        self.time = time
        self.steps_taken = steps_taken
        self.dt = dt
        self.bodies = bodies
        # per collider: ((base_rotation, base_translation), target or None)
        self.colliders = colliders
        # what the core keeps between steps beyond the above, if the solver exposes it
        self.internal = internal


#: Prefix of the entries that hold a solver's internal state (see :func:`save_state`).
_INTERNAL = "internal_"


def _internal_state(solver: Any) -> Optional[Dict[str, np.ndarray]]:
    """``solver.internal_state()`` (copies), or None when the solver does not expose any."""
    get = getattr(solver, "internal_state", None)
    if get is None:
        return None
    return {str(k): np.array(v) for k, v in dict(get()).items()}


#: The entries of a plastic particle body's bonds (``Particles.rest_bonds``): the file holds
#: each as ``bonds_<name>_<b>``, with its dtype and its shape's second axis (None: 1-D).
_BOND_ENTRIES = {
    "offsets": ("i", None),
    "neighbours": ("i", None),
    "vectors": ("f", 3),
    "born": ("f", None),
    "plastic_strain": ("f", None),
    "volume": ("f", None),
}
#: Bond entries a file written before them may lack: left out of the bonds read, the core
#: takes its default (``volume``: 1 for every particle, as for the bonds of the rest state).
_BOND_OPTIONAL = {"volume"}


#: The entries of a particle body's material state (``Particles.material_state``) beside its
#: region bonds (``region_<bond entry>``): dtype kind and the shapes allowed ("N": the
#: body's particle count; an empty shape for a part the body does not have).
_MATERIAL_ENTRIES = {
    "elastic": ("f", [(3,)]),
    # 9, 10, 11, 12 numbers: written before the density solver, bulk modulus, surface
    # tension, plastic viscosity
    "fluid": ("f", [(0,), (9,), (10,), (11,), (12,), (13,)]),
    "horizon": ("f", [(0,), (1,)]),
    "reference": ("f", [("N", 3)]),
    "fluid_mask": ("b", [(0,), ("N",)]),
    "wetted": ("f", [(0,), ("N",)]),
}


def _is_membrane(body: Any) -> bool:
    """Membranes have vertices and a self-contact switch; particle bodies have neither."""
    return hasattr(body, "num_vertices")


def _count(body: Any) -> int:
    """A body's number of vertices (membrane) or particles."""
    return int(body.num_vertices if _is_membrane(body) else body.num_particles)


def _path_first(func: str, path: Any) -> None:
    """Refuses a solver given where the path belongs (the arguments are ``(path, solver)``,
    as for every writer of :mod:`peridyn.io`), which pathlib would report obscurely."""
    if hasattr(path, "step") and hasattr(path, "bodies"):
        raise TypeError(f"{func}(path, solver): the first argument is a solver; "
                        f"pass the file's path first")


def _capture(solver: Any) -> _State:
    """The solver's state now (copies)."""
    bodies = []
    for body in solver.bodies:
        pinned = np.asarray(body.pinned, dtype=np.int64)
        membrane = _is_membrane(body)
        bonds = None if membrane else body.rest_bonds
        material = None if membrane else body.material_state
        bodies.append(_BodyState(
            np.array(body.positions, dtype=np.float64),
            np.array(body.velocities, dtype=np.float64),
            pinned,
            np.array(body.pin_targets, dtype=np.float64).reshape(len(pinned), 3),
            bool(body.self_contact) if membrane else None,
            None if bonds is None else {k: np.array(v) for k, v in bonds.items()},
            None if material is None else {k: np.array(v) for k, v in material.items()},
        ))
    colliders = []
    for c in range(len(solver.colliders)):
        (base_r, base_t), target = solver.collider_motion(c)
        base = (np.array(base_r, dtype=np.float64), np.array(base_t, dtype=np.float64))
        if target is not None:
            target = (np.array(target[0], dtype=np.float64), np.array(target[1], dtype=np.float64))
        colliders.append((base, target))
    return _State(float(solver.time), int(solver.steps_taken), float(solver.dt), bodies, colliders,
                  _internal_state(solver))


def _apply(solver: Any, state: _State) -> None:
    """Sets ``state`` into ``solver`` (checked against it beforehand)."""
    if state.dt is not None:
        solver.dt = state.dt
    for index, (body, b) in enumerate(zip(solver.bodies, state.bodies)):
        body.positions = b.positions
        body.velocities = b.velocities
        body.unpin()
        if len(b.pinned):
            body.pin(b.pinned, b.pin_targets)
        if b.self_contact is not None:
            body.self_contact = b.self_contact
        if b.material is not None:
            try:
                body.material_state = b.material
            except ValueError as e:
                raise ValueError(f"body {index}'s material (entries 'material_<name>_{index}'): "
                                 f"{e}") from e
        # After the material: a body made plastic by it takes its bonds, another none.
        if not _is_membrane(body):
            if body.plasticity is not None and b.bonds is None:
                raise ValueError(f"body {index} is plastic but the file holds no entries "
                                 f"'bonds_<name>_{index}'")
            if body.plasticity is not None or b.bonds is not None:
                body.rest_bonds = b.bonds
    for c, (base, target) in enumerate(state.colliders):
        extra = {}
        if target is not None:
            extra = dict(target_rotation=target[0], target_translation=target[1])
        solver.set_collider_motion(c, base_rotation=base[0], base_translation=base[1], **extra)
    if state.internal is not None:
        try:
            solver.set_internal_state(state.internal)
        except ValueError as e:
            raise ValueError(f"the solver refuses its internal state (entries "
                             f"'{_INTERNAL}<name>'): {e}") from e
    solver.set_clock(state.time, state.steps_taken)


def save_state(path: PathLike, solver: Any) -> Path:
    """Saves everything that a solver's next steps depend on (as far as the Python API
    reaches it) to a compressed ``.npz`` file at exactly ``path``.

    That is the file format version, the solver's clock (``time``, ``steps_taken``) and time
    step ``dt``; each body's positions, velocities, pinned vertices and pin targets, a
    membrane's ``self_contact`` switch, a plastic particle body's current reference bonds
    (``Particles.rest_bonds``: its neighbours after the returns and rebuilds, their reference
    vectors and the hardening state, as entries ``bonds_<name>_<b>``), every particle body's
    material as the run left it (``Particles.material_state``: a material changed by
    ``set_material``, a mixed body's fluid particles and bonds, wetted sand's saturations, as
    entries ``material_<name>_<b>``); each collider's motion (the pose its velocity carries on from and
    a pose set with ``Solver.set_collider_pose`` for the next step, if any). :func:`load_state`
    into a solver set up the same way (same bodies, parameters and colliders, in order) then
    continues the simulation bit for bit, with and without contact.

    A solver that exposes more of what its steps depend on through two methods,
    ``internal_state()`` returning a dict of name to numeric array and
    ``set_internal_state(dict)`` restoring it (all or nothing, ``ValueError`` on a bad dict),
    has that dict saved as entries ``internal_<name>`` and restored by :func:`load_state`
    (with an empty dict for a file that holds none, for the solver to reset it).

    The file is written to ``path`` as given (no ``.npz`` is appended), through a temporary
    file in the same directory that replaces ``path`` only once complete: a failed save leaves
    an earlier file at ``path`` intact.

    Parameters
    ----------
    path : str or os.PathLike
        Destination file (``.npz`` by convention); parent directories are created.
    solver : Solver
        The solver to save.

    Returns
    -------
    Path
        The file written: ``path``.
    """
    _path_first("save_state", path)
    path = Path(path)
    state = _capture(solver)
    arrays: Dict[str, np.ndarray] = {
        "format_version": np.array(STATE_FORMAT_VERSION, dtype=np.int64),
        "time": np.array(state.time, dtype=np.float64),
        "steps_taken": np.array(state.steps_taken, dtype=np.uint64),
        "dt": np.array(state.dt, dtype=np.float64),
        "bodies": np.array(len(state.bodies), dtype=np.int64),
        "colliders": np.array(len(state.colliders), dtype=np.int64),
    }
    for b, body in enumerate(state.bodies):
        arrays[f"positions_{b}"] = body.positions
        arrays[f"velocities_{b}"] = body.velocities
        arrays[f"pinned_{b}"] = body.pinned
        arrays[f"pin_targets_{b}"] = body.pin_targets
        if body.self_contact is not None:
            arrays[f"self_contact_{b}"] = np.array(bool(body.self_contact))
        for name, value in (body.bonds or {}).items():
            arrays[f"bonds_{name}_{b}"] = value
        for name, value in (body.material or {}).items():
            arrays[f"material_{name}_{b}"] = value
    for name, value in (state.internal or {}).items():
        arrays[_INTERNAL + name] = value
    for c, (base, target) in enumerate(state.colliders):
        arrays[f"collider_base_rotation_{c}"] = base[0]
        arrays[f"collider_base_translation_{c}"] = base[1]
        if target is not None:
            arrays[f"collider_target_rotation_{c}"] = target[0]
            arrays[f"collider_target_translation_{c}"] = target[1]
    path.parent.mkdir(parents=True, exist_ok=True)
    _write_npz(path, arrays)
    return path


def _read_npz(path: PathLike) -> Dict[str, np.ndarray]:
    """Every entry of the ``.npz`` file at ``path``, as arrays; never unpickles. Raises
    ``_StateError`` for anything but a well-formed archive of ``.npy`` arrays (an
    ``OSError`` such as ``FileNotFoundError`` when the file cannot be opened)."""
    import zipfile

    fmt = np.lib.format
    with open(path, "rb") as f:
        try:
            if f.read(4) != b"PK\x03\x04":
                raise _invalid(path, "it is not an .npz (zip) archive")
            f.seek(0)
            entries: Dict[str, np.ndarray] = {}
            with zipfile.ZipFile(f) as archive:
                for info in archive.infolist():
                    name = info.filename
                    if not name.endswith(".npy"):
                        raise _invalid(path, f"entry {name!r} is not an .npy array")
                    key = name[: -len(".npy")]
                    if key in entries:
                        raise _invalid(path, f"entry {key!r} appears twice")
                    with archive.open(info) as member:
                        version = fmt.read_magic(member)
                        if version == (1, 0):
                            shape, fortran, dtype = fmt.read_array_header_1_0(member)
                        elif version == (2, 0):
                            shape, fortran, dtype = fmt.read_array_header_2_0(member)
                        else:
                            raise _invalid(path, f"entry {key!r} is an .npy file of version "
                                                 f"{version}, which peridyn does not write")
                        if dtype.hasobject:
                            raise _invalid(path, f"entry {key!r} is an array of Python objects "
                                                 f"(dtype {dtype}); state files hold numbers only")
                        size = int(np.prod(shape, dtype=object)) * dtype.itemsize
                        stored = info.file_size - member.tell()
                        if size != stored:
                            raise _invalid(path, f"entry {key!r} declares shape {shape} of "
                                                 f"{dtype} ({size} bytes) but holds {stored} bytes")
                    with archive.open(info) as member:
                        array = fmt.read_array(member, allow_pickle=False)
                    if not isinstance(array, np.ndarray):
                        raise _invalid(path, f"entry {key!r} is not an array")
                    entries[key] = array
            return entries
        except _StateError:
            raise
        except Exception as e:  # zipfile.BadZipFile, zlib.error, EOFError, ValueError, ...
            raise _invalid(path, f"{type(e).__name__}: {e}") from e


class _Entries:
    """The entries of a state file, taken one by one with checks; reports leftovers."""

    def __init__(self, path: Any, entries: Dict[str, np.ndarray], float_max: float) -> None:
        self.path = path
        self.entries = entries
        self.float_max = float_max
        self.taken: set = set()

    def has(self, key: str) -> bool:
        return key in self.entries

    def _get(self, key: str) -> np.ndarray:
        if key not in self.entries:
            raise _invalid(self.path, f"entry {key!r} is missing")
        self.taken.add(key)
        return self.entries[key]

    def _kind(self, key: str, value: np.ndarray, kinds: str, what: str) -> None:
        if value.dtype.kind not in kinds:
            raise _invalid(self.path, f"entry {key!r} has dtype {value.dtype}, expected {what}")

    def integer(self, key: str, low: int = 0, high: int = 2**63 - 1) -> int:
        value = self._get(key)
        self._kind(key, value, "iu", "an integer")
        if value.shape != ():
            raise _invalid(self.path, f"entry {key!r} has shape {value.shape}, expected a scalar")
        n = int(value)
        if not low <= n <= high:
            raise _invalid(self.path, f"entry {key!r} is {n}, outside [{low}, {high}]")
        return n

    def boolean(self, key: str) -> bool:
        value = self._get(key)
        self._kind(key, value, "b", "a bool")
        if value.shape != ():
            raise _invalid(self.path, f"entry {key!r} has shape {value.shape}, expected a scalar")
        return bool(value)

    def floats(self, key: str, shape: tuple, count: Optional[str] = None,
               of_solver: bool = True) -> np.ndarray:
        """A real float array of ``shape`` with finite values that the solver's precision
        holds; ``count`` says what the solver has ``shape[0]`` of, for the message when the
        file has a different number of them."""
        value = self._get(key)
        self._kind(key, value, "f", "real floats")
        if value.shape != shape:
            if count and value.ndim == len(shape) and value.shape[0] != shape[0]:
                error = _unfit if of_solver else _invalid
                raise error(self.path, f"{count} {shape[0]}, the file's {key!r} has "
                                       f"{value.shape[0]} (shape {value.shape})")
            expected = "() (a scalar)" if shape == () else str(shape)
            raise _invalid(self.path, f"entry {key!r} has shape {value.shape}, expected {expected}")
        value = value.astype(np.float64)
        bad = ~np.isfinite(value)
        if bad.any():
            index = tuple(int(i) for i in np.argwhere(bad)[0])
            raise _invalid(self.path, f"entry {key!r} holds {value[index]!r} at {index}, "
                                      "not a finite number")
        over = np.abs(value) > self.float_max
        if over.any():
            index = tuple(int(i) for i in np.argwhere(over)[0])
            raise _unfit(self.path, f"entry {key!r} holds {value[index]!r} at {index}, beyond "
                                    f"the largest number of the solver's precision ({self.float_max:g})")
        return value

    def scalar(self, key: str) -> float:
        return float(self.floats(key, ()))

    def numbers(self, key: str) -> np.ndarray:
        """An array of real numbers or bools of any shape, finite where floats."""
        value = self._get(key)
        self._kind(key, value, "biuf", "real numbers or bools")
        if value.dtype.kind == "f" and not np.isfinite(value).all():
            index = tuple(int(i) for i in np.argwhere(~np.isfinite(value))[0])
            raise _invalid(self.path, f"entry {key!r} holds {value[index]!r} at {index}, "
                                      "not a finite number")
        return value

    def indices(self, key: str, n: int) -> np.ndarray:
        """Sorted distinct vertex indices in [0, n)."""
        value = self._get(key)
        self._kind(key, value, "iu", "integers")
        if value.ndim != 1:
            raise _invalid(self.path, f"entry {key!r} has shape {value.shape}, expected (P,)")
        if len(value):
            low, high = value.min(), value.max()
            if low < 0 or high >= n:
                bad = low if low < 0 else high
                raise _unfit(self.path, f"entry {key!r} holds vertex {int(bad)}, outside [0, {n})")
            if np.any(np.diff(value.astype(np.int64)) <= 0):
                raise _invalid(self.path, f"entry {key!r} is not sorted without repeats")
        return value.astype(np.int64)

    def bonds(self, b: int, prefix: str = "bonds_") -> Dict[str, np.ndarray]:
        """Body ``b``'s bonds (entries ``<prefix><name>_<b>``), of the dtypes and dimensions
        of :data:`_BOND_ENTRIES`; whether they fit the body is checked when they are set."""
        bonds = {}
        for name, (kind, columns) in _BOND_ENTRIES.items():
            key = f"{prefix}{name}_{b}"
            if name in _BOND_OPTIONAL and not self.has(key):
                continue
            value = self._get(key)
            self._kind(key, value, "iu" if kind == "i" else "f",
                       "integers" if kind == "i" else "real floats")
            ok = value.ndim == 1 if columns is None else value.ndim == 2 and value.shape[1] == 3
            if not ok:
                expected = "(B,)" if columns is None else "(B, 3)"
                raise _invalid(self.path, f"entry {key!r} has shape {value.shape}, expected {expected}")
            if kind == "f" and not np.isfinite(value).all():
                index = tuple(int(i) for i in np.argwhere(~np.isfinite(value))[0])
                raise _invalid(self.path, f"entry {key!r} holds {value[index]!r} at {index}, "
                                          "not a finite number")
            bonds[name] = value
        return bonds

    def material(self, b: int, n: int) -> Dict[str, np.ndarray]:
        """Body ``b``'s material state (entries ``material_<name>_<b>`` of
        :data:`_MATERIAL_ENTRIES`) for a body of ``n`` particles: each of its dtype kind and
        one of its shapes, finite; whether they fit the body is checked when they are set."""
        material = {}
        for name, (kind, shapes) in _MATERIAL_ENTRIES.items():
            key = f"material_{name}_{b}"
            value = self._get(key)
            self._kind(key, value, kind, "bools" if kind == "b" else "real floats")
            allowed = [tuple(n if d == "N" else d for d in shape) for shape in shapes]
            if value.shape not in allowed:
                raise _invalid(self.path, f"entry {key!r} has shape {value.shape}, expected "
                                          + " or ".join(str(a) for a in allowed))
            if kind == "f":
                value = self.floats(key, value.shape)
            material[name] = value
        bonds = self.bonds(b, prefix="material_region_")
        material.update({f"region_{name}": value for name, value in bonds.items()})
        return material

    def leftovers(self) -> None:
        extra = sorted(set(self.entries) - self.taken)
        if extra:
            raise _invalid(self.path, f"unexpected entries {extra}")


def _parse(path: Any, entries: Dict[str, np.ndarray], solver: Any) -> _State:
    """The state held by ``entries``, checked in full against ``solver``."""
    float_max = float(np.finfo(np.float32 if solver.precision == "f32" else np.float64).max)
    e = _Entries(path, entries, float_max)
    version = e.integer("format_version") if e.has("format_version") else 0
    if version > STATE_FORMAT_VERSION:
        raise _StateError(
            f"load_state: {str(path)!r} has state format version {version}, newer than the "
            f"versions this peridyn reads (0 to {STATE_FORMAT_VERSION}): update peridyn"
        )
    time = e.scalar("time")
    steps_taken = e.integer("steps_taken", 0, 2**64 - 1)
    dt = None
    if version >= 1:
        dt = e.scalar("dt")
        if dt <= 0.0:
            raise _invalid(path, f"entry 'dt' is {dt!r}, not a time step > 0 s")
    solver_bodies = list(solver.bodies)
    n_bodies = e.integer("bodies")
    if n_bodies != len(solver_bodies):
        raise _unfit(path, f"the file holds {n_bodies} bodies, the solver has {len(solver_bodies)}")
    bodies = []
    for b, body in enumerate(solver_bodies):
        n = _count(body)
        membrane = _is_membrane(body)
        what = "vertices" if membrane else "particles"
        positions = e.floats(f"positions_{b}", (n, 3), f"body {b} has {n} {what},")
        velocities = e.floats(f"velocities_{b}", (n, 3), f"body {b} has {n} {what},")
        pinned = e.indices(f"pinned_{b}", n)
        targets = e.floats(f"pin_targets_{b}", (len(pinned), 3),
                           f"the file's 'pinned_{b}' has {len(pinned)} {what},", of_solver=False)
        self_contact = e.boolean(f"self_contact_{b}") if version >= 1 and membrane else None
        material = None
        if version >= 2 and not membrane:
            material = e.material(b, n)
        bonds = None
        if not membrane and (e.has(f"bonds_offsets_{b}")
                             or (version < 2 and body.plasticity is not None)):
            bonds = e.bonds(b)
        bodies.append(_BodyState(positions, velocities, pinned, targets, self_contact, bonds,
                                 material))
    n_colliders = len(solver.colliders)
    if version >= 1 or e.has("colliders"):
        in_file = e.integer("colliders")
        if in_file != n_colliders:
            raise _unfit(path, f"the file holds {in_file} colliders, the solver has {n_colliders}")
    else:  # files written before collider motion was saved
        n_colliders = 0
    colliders = []
    for c in range(n_colliders):
        base = (e.floats(f"collider_base_rotation_{c}", (3, 3)),
                e.floats(f"collider_base_translation_{c}", (3,)))
        has_r = e.has(f"collider_target_rotation_{c}")
        has_t = e.has(f"collider_target_translation_{c}")
        target = None
        if has_r or has_t:
            target = (e.floats(f"collider_target_rotation_{c}", (3, 3)),
                      e.floats(f"collider_target_translation_{c}", (3,)))
        colliders.append((base, target))
    internal = None
    if hasattr(solver, "internal_state"):
        internal = {key[len(_INTERNAL):]: e.numbers(key)
                    for key in sorted(entries) if key.startswith(_INTERNAL)}
    e.leftovers()
    return _State(time, steps_taken, dt, bodies, colliders, internal)


def load_state(path: PathLike, solver: Any) -> None:
    """Restores a state written by :func:`save_state` into ``solver``, set up the same way
    (same bodies and colliders, in order; same parameters).

    All or nothing: the whole file is read and checked against the solver (every entry
    present, real numbers of the expected shapes, finite and within the solver's precision,
    the counts of bodies, vertices, pins and colliders, the format version) before anything
    changes; if the solver still refuses part of it (say a collider pose that is not a
    rotation), what was set is undone and the solver is left exactly as before.

    Files of format version 2 (:data:`STATE_FORMAT_VERSION`) also set each particle body's
    material as the run left it (``Particles.material_state``, before its bonds); version 1
    files leave it as it is. Version 1 and later set the solver's ``dt`` and each body's
    ``self_contact``; files without a ``format_version`` entry (version 0, written by peridyn
    before versions) are read too and leave those as they are.

    The solver's internal state (``Solver.internal_state``: the contact local step's warm
    start and the rest gaps of the pairs that started within the barrier's reach) is in the
    file as entries ``internal_<name>``, so a run with contact continues bit for bit too; a
    file without them (written before they were saved) resets it, and the next contact step
    starts afresh. Not in the file: the solver's parameters (``Solver.contact`` included), which
    the solver it is loaded into must share. Entries ``internal_<name>`` in a file are refused
    by a solver without ``set_internal_state``.

    Raises
    ------
    ValueError
        If the file is not a valid peridyn state (not an ``.npz``, truncated, corrupt, an entry
        missing, unexpected, of the wrong dtype or shape, non-finite or out of range) or not
        one for this solver (a different number of bodies, vertices or colliders), or has a
        newer format version; the message says which and why.
    OSError
        If the file cannot be opened (``FileNotFoundError`` if it does not exist).
    """
    _path_first("load_state", path)
    entries = _read_npz(path)
    state = _parse(path, entries, solver)
    before = _capture(solver)
    try:
        _apply(solver, state)
    except Exception as e:
        _apply(solver, before)
        if isinstance(e, ValueError):
            raise _unfit(path, str(e)) from e
        raise
