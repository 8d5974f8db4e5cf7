"""The figure of ``sweep analyze`` (matplotlib, Agg): six labelled panels (:func:`analysis_figure`).

Top, in the room's own aspect (equal axes): the trajectories coloured by group (and the robots:
path, heading, contacts, :mod:`.robot_plots`), and the density
map with the travel-time contours of the navigation fields (legends outside the room). Bottom:
the agents who arrived and crossed the counting line per group and per exit; the run's
fundamental diagram (local density against speed); speeds and touching constraints; the
distribution of the per-frame minimum gap, touching frames (|gap| at rounding level) counted
apart. Time axes mark the node's commands, resets and map changes."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from sweep_core.analysis.crowd import ROUNDING_M, gap_distribution
from sweep_core.analysis.drawing import (
    agent_groups,
    draw_geometry,
    group_colour,
    pyplot,
    save_figure,
    view_of,
)
from sweep_core.analysis.metrics import Analysis
from sweep_core.analysis.references import weidmann
from sweep_core.analysis.robot_plots import draw_robots
from sweep_core.analysis.run import NS
from sweep_core.errors import SweepError
from sweep_core.model.fields import NAVIGATION_KINDS, Field, Groups
from sweep_core.model.geodesic import Geodesic, navigation_fields
from sweep_core.model.scene import Scene

__all__ = ["analysis_figure", "draw_travel_time", "named_navigation_fields", "plot_analysis",
           "pyplot", "save_figure"]

#: travel-time contours drawn per navigation field
CONTOURS = 12
#: the figure's width (inches; its height follows the room) and resolution (pixels per inch)
SIZE, DPI = (14.0, 15.0), 72
#: a room wider than this (width / height) gets the whole width of the figure
WIDE = 1.8
#: height (inches) of each lower panel, and room for a legend below a room's panel
PANEL_HEIGHT, LEGEND = 3.6, 0.7
#: how each kind of event is drawn on the time axes: (colour, line style)
EVENT_STYLE = {"command": ("C1", "--"), "reset": ("k", "-"), "map": ("C4", ":")}


def draw_scene(ax: Any, scene: Scene | None) -> None:
    """Walls (segments) and circular obstacles of a scene at t = 0 on a matplotlib axis."""
    if scene is not None:
        draw_geometry(ax, scene.geometry)


def named_navigation_fields(drift: Field) -> list[tuple[str, Geodesic]]:
    """The geodesic / exits fields of a drift, named for a legend ("travel time", the group's
    name, or "others" for a groups drift's rest)."""
    return [(name, f) for name, _, f in _navigation(drift)]


def _navigation(drift: Field) -> list[tuple[str, str, Geodesic]]:
    """(name, colour, field) of each navigation field: the group's colour under groups."""
    found = navigation_fields(drift)
    if not isinstance(drift, Groups):
        return [("travel time", "0.45", f) for _, f in found]
    return [(drift.names[k] if k >= 0 else "others", group_colour(k), f) for k, f in found]


def commanded_navigation(an: Analysis) -> tuple[int, Field] | None:
    """For a scene without a navigation field: the last command (its index and drift, built as
    the node built it) that gave one (a goal command round the walls), or None."""
    scene = an.meta.scene
    if scene is None or navigation_fields(scene.drift):
        return None
    for c in sorted(an.meta.commands, key=lambda c: (c.segment, c.step, c.index), reverse=True):
        if not _navigates(c.spec):
            continue
        try:
            drift = scene.drift_from_spec(c.spec, f"command {c.index}")
        except SweepError:
            continue  # a command the recording's scene cannot rebuild: no contours from it
        if navigation_fields(drift):
            return c.index, drift
    return None


def _navigates(spec: Any) -> bool:
    """A drift spec has a navigation kind (itself, a group's drift or a groups drift's rest)."""
    if not isinstance(spec, dict):
        return False
    if spec.get("kind") in NAVIGATION_KINDS:
        return True
    groups = spec.get("groups") if spec.get("kind") == "groups" else None
    return isinstance(groups, list) and (
        any(isinstance(g, dict) and _navigates(g.get("drift")) for g in groups)
        or _navigates(spec.get("rest")))


def draw_travel_time(ax: Any, scene: Scene | None, legend_below: bool = False,
                     drift: Field | None = None, source: str = "") -> str:
    """Contours of the travel time T / speed (s) at t = 0 of the navigation fields of
    ``drift`` (default: the scene's), one colour each (a group's own), on a matplotlib axis,
    with their legend (below the axes with ``legend_below``; ``source`` names where the drift
    comes from); the title suffix saying so ("" if none)."""
    if drift is None and scene is not None:
        drift = scene.drift
    fields = _navigation(drift) if drift is not None else []
    from matplotlib.lines import Line2D
    handles = []
    for name, colour, f in fields:
        seconds = f.travel / f.speed if f.speed > 0 else f.travel
        finite = seconds[np.isfinite(seconds)]
        if finite.size < 4 or float(finite.max()) <= 0:
            continue
        levels = np.linspace(0.0, float(finite.max()), CONTOURS + 1)[1:]
        ax.contour(f.x, f.y, np.ma.masked_invalid(seconds), levels=levels, colors=colour,
                   linewidths=0.7, alpha=0.8)
        step = float(levels[1] - levels[0]) if len(levels) > 1 else float(levels[0])
        handles.append(Line2D([], [], color=colour, lw=0.7, label=f"{name}: every {step:.2g} s"))
    if not handles:
        return ""
    if legend_below:
        ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, 0.0),
                  borderaxespad=4.0, fontsize=8, ncol=min(3, len(handles)), frameon=False,
                  title="travel time to the goal" + (f" ({source})" if source else ""),
                  title_fontsize=8)
    else:
        ax.legend(handles=handles, loc="upper right", fontsize=7, framealpha=0.7)
    return " and travel time"


