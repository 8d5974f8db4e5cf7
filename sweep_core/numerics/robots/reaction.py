"""The crowd's anticipatory avoidance of robots (``crowd_reaction: avoid``, defined in
:mod:`sweep_core.model.robots`): a term added to the people's wished velocity."""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from sweep_core.model import elementary
from sweep_core.model.robots import CrowdReaction


def avoidance(reaction: CrowdReaction, q: np.ndarray, states: Sequence[Any]) -> np.ndarray:
    """(N, 2) m/s: for every robot (``states``: objects with ``pose`` (x, y, yaw) and
    ``command`` (vx, vy, omega) in the robot's frame), people within ``reaction.radius`` m of the
    segment from the robot's centre to centre + horizon * velocity get ``strength`` (1 - d /
    radius) m/s away from the segment's nearest point (d their distance to it, m); a person on
    the segment itself is sent to the robot's left."""
    out = np.zeros_like(q)
    for st in states:
        x, y, yaw = st.pose
        vx, vy = st.command[0], st.command[1]
        s, c = elementary.sincos(yaw)
        wx, wy = reaction.horizon * (c * vx - s * vy), reaction.horizon * (s * vx + c * vy)
        length2 = wx * wx + wy * wy
        rel = q - np.array([x, y])
        if length2 > 0:
            u = np.clip((rel[:, 0] * wx + rel[:, 1] * wy) / length2, 0.0, 1.0)
        else:
            u = np.zeros(len(q))
        away = rel - u[:, None] * np.array([wx, wy])
        d = np.hypot(away[:, 0], away[:, 1])
        near = d < reaction.radius
        if not np.any(near):
            continue
        left = np.array([-s, c])
        unit = np.where((d > 1e-12)[:, None], away / np.maximum(d, 1e-12)[:, None], left)
        gain = np.where(near, reaction.strength * (1.0 - d / reaction.radius), 0.0)
        out += gain[:, None] * unit
    return out
