"""What the figures and the animation draw alike: matplotlib on the Agg backend
(:func:`pyplot`), a scene's walls and obstacles posed at a time (:func:`draw_geometry`), the
colour of each agent's group (:func:`group_colours`), and a figure saved through
:mod:`sweep_core.io.outputs` (:func:`save_figure`)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from sweep_core.errors import SweepError
from sweep_core.io.outputs import replacing
from sweep_core.model.fields import Groups
from sweep_core.model.geometry import Geometry
from sweep_core.model.scene import Scene

#: colour of the agents in no group (and of every agent without groups)
REST_COLOUR = "0.55"
#: colours of groups 0, 1, ... (matplotlib's tab10 without its grey)
GROUP_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b",
                 "#e377c2", "#bcbd22", "#17becf")


def pyplot() -> Any:
    """matplotlib.pyplot on the Agg backend (SweepError naming the fix if not installed)."""
    try:
        import matplotlib
    except ImportError as err:
        raise SweepError("matplotlib is not installed (fix: pip install matplotlib, or pass "
                         "--no-plots)") from err
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def group_colour(k: int) -> str:
    """The colour of group k (0-based; -1: the agents in no group)."""
    return REST_COLOUR if k < 0 else GROUP_COLOURS[k % len(GROUP_COLOURS)]


def agent_groups(scene: Scene | None, n: int) -> tuple[np.ndarray, list[str]]:
    """The group of each of n agents ((n,) int, -1 in none) and the groups' names."""
    out = np.full(n, -1, dtype=np.intp)
    drift = scene.drift if scene is not None else None
    if not isinstance(drift, Groups):
        return out, []
    for k, idx in enumerate(drift.members):
        out[idx[idx < n]] = k
    return out, list(drift.names)


def group_colours(groups: np.ndarray) -> list[str]:
    """One colour per agent from its group ((n,) int, -1 in none)."""
    return [group_colour(int(k)) for k in groups]


def view_of(scene: Scene | None, points: np.ndarray, margin: float = 0.5
            ) -> tuple[float, float, float, float]:
    """(x0, x1, y0, y1) m: the box holding the scene's walls and obstacles and ``points``
    (M, 2), grown by ``margin`` m; at least 1 m on each side."""
    pts = [points.reshape(-1, 2)]
    if scene is not None:
        g = scene.geometry
        pts += [g.segment_a, g.segment_b]
        r = g.circle_radius[:, None]
        pts += [g.circle_center - r, g.circle_center + r]
    allp = np.concatenate([p for p in pts if len(p)]) if any(len(p) for p in pts) else (
        np.zeros((1, 2)))
    allp = allp[np.all(np.isfinite(allp), axis=1)]
    lo, hi = allp.min(axis=0) - margin, allp.max(axis=0) + margin
    mid, half = (lo + hi) / 2, np.maximum((hi - lo) / 2, 0.5)
    return float(mid[0] - half[0]), float(mid[0] + half[0]), float(mid[1] - half[1]), float(
        mid[1] + half[1])


def draw_geometry(ax: Any, geometry: Geometry, t: float = 0.0,
                  view: tuple[float, float, float, float] | None = None,
                  colour: str = "k") -> list[Any]:
    """Walls (segments, half-planes clipped to ``view``) and circular obstacles posed at t (s)
    on a matplotlib axis; returns the artists drawn (to remove them for the next pose)."""
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Circle
    g = geometry.at(t) if geometry.is_moving else geometry
    out: list[Any] = []
    if len(g.segment_a):
        out.append(ax.add_collection(LineCollection(np.stack([g.segment_a, g.segment_b], 1),
                                                    colors=colour, linewidths=1.5)))
    for c, r in zip(g.circle_center, g.circle_radius):
        out.append(ax.add_patch(Circle(c, r, fill=True, facecolor="0.85", edgecolor=colour,
                                       lw=1.0)))
    if view is not None:
        x0, x1, y0, y1 = view
        for n, c, v in zip(g.halfplane_normal, g.halfplane_offset, g.halfplane_velocity):
            c = c + v * t
            # the boundary n . p = c, drawn across the view
            if abs(n[1]) > abs(n[0]):
                xs = np.array([x0, x1])
                ys = (c - n[0] * xs) / n[1]
            else:
                ys = np.array([y0, y1])
                xs = (c - n[1] * ys) / n[0]
            out += ax.plot(xs, ys, color=colour, lw=1.5)
    return out


def save_figure(fig: Any, png: str | Path, inputs: list[str]) -> None:
    """Saves ``fig`` as PNG to ``png`` through a temporary file renamed over it
    (:func:`sweep_core.io.outputs.replacing`); ``png`` may be none of ``inputs``."""
    with replacing(png, inputs, other="write beside another recording") as tmp:
        fig.savefig(tmp, format="png")