def events(an: Analysis) -> list[tuple[float, str, str]]:
    """(t s on the table's clock, kind, text) of the node's commands, resets and map changes."""
    meta, t0 = an.meta, an.t0_ns
    out = [((c.log_time_ns - t0) / NS, "command", f"command {c.index}") for c in meta.commands]
    out += [((ns - t0) / NS, "reset", f"reset {k + 1}") for k, ns in enumerate(meta.resets)]
    out += [((m.log_time_ns - t0) / NS, "map", f"map {m.index}") for m in meta.maps]
    return sorted(out)


def mark_events(ax: Any, marks: list[tuple[float, str, str]]) -> None:
    """Vertical lines at the events, one legend entry per kind."""
    seen: set[str] = set()
    for t, kind, _ in marks:
        colour, style = EVENT_STYLE[kind]
        ax.axvline(t, color=colour, ls=style, lw=1.0, alpha=0.8,
                   label=kind + "s" if kind not in seen else None)
        seen.add(kind)


def draw_line(ax: Any, an: Analysis) -> None:
    """The counting line of ``--line``, thick with a white edge, its ends marked and an arrow
    in its positive direction (left to right looking from its first end to its second)."""
    flow = an.summary["flow"]
    if flow is None:
        return
    import matplotlib.patheffects as pe
    x0, y0, x1, y1 = flow["line"]
    edge = [pe.Stroke(linewidth=5.5, foreground="white"), pe.Normal()]
    ax.plot([x0, x1], [y0, y1], color="#d62728", lw=3.0, solid_capstyle="butt", zorder=6,
            path_effects=edge, marker="|", ms=12, mew=2.5, label="counting line")
    length = max(float(np.hypot(x1 - x0, y1 - y0)), 1e-9)
    nx, ny = (y1 - y0) / length, -(x1 - x0) / length
    mx, my = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    reach = 0.4 * length
    ax.annotate("", xy=(mx + reach * nx, my + reach * ny), xytext=(mx, my), zorder=6,
                arrowprops={"arrowstyle": "-|>", "color": "#d62728", "lw": 2.0})


def _room(ax: Any, an: Analysis) -> None:
    """Equal axes on the box of the walls, obstacles and trajectories."""
    pts = an.tracks.reshape(-1, 2) if an.tracks.size else np.zeros((0, 2))
    x0, x1, y0, y1 = view_of(an.meta.scene, pts[np.all(np.isfinite(pts), axis=1)], 0.3)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")


