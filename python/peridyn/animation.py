"""Animations of a recorded run: MP4 (H.264 through imageio-ffmpeg) or GIF, off-screen.

Each frame is drawn with matplotlib's Agg canvas like :func:`peridyn.render_png` (membranes as
shaded surfaces, particle sets as points, colliders translucent at their recorded poses) and
handed to imageio's writer, so no display and no system ffmpeg are needed: the ``imageio-ffmpeg``
wheel carries its own encoder binary. Where that encoder is missing or fails to start, the
animation is written as a GIF instead (Pillow), with a warning.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path
from typing import Any, Callable, Optional, Sequence, Tuple, Union

import numpy as np

from .recording import FIELDS, Recording, _robust_range, as_recording
from .render import _MESH_COLORS, _draw_body, _draw_collider, _run_view_box, _set_view

__all__ = ["animate"]

PathLike = Union[str, "os.PathLike[str]"]

_BLOCK = 16  # H.264 encodes whole 16 x 16 macroblocks: frame sizes are kept multiples of it


def _mp4_encoder_available() -> bool:
    try:
        import imageio_ffmpeg

        return Path(imageio_ffmpeg.get_ffmpeg_exe()).is_file()
    except (ImportError, RuntimeError, OSError):
        return False


def _open_writer(path: Path, fps: float) -> Tuple[Any, Path]:
    """An imageio writer for ``path`` (``.mp4`` or ``.gif``), and the path it really writes."""
    import imageio.v2 as imageio

    suffix = path.suffix.lower()
    if suffix not in (".mp4", ".gif"):
        raise ValueError(f"animate: unsupported suffix {path.suffix!r} in {str(path)!r}; use .mp4 or .gif")
    if suffix == ".mp4":
        if _mp4_encoder_available():
            try:
                return imageio.get_writer(str(path), format="FFMPEG", mode="I", fps=fps, codec="libx264",
                                          quality=7, pixelformat="yuv420p", macro_block_size=_BLOCK,
                                          ffmpeg_log_level="error"), path
            except (RuntimeError, OSError) as err:
                reason = f"the MP4 encoder failed to start ({err})"
        else:
            reason = "no MP4 encoder (pip install imageio-ffmpeg)"
        path = path.with_suffix(".gif")
        warnings.warn(f"animate: {reason}; writing a GIF instead: {path}", RuntimeWarning, stacklevel=3)
    return imageio.get_writer(str(path), format="GIF", mode="I", duration=1000.0 / fps, loop=0), path


def animate(
    source: Any,
    path: PathLike = "animation.mp4",
    *,
    colliders: Optional[Sequence[Any]] = None,
    field: Union[None, str, Callable[..., Any]] = None,
    cmap: str = "viridis",
    clim: Optional[Tuple[float, float]] = None,
    fps: float = 20.0,
    elev: float = 25.0,
    azim: float = -60.0,
    size: Tuple[int, int] = (800, 640),
    dpi: int = 100,
    title: bool = True,
    progress: bool = False,
) -> Path:
    """Write a recorded run as an MP4 (or GIF) animation, one video frame per recorded frame.

    Parameters
    ----------
    source : FrameRecorder, Recording, str or path-like
        The run: a :class:`peridyn.FrameRecorder` (its frames so far, with the solver's
        colliders), a :class:`peridyn.recording.Recording`, or the path of a recorder's
        ``.npz`` (pass ``colliders`` to draw them then).
    path : str or path-like
        Output file, ``.mp4`` (H.264) or ``.gif``. An ``.mp4`` without an encoder becomes a
        ``.gif`` beside it (a ``RuntimeWarning`` says so); the path returned is the one written.
    colliders : sequence of colliders, optional
        Replaces the recording's colliders (drawn at their recorded poses when the recording
        has them, else as built).
    field : {"speed", "stretch", "contact", "height"} or callable, optional
        Colour the bodies by a per-vertex field (see :data:`peridyn.recording.FIELDS`; a
        function ``f(recording, frame, body)`` returns (N,) values); None: one colour per body.
    cmap : str
        Matplotlib colour map of the field.
    clim : (float, float), optional
        Field values at the ends of the colour map (in the field's unit); default: the
        field's minimum to its 99th percentile over the whole run, so colours mean the same
        in every frame and a few outliers do not wash them out.
    fps : float
        Video frames per second (> 0).
    elev, azim : float
        Camera elevation and azimuth in degrees.
    size : (int, int)
        Frame width and height in pixels, rounded down to multiples of 16 (>= 16).
    dpi : int
        Dots per inch (the scale of text and lines).
    title : bool
        Show the simulated time in each frame.
    progress : bool
        Show a tqdm progress bar over the frames.

    Returns
    -------
    pathlib.Path
        The file written.

    Raises
    ------
    ValueError
        For a recording without frames, an unknown or unrecorded field, ``fps <= 0``, a frame
        size under 16 pixels or a suffix other than ``.mp4`` / ``.gif``.
    """
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure

    rec: Recording = as_recording(source, colliders)
    if rec.num_frames == 0:
        raise ValueError("animate: the recording has no frames")
    if not fps > 0.0:
        raise ValueError(f"animate: fps must be > 0, got {fps!r}")
    width, height = (int(s) // _BLOCK * _BLOCK for s in size)
    if width < _BLOCK or height < _BLOCK:
        raise ValueError(f"animate: size must be at least ({_BLOCK}, {_BLOCK}) pixels, got {size!r}")

    values = None
    norm = None
    if field is not None:
        values = [[rec.field(field, f, b) for b in range(len(rec.bodies))] for f in range(rec.num_frames)]
        if clim is None:
            flat = np.concatenate([v for frame in values for v in frame])
            clim = _robust_range(flat)
        norm = Normalize(*clim)
    colormap = colormaps[cmap]

    center, half = _run_view_box(rec)

    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot(projection="3d")
    if norm is not None:
        from matplotlib.cm import ScalarMappable

        label = FIELDS.get(field, "field") if isinstance(field, str) else "field"
        fig.colorbar(ScalarMappable(norm=norm, cmap=colormap), ax=ax, shrink=0.6, label=label)

    frames = range(rec.num_frames)
    if progress:
        from tqdm.auto import tqdm

        frames = tqdm(frames, desc="animate", unit="frame")
    writer, written = _open_writer(Path(path), float(fps))
    with writer:
        for f in frames:
            ax.cla()
            for c, col in enumerate(rec.colliders):
                _draw_collider(ax, col, center, half, rec.collider_pose(f, c))
            for b, track in enumerate(rec.bodies):
                _draw_body(ax, track.positions[f], track.triangles, _MESH_COLORS[b % len(_MESH_COLORS)],
                           None if values is None else values[f][b], colormap, norm)
            _set_view(ax, center, half, f"t = {rec.times[f]:.3f} s" if title else None, elev, azim)
            canvas.draw()
            image = np.asarray(canvas.buffer_rgba())[:, :, :3]
            writer.append_data(np.ascontiguousarray(image[:height, :width]))
    return written
