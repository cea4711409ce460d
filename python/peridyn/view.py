"""Interactive 3-D views in Jupyter: a solver's bodies and colliders, or a recorded run with a
time slider, as a plotly figure.

Plotly draws in the browser with WebGL (``Mesh3d`` surfaces, ``Scatter3d`` points). A figure
is a plain notebook output (plotly's own MIME type), which JupyterLab, Jupyter Notebook 7 and
VS Code render natively: no widget extension, no kernel round trip and no display server; the
slider and the play button run in the page, so a saved notebook or an HTML export
(``fig.write_html``) still plays.
"""

from __future__ import annotations

from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from .recording import FIELDS, Recording, _robust_range, as_recording
from .render import _COLLIDER_COLOR, _MESH_COLORS, _run_view_box

__all__ = ["show"]


def _body_trace(go: Any, X: np.ndarray, tris: Optional[np.ndarray], color: str, values: Optional[np.ndarray],
                style: Dict[str, Any], name: str) -> Any:
    if tris is None:
        marker: Dict[str, Any] = {"size": 2.5, "color": color}
        if values is not None:
            marker.update(color=values, **style)
        return go.Scatter3d(x=X[:, 0], y=X[:, 1], z=X[:, 2], mode="markers", marker=marker, name=name)
    extra: Dict[str, Any] = {"color": color}
    if values is not None:
        extra = {"intensity": values, **style}
    return go.Mesh3d(x=X[:, 0], y=X[:, 1], z=X[:, 2], i=tris[:, 0], j=tris[:, 1], k=tris[:, 2],
                     flatshading=False, name=name, showlegend=True, **extra)


def _frame_traces(go: Any, rec: Recording, f: int, values: Optional[List[List[np.ndarray]]],
                  style: Dict[str, Any], colliders: List[Tuple[np.ndarray, np.ndarray]]) -> List[Any]:
    from .shapes import at_pose

    traces = []
    for b, track in enumerate(rec.bodies):
        traces.append(_body_trace(go, track.positions[f], track.triangles, _MESH_COLORS[b % len(_MESH_COLORS)],
                                  None if values is None else values[f][b], style, f"body {b}"))
    for c, (V, F) in enumerate(colliders):
        P = at_pose(V, rec.collider_pose(f, c))
        traces.append(go.Mesh3d(x=P[:, 0], y=P[:, 1], z=P[:, 2], i=F[:, 0], j=F[:, 1], k=F[:, 2],
                                color=_COLLIDER_COLOR, opacity=0.35, name=type(rec.colliders[c]).__name__,
                                showlegend=True, hoverinfo="skip"))
    return traces


def show(
    source: Any,
    *,
    colliders: Optional[Sequence[Any]] = None,
    field: Union[None, str, Callable[..., Any]] = None,
    cmap: str = "Viridis",
    clim: Optional[Tuple[float, float]] = None,
    every: int = 1,
    height: int = 600,
) -> Any:
    """An interactive 3-D view of a solver now, or of a recorded run with a time slider.

    Parameters
    ----------
    source : Solver, FrameRecorder, Recording, str or path-like
        A solver (its bodies and colliders now), a :class:`peridyn.FrameRecorder` or a
        :class:`peridyn.recording.Recording` (every recorded frame), or the path of a
        recorder's ``.npz``. Membranes are drawn as surfaces, particle sets as points.
    colliders : sequence of colliders, optional
        Replaces the source's colliders (drawn at their recorded poses).
    field : {"speed", "stretch", "contact", "height"} or callable, optional
        Colour the bodies by a per-vertex field (:data:`peridyn.recording.FIELDS`).
    cmap : str
        A plotly colour scale name.
    clim : (float, float), optional
        Field values at the ends of the colour scale; default: the minimum to the 99th
        percentile over the shown frames.
    every : int
        Show every ``every``-th recorded frame (>= 1; the last frame is always shown).
    height : int
        Figure height in pixels.

    Returns
    -------
    plotly.graph_objects.Figure
        Displayed when it is the last expression of a notebook cell. ``fig.data`` holds the
        first frame's traces (one per body, then one per collider) and ``fig.frames`` one
        frame per shown recorded frame.

    Raises
    ------
    ValueError
        For a source without frames or bodies, an unknown or unrecorded field, or ``every < 1``.
    """
    import plotly.graph_objects as go

    from .shapes import collider_mesh

    if isinstance(every, bool) or int(every) != every or every < 1:
        raise ValueError(f"show: every must be an integer >= 1, got {every!r}")
    rec = as_recording(source, colliders)
    if rec.num_frames == 0 or not rec.bodies:
        raise ValueError("show: nothing to show (no frames or no bodies)")
    shown = list(range(0, rec.num_frames, int(every)))
    if shown[-1] != rec.num_frames - 1:
        shown.append(rec.num_frames - 1)

    values = None
    style: Dict[str, Any] = {}
    if field is not None:
        values = [[rec.field(field, f, b) for b in range(len(rec.bodies))] if f in shown else []
                  for f in range(rec.num_frames)]
        if clim is None:
            flat = np.concatenate([v for f in shown for v in values[f]])
            clim = _robust_range(flat)
        label = FIELDS.get(field, "field") if isinstance(field, str) else "field"
        style = {"colorscale": cmap, "cmin": clim[0], "cmax": clim[1], "colorbar": {"title": {"text": label}}}

    center, half = _run_view_box(rec)
    meshes = [collider_mesh(c, center, half) for c in rec.colliders]

    fig = go.Figure(data=_frame_traces(go, rec, shown[0], values, style, meshes))
    scene = {"aspectmode": "data", "xaxis_title": "x (m)", "yaxis_title": "y (m)", "zaxis_title": "z (m)"}
    fig.update_layout(scene=scene, height=height, margin={"l": 0, "r": 0, "t": 30, "b": 10},
                      title=f"t = {rec.times[shown[0]]:.3f} s")
    if len(shown) > 1:
        fig.frames = [go.Frame(data=_frame_traces(go, rec, f, values, style, meshes), name=str(f),
                               layout={"title": f"t = {rec.times[f]:.3f} s"}) for f in shown]
        # Fixed axes: the view does not rescale as the bodies move.
        for name, k in (("xaxis", 0), ("yaxis", 1), ("zaxis", 2)):
            fig.layout.scene[name].range = (center[k] - 1.05 * half, center[k] + 1.05 * half)
        fig.layout.scene.aspectmode = "cube"
        play = {"frame": {"duration": 80, "redraw": True}, "fromcurrent": True, "transition": {"duration": 0}}
        fig.update_layout(
            legend={"x": 0.0, "xanchor": "left", "y": 1.0},  # clear of the colour bar on the right
            updatemenus=[{"type": "buttons", "showactive": False, "direction": "left", "x": 0.0, "y": 0.0,
                          "xanchor": "left", "yanchor": "top", "pad": {"t": 45, "r": 10},
                          "buttons": [{"label": "play", "method": "animate", "args": [None, play]},
                                      {"label": "pause", "method": "animate",
                                       "args": [[None], {"mode": "immediate", "frame": {"duration": 0}}]}]}],
            sliders=[{"currentvalue": {"prefix": "t = ", "suffix": " s"}, "pad": {"t": 10},
                      "x": 0.18, "len": 0.78, "xanchor": "left", "y": 0.0, "yanchor": "top",
                      "steps": [{"label": f"{rec.times[f]:.3f}", "method": "animate",
                                 "args": [[str(f)], {"mode": "immediate", "frame": {"duration": 0, "redraw": True}}]}
                                for f in shown]}],
        )
    return fig