def _trajectories(ax: Any, an: Analysis) -> None:
    tracks = an.tracks
    n = tracks.shape[1] if tracks.ndim == 3 else 0
    groups, names = agent_groups(an.meta.scene, n)
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Patch
    present = set(groups.tolist())
    order = sorted(k for k in present if k >= 0) + ([-1] if -1 in present else [])
    for k in order:
        idx = np.flatnonzero(groups == k)
        segs = [tracks[:, i][np.all(np.isfinite(tracks[:, i]), axis=1)] for i in idx]
        ax.add_collection(LineCollection(segs, colors=group_colour(k), linewidths=0.8,
                                         alpha=0.7, label=f"trajectories of group {k}"))
    if len(tracks):
        ax.scatter(tracks[0, :, 0], tracks[0, :, 1], s=8, c="k", marker="o", zorder=3,
                   label="start")
        ax.autoscale_view()
    draw_scene(ax, an.meta.scene)
    draw_line(ax, an)
    draw_robots(ax, an)
    _room(ax, an)
    handles = [Patch(color=group_colour(k), label=names[k] if k >= 0 else "others")
               for k in order] if names else []
    if handles:
        ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, 0.0),
                  borderaxespad=4.0, fontsize=8, ncol=min(4, len(handles)), frameon=False,
                  title="groups", title_fontsize=8)
    ax.set_title(f"trajectories ({n} agents" + (", coloured by group)" if names else ")"))


def _density(fig: Any, ax: Any, an: Analysis) -> None:
    d = an.density
    x0, y0 = an.density_origin
    im = ax.imshow(np.ma.masked_equal(d, 0.0), origin="lower", cmap="viridis",
                   interpolation="nearest",
                   extent=(x0, x0 + d.shape[1] * an.cell, y0, y0 + d.shape[0] * an.cell))
    draw_scene(ax, an.meta.scene)
    commanded = commanded_navigation(an)
    if commanded is None:
        travel = draw_travel_time(ax, an.meta.scene, legend_below=True)
    else:
        travel = draw_travel_time(ax, an.meta.scene, True, commanded[1],
                                  f"the field of command {commanded[0]}")
    flow = an.summary["flow"]
    draw_line(ax, an)
    fig.colorbar(im, ax=ax, label="agents / m² (time average)", shrink=0.7)
    _room(ax, an)
    ax.set_title("density" + travel + (" (red: counting line, arrow: positive)"
                                       if flow is not None else ""))


def _cumulative(times: np.ndarray, t_end: float) -> tuple[np.ndarray, np.ndarray]:
    """A step curve of how many of ``times`` have passed, from 0 to t_end (s)."""
    t = np.sort(times[np.isfinite(times)])
    return (np.concatenate([[0.0], np.repeat(t, 2), [t_end]]),
            np.concatenate([[0, 0], np.repeat(np.arange(1, len(t) + 1), 2)[:-1], [len(t)]])
            if len(t) else np.array([0, 0]))


def _arrivals(ax: Any, an: Analysis, marks: list) -> None:
    tab, s = an.table, an.summary
    t_end = float(tab[-1, 0])
    n = len(an.arrival)
    groups, names = agent_groups(an.meta.scene, n)
    drawn = False
    if s["arrivals"] is not None:
        ax.plot(*_cumulative(an.arrival, t_end), color="k", lw=1.6, label="arrived, all")
        for k, name in enumerate(names):
            ax.plot(*_cumulative(an.arrival[groups == k], t_end), color=group_colour(k),
                    lw=1.2, label=f"arrived, {name}")
        # every exit, those nobody reached too (a flat line at 0)
        labels = list(s["per_exit"] or {}) or sorted({e for e in an.arrival_exit if e})
        exits = np.array([e if e is not None else "" for e in an.arrival_exit])
        for j, label in enumerate(labels):
            ax.plot(*_cumulative(an.arrival[exits == label], t_end), color="0.35",
                    ls=(0, (1 + j, 1 + j)), lw=1.0, label=f"arrived at {label}")
        drawn = True
    if s["flow"] is not None:
        ax.plot(tab[:, 0], tab[:, 8], color="C3", lw=1.4, label="line: net crossings")
        _reference_band(ax, s["flow"], t_end)
        for k, name in enumerate(names):
            ax.plot(*_cumulative(an.evacuation[groups == k], t_end), color=group_colour(k),
                    lw=1.0, ls="--", label=f"line: {name} crossed")
        drawn = True
    if not drawn:
        ax.text(0.5, 0.5, "no goal and no --line: nothing arrives or crosses",
                ha="center", va="center", transform=ax.transAxes)
    mark_events(ax, marks)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("agents (cumulative)")
    ax.set_title("arrivals and flow per group and exit")
    if drawn or marks:
        ax.legend(loc="upper left", fontsize=7)


