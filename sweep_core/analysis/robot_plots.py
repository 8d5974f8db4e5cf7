"""The robots in the figure of ``sweep analyze``: each robot's path over its episode (the
frames of :attr:`~sweep_core.analysis.metrics.Analysis.robots`), its heading as arrows about
once a second, its disk at the start, its goal and goal radius, and the frames with a contact
(crosses); drawn on the trajectories' axes by :mod:`sweep_core.analysis.plots`."""
from __future__ import annotations

from typing import Any

import numpy as np

#: colour of the robots' paths and markers
ROBOT_COLOUR = "tab:red"
#: about this many seconds between two heading arrows
ARROW_EVERY_S = 1.0


def draw_robots(ax: Any, an: Any) -> int:
    """Draws every robot of ``an`` (an :class:`~sweep_core.analysis.metrics.Analysis`) on
    ``ax``; returns how many were drawn (0 without robots)."""
    table = getattr(an, "robots", None)
    if table is None or not len(table):
        return 0
    from matplotlib.patches import Circle
    names = list((an.summary.get("robots") or {}).keys())
    specs = {str(r["name"]): r for r in
             ((an.meta.scene.spec.get("robots") or []) if an.meta.scene is not None else [])}
    drawn = 0
    for k in np.unique(table[:, 0]).astype(int):
        rows = table[table[:, 0] == k]
        t, x, y, yaw = rows[:, 1], rows[:, 2], rows[:, 3], rows[:, 4]
        name = names[k] if k < len(names) else f"robot {k}"
        label = f"robot {name}" if drawn == 0 or len(names) > 1 else None
        ax.plot(x, y, color=ROBOT_COLOUR, lw=2.0, zorder=5, label=label)
        gap = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
        every = max(1, int(round(ARROW_EVERY_S / gap))) if gap > 0 else 1
        pick = slice(0, len(t), every)
        ax.quiver(x[pick], y[pick], np.cos(yaw[pick]), np.sin(yaw[pick]), color=ROBOT_COLOUR,
                  angles="xy", scale_units="inches", scale=4.0, width=0.004, zorder=6)
        spec = specs.get(name, {})
        radius = float(spec.get("radius", 0.0))
        if radius > 0:
            ax.add_patch(Circle((x[0], y[0]), radius, fill=False, ec=ROBOT_COLOUR, lw=1.5,
                                zorder=6))
        goal = spec.get("goal")
        if goal is not None:
            ax.add_patch(Circle(tuple(goal[:2]), float(spec.get("goal_radius", 0.5)),
                                fill=False, ec=ROBOT_COLOUR, ls="--", lw=1.0, zorder=6))
            ax.plot([goal[0]], [goal[1]], marker="*", color=ROBOT_COLOUR, ms=10, zorder=6)
        touch = rows[:, 9] > 0
        if touch.any():
            ax.scatter(x[touch], y[touch], marker="x", s=30, c="k", zorder=7,
                       label="robot contacts" if drawn == 0 else None)
        drawn += 1
    return drawn
