"""peridyn: thin hyperelastic membranes (cloth) with contact and elastoplastic particles
(solids, sand, fluids), by projective peridynamics.

The simulation runs in a compiled Rust core (:mod:`peridyn._core`); this package re-exports it
and adds Python helpers: mesh building and loading (:mod:`peridyn.mesh`), output
(:mod:`peridyn.io`), saved states (:mod:`peridyn.state`), pictures (:mod:`peridyn.render`), animations (:mod:`peridyn.animation`),
notebook views (:mod:`peridyn.view`), USD stages (:mod:`peridyn.usd`), parameter sweeps
(:mod:`peridyn.sweeps`), a ``run`` loop with progress bar
(:class:`peridyn.Solver`) and ready-made scenes (:mod:`peridyn.scenes`, and the paper's
contact scenes in :mod:`peridyn.paper_scenes` and :mod:`peridyn.avatar_scenes`).

All quantities are SI: metres, kilograms, seconds, pascals, joules.
"""

from . import _core
from ._core import (
    Box,
    Capsule,
    Collider,
    Contact,
    DivergenceError,
    DruckerPrager,
    Elastic,
    Granular,
    Membrane,
    MeshCollider,
    NeoHookean,
    Particles,
    Plane,
    PrecisionWarning,
    Sphere,
    StepStats,
    ViscoelasticFluid,
    StretchA3,
    contact,
    gpu_info,
    sample_surface,
    sample_volume,
)
from .animation import animate
from .io import FrameRecorder, write_mesh
from .state import load_state, save_state
from .materials import plate_bending_stiffness
from .mesh import grid, load_mesh
from .render import draw_scene, render_png
from .avatar_scenes import dress, mannequin, skirt
from .paper_scenes import antependium, cloths_over_ball, shooting_shell
from .recording import Recording, load_recording
from .scenes import Scene, colliding_sheets, default_scene, elastic_torus_scene
from .view import show
from .solver import RunSummary, Solver, gravity_tolerance
from .surface import particle_surface
from .sweeps import SweepResult, sweep
from .usd import write_usd

__version__: str = _core.__version__

__all__ = [
    # Rust core (peridyn._core; Solver is its subclass with a Python run loop)
    "Box",
    "Capsule",
    "Collider",
    "Contact",
    "DivergenceError",
    "DruckerPrager",
    "Elastic",
    "ViscoelasticFluid",
    "Granular",
    "Membrane",
    "MeshCollider",
    "NeoHookean",
    "Particles",
    "Plane",
    "PrecisionWarning",
    "Solver",
    "Sphere",
    "StepStats",
    "StretchA3",
    "contact",
    "gpu_info",
    "sample_surface",
    "sample_volume",
    # Python layer
    "FrameRecorder",
    "Recording",
    "RunSummary",
    "SweepResult",
    "Scene",
    "animate",
    "antependium",
    "cloths_over_ball",
    "colliding_sheets",
    "default_scene",
    "elastic_torus_scene",
    "draw_scene",
    "dress",
    "gravity_tolerance",
    "grid",
    "load_mesh",
    "load_recording",
    "load_state",
    "mannequin",
    "particle_surface",
    "plate_bending_stiffness",
    "render_png",
    "save_state",
    "shooting_shell",
    "show",
    "skirt",
    "sweep",
    "write_mesh",
    "write_usd",
    "__version__",
]