def _reference_band(ax: Any, flow: dict, t_end: float) -> None:
    """The experiments' flow for the line's width from its first crossing on: a band of the
    tolerance sweep verify accepts around their line (references.flow_reference)."""
    ref, t1 = flow.get("reference") or {}, flow.get("t_first_s")
    if "flow_per_s" not in ref or t1 is None or t_end <= t1:
        return
    t = np.array([t1, t_end])
    lo, hi = ref["band_per_s"]
    ax.fill_between(t, (t - t1) * lo, (t - t1) * hi, color="0.6", alpha=0.35, lw=0,
                    label=f"experiments at {ref['width_m']:.2g} m: {ref['flow_per_s']:.2f}/s "
                          f"± {100 * (hi / ref['flow_per_s'] - 1):.0f} %")
    ax.plot(t, (t - t1) * ref["flow_per_s"], color="0.35", lw=1.0, ls="--")


def _fundamental(fig: Any, ax: Any, an: Analysis) -> None:
    fd = an.fundamental
    if fd is None or not fd.counts.any():
        ax.text(0.5, 0.5, "no speeds recorded (/agents)", ha="center", va="center",
                transform=ax.transAxes)
    else:
        keep = fd.counts.sum(axis=1) > 0
        top = int(np.flatnonzero(keep)[-1]) + 2
        counts = np.ma.masked_equal(fd.counts[:top], 0)
        from matplotlib.colors import LogNorm
        im = ax.pcolormesh(fd.density_edges[:top + 1], fd.speed_edges, counts.T,
                           norm=LogNorm(), cmap="Greys")
        fig.colorbar(im, ax=ax, label="agent-frames")
        rho, mean = fd.mean_speed()
        ax.plot(rho[:top], mean[:top], "o-", color="C3", ms=3, lw=1.2, label="mean speed")
        dens = np.linspace(max(float(fd.density_edges[0]), 0.2),
                           min(float(fd.density_edges[top]), 5.4), 100)
        ax.plot(dens, weidmann(dens), color="C0", lw=1.6,
                label="Weidmann 1993 (free speed 1.34 m/s)")
        ax.legend(loc="upper right", fontsize=7)
    ax.set_xlabel("local density (1/m², agents within 1 m)")
    ax.set_ylabel(f"speed over {an.speed_window:g} s (m/s)")
    ax.set_title("fundamental diagram beside Weidmann's")


def _speeds(ax: Any, an: Analysis, marks: list) -> None:
    tab = an.table
    ax.plot(tab[:, 0], tab[:, 6], lw=1.2, color="C0", label="mean speed")
    ax.plot(tab[:, 0], tab[:, 7], lw=0.7, color="C0", alpha=0.45, label="max speed")
    ax.set_xlabel("t (s)")
    ax.set_ylabel(f"speed over {an.speed_window:g} s (m/s)")
    ax2 = ax.twinx()
    ax2.plot(tab[:, 0], tab[:, 3], lw=1.0, color="C2")
    ax2.set_ylabel("touching constraints (gap <= 1e-6 m)", color="C2")
    mark_events(ax, marks)
    ax.legend(loc="upper left", fontsize=7)
    ax.set_title("speed and contacts over time")


#: classes of the per-frame minimum gap (m) beyond touching: (upper bound, label)
GAP_CLASSES = ((1e-6, "1e-9 to\n1e-6 m"), (1e-5, "1e-6 to\n1e-5 m"), (1e-4, "1e-5 to\n1e-4 m"),
               (1e-3, "0.1 to\n1 mm"), (1e-2, "1 to\n10 mm"), (1e-1, "1 to\n10 cm"),
               (np.inf, "above\n10 cm"))


