"""Plots of an analysis (matplotlib, Agg backend)."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from sweep_core.analysis.metrics import SPEED_BIN, Analysis
from sweep_core.errors import SweepError
from sweep_core.io.outputs import replacing
from sweep_core.model.fields import Field, Groups
from sweep_core.model.geodesic import Geodesic, navigation_fields
from sweep_core.model.scene import Scene

#: travel-time contours drawn per navigation field
CONTOURS = 12


def pyplot() -> Any:
    try:
        import matplotlib
    except ImportError as err:
        raise SweepError("matplotlib is not installed (fix: pip install matplotlib, or pass "
                         "--no-plots)") from err
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def draw_scene(ax: Any, scene: Scene | None) -> None:
    """Walls (segments) and circular obstacles of a scene on a matplotlib axis."""
    if scene is None:
        return
    from matplotlib.patches import Circle
    g = scene.geometry
    for a, b in zip(g.segment_a, g.segment_b):
        ax.plot([a[0], b[0]], [a[1], b[1]], color="k", lw=1.5)
    for c, r in zip(g.circle_center, g.circle_radius):
        ax.add_patch(Circle(c, r, fill=False, color="k", lw=1.0))


def named_navigation_fields(drift: Field) -> list[tuple[str, Geodesic]]:
    """The geodesic / exits fields of a drift, named for a legend ("travel time", the group's
    name, or "others" for a groups drift's rest)."""
    found = navigation_fields(drift)
    if not isinstance(drift, Groups):
        return [("travel time", f) for _, f in found]
    return [(drift.names[k] if k >= 0 else "others", f) for k, f in found]


def draw_travel_time(ax: Any, scene: Scene | None) -> str:
    """Contours of the travel time T / speed (s) at t = 0 of the scene's navigation fields
    (one colour each) on a matplotlib axis; the title suffix saying so ("" if none)."""
    fields = named_navigation_fields(scene.drift) if scene is not None else []
    from matplotlib.lines import Line2D
    handles = []
    for k, (name, f) in enumerate(fields):
        seconds = f.travel / f.speed if f.speed > 0 else f.travel
        finite = seconds[np.isfinite(seconds)]
        if finite.size < 4 or float(finite.max()) <= 0:
            continue
        levels = np.linspace(0.0, float(finite.max()), CONTOURS + 1)[1:]
        colour = "0.45" if len(fields) == 1 else f"C{k + 1}"
        ax.contour(f.x, f.y, np.ma.masked_invalid(seconds), levels=levels, colors=colour,
                   linewidths=0.7, alpha=0.8)
        step = float(levels[1] - levels[0]) if len(levels) > 1 else float(levels[0])
        handles.append(Line2D([], [], color=colour, lw=0.7, label=f"{name}: every {step:.2g} s"))
    if not handles:
        return ""
    ax.legend(handles=handles, loc="upper right", fontsize=7, framealpha=0.7)
    return " and travel time"


def plot_analysis(an: Analysis, png: Path) -> None:
    plt = pyplot()
    tab, s = an.table, an.summary
    t = tab[:, 0]
    fig, axes = plt.subplots(2, 3, figsize=(12, 6.5), dpi=72)
    title = f"{s['scene'] or Path(an.meta.path).name}: {s['agents']} agents, {s['duration_s']:g} s"
    if s["truncated"]:
        title += " (truncated recording)"
    fig.suptitle(title)
    ax = axes[0, 0]
    gap = tab[:, 2]
    ax.plot(t, np.where(np.isfinite(gap), gap, np.nan), lw=1)
    ax.set_yscale("symlog", linthresh=1e-9)
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("minimum gap (m)")
    ax.set_title("minimum gap")
    ax = axes[0, 1]
    ax.plot(t, tab[:, 3], lw=1, color="C0")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("touching (gap <= 1e-6 m)", color="C0")
    ax2 = ax.twinx()
    ax2.plot(t, tab[:, 5], lw=1, color="C3")
    ax2.set_ylabel("total reaction / dt (m/s)", color="C3")
    ax.set_title("touching constraints and pressure")
    ax = axes[0, 2]
    ax.plot(t, tab[:, 6], lw=1, label="mean")
    ax.plot(t, tab[:, 7], lw=0.8, alpha=0.6, label="max")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("speed (m/s)")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title("speed over time")
    ax = axes[1, 0]
    h = an.speed_hist
    if h.sum():
        k = max(1, math.ceil(len(h) / 60))
        pad = np.concatenate([h, np.zeros(-len(h) % k, dtype=h.dtype)]).reshape(-1, k).sum(1)
        edges = np.arange(len(pad) + 1) * k * SPEED_BIN
        ax.stairs(pad / pad.sum(), edges, fill=True, alpha=0.7)
    ax.set_xlabel("speed (m/s)")
    ax.set_ylabel("fraction")
    ax.set_title("speed distribution")
    ax = axes[1, 1]
    drawn = False
    if s["flow"] is not None:
        ax.plot(t, tab[:, 8], lw=1.2, label="net crossings")
        drawn = True
    if s["arrivals"] is not None:
        ax.plot(t, tab[:, 9], lw=1.2, label="arrived")
        drawn = True
    if drawn:
        ax.legend(loc="upper left", fontsize=8)
    else:
        ax.text(0.5, 0.5, "no --line, no goal", ha="center", va="center",
                transform=ax.transAxes)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("agents")
    ax.set_title("flow and arrivals (cumulative)")
    ax = axes[1, 2]
    d = an.density
    x0, y0 = an.density_origin
    im = ax.imshow(np.ma.masked_equal(d, 0.0), origin="lower", cmap="viridis",
                   interpolation="nearest",
                   extent=(x0, x0 + d.shape[1] * an.cell, y0, y0 + d.shape[0] * an.cell))
    draw_scene(ax, an.meta.scene)
    travel = draw_travel_time(ax, an.meta.scene)
    if s["flow"] is not None:
        x_0, y_0, x_1, y_1 = s["flow"]["line"]
        ax.plot([x_0, x_1], [y_0, y_1], color="r", lw=1.5)
    fig.colorbar(im, ax=ax, label="agents / m²")
    ax.set_aspect("equal")
    ax.set_title(("density" if travel else "density (time average)") + travel)
    fig.tight_layout()
    save_figure(fig, png, [an.meta.path])
    plt.close(fig)


def save_figure(fig: Any, png: str | Path, inputs: list[str]) -> None:
    """Saves ``fig`` as PNG to ``png`` through a temporary file renamed over it
    (:func:`sweep_core.io.outputs.replacing`); ``png`` may be none of ``inputs``."""
    with replacing(png, inputs, other="write beside another recording") as tmp:
        fig.savefig(tmp, format="png")