def gap_classes(gaps: np.ndarray) -> tuple[list[str], np.ndarray]:
    """The per-frame minimum gaps (m) as a distribution over frames: labels and fractions
    (summing to 1 over the frames with a gap) of overlapping, touching (|gap| at rounding
    level) and each class of :data:`GAP_CLASSES` up to the largest gap."""
    touching, overlap, positive = gap_distribution(gaps)
    total = touching + overlap + len(positive)
    labels = [f"overlap\n< -{ROUNDING_M:g} m", f"touching\n|gap| <= {ROUNDING_M:g} m"]
    counts = [overlap, touching]
    lower = ROUNDING_M
    top = float(positive.max()) if len(positive) else 0.0
    for upper, label in GAP_CLASSES:
        if lower >= top and len(counts) > 2:
            break
        counts.append(int(np.count_nonzero((positive > lower) & (positive <= upper))))
        labels.append(label)
        lower = upper
    frac = np.array(counts, dtype=np.float64) / max(total, 1)
    if not overlap:  # no overlap: its class is left out
        labels, frac = labels[1:], frac[1:]
    return labels, frac


def _gaps(ax: Any, an: Analysis) -> None:
    labels, frac = gap_classes(an.table[:, 2])
    colours = ["C3" if lab.startswith("overlap") else "0.45" if lab.startswith("touching")
               else "C0" for lab in labels]
    x = np.arange(len(labels))
    ax.bar(x, frac, color=colours, width=0.8)
    for k, f in enumerate(frac):
        if f > 0:
            ax.text(k, f, f"{f:.0%}" if f >= 0.01 else f"{f:.1%}", ha="center", va="bottom",
                    fontsize=7)
    ax.set_xticks(x, labels, fontsize=7)
    ax.set_ylim(0, min(1.0, float(frac.max()) * 1.15 + 0.02))
    ax.set_xlabel("minimum gap of a frame (touching: at rounding level, not a distance)")
    ax.set_ylabel("fraction of frames (bars sum to 1)")
    ax.set_title("minimum gap: distribution over frames")


def analysis_figure(an: Analysis) -> Any:
    """The figure (see the module docstring); close it with pyplot's ``close``."""
    plt = pyplot()
    s = an.summary
    pts = an.tracks.reshape(-1, 2) if an.tracks.size else np.zeros((0, 2))
    x0, x1, y0, y1 = view_of(an.meta.scene, pts[np.all(np.isfinite(pts), axis=1)], 0.3)
    aspect = (x1 - x0) / (y1 - y0)
    wide = aspect > WIDE
    # a wide room takes the whole width, once for the trajectories and once for the density
    # the room's panels as tall as their width and aspect need (legends below: LEGEND)
    room = (min(max(SIZE[0] * 0.85 / aspect, 1.6), 6.0) if wide
            else min(max(SIZE[0] * 0.4 / aspect, 2.5), 6.5))
    rows = (room + LEGEND, room + LEGEND) if wide else (room + LEGEND,)
    fig = plt.figure(figsize=(SIZE[0], sum(rows) + 2 * PANEL_HEIGHT + 0.5), dpi=DPI,
                     layout="constrained")
    grid = fig.add_gridspec(len(rows) + 2, 2, height_ratios=rows + (PANEL_HEIGHT,) * 2)
    title = f"{s['scene'] or Path(an.meta.path).name}: {s['agents']} agents, {s['duration_s']:g} s"
    if s["truncated"]:
        title += " (truncated recording)"
    fig.suptitle(title, fontsize=14)
    marks = events(an)
    _trajectories(fig.add_subplot(grid[0, :] if wide else grid[0, 0]), an)
    _density(fig, fig.add_subplot(grid[1, :] if wide else grid[0, 1]), an)
    top = len(rows)
    _arrivals(fig.add_subplot(grid[top, 0]), an, marks)
    _fundamental(fig, fig.add_subplot(grid[top, 1]), an)
    _speeds(fig.add_subplot(grid[top + 1, 0]), an, marks)
    _gaps(fig.add_subplot(grid[top + 1, 1]), an)
    return fig


def plot_analysis(an: Analysis, png: Path) -> None:
    """Writes the figure to ``png`` (never over the recording)."""
    fig = analysis_figure(an)
    save_figure(fig, png, [an.meta.path])
    pyplot().close(fig)
