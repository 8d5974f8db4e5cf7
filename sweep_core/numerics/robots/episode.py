"""The environment's per-step record of one robot in one compiled call (``sweep/CrowdNav-v0``,
:class:`sweep_core.envs.crowdnav.CrowdNavEnv`).

:func:`record` computes from the robot's pose and twist, the people and the goal field's grid
what the environment records and observes after a step: the robot's velocity in the map
frame, the clearance to the nearest person and the smallest time to collision
(:func:`~sweep_core.numerics.robots.social_kernels.nearest_pass`, the pass of
:func:`sweep_core.analysis.social.nearest`), the goal field's distance at the robot's position
clamped to the grid (:func:`~sweep_core.model.bilinear.bilinear`, the interpolation of
``Geodesic.travel_distance``), the odometry and the goal in base_link
(:func:`~sweep_core.model.elementary.sincos`), the scan's ranges bounded to [0, range_max]
(:func:`~sweep_core.numerics.robots.scan.bounded_ranges`) and the contacts' impulses summed
(:func:`~sweep_core.numerics.projection.pairwise.numpy_sum`, numpy's order). Each value is
computed by the same kernels, or the same operations in the same order, as the Python it
replaces (no fused multiply-add: numba compiles without fastmath), so the records and
observations keep their bits (test_episode_kernel compares them). The straight distance off
the grid and the goal's distance are left to the caller: they are Python's ``math.hypot``,
whose bits are not the C library's ``hypot``.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from sweep_core.model.bilinear import bilinear
from sweep_core.model.elementary import sincos
from sweep_core.numerics.projection.pairwise import numpy_sum
from sweep_core.numerics.robots.scan import bounded_ranges
from sweep_core.numerics.robots.social_kernels import nearest_pass

#: the length of :func:`record`'s ``out``: the row (11: t, x, y, yaw, vx, vy, clearance, ttc,
#: contacts, impulse, largest impulse), the distance on the grid, the clamped (x, y), and
#: the scratch of the nearest pass (3)
OUT = 17
#: where the distance to go on the grid and the clamped x and y are in ``out``
TOGO, CLAMPED_X, CLAMPED_Y = 11, 12, 13


@numba.njit(cache=True)
def clamp(s: float, low: float, high: float) -> float:  # pragma: no cover - compiled
    """Python's ``min(max(s, low), high)`` for floats (a NaN s kept: the builtins keep the
    first argument unless the other compares greater, or smaller)."""
    if low > s:
        s = low
    if high < s:
        s = high
    return s


@numba.njit(cache=True)
def largest(a: np.ndarray) -> float:  # pragma: no cover - compiled
    """numpy's ``a.max()`` of a (K,) vector, K >= 1: the first NaN propagates."""
    most = a[0]
    for k in range(1, a.shape[0]):
        if most != most:
            break
        if a[k] > most or a[k] != a[k]:
            most = a[k]
    return most


@numba.njit(cache=True)
def record(x: float, y: float, yaw: float, u: float, w: float, omega: float, t: float,
           radius: float, people: np.ndarray, radii: np.ndarray, velocities: np.ndarray,
           nodes_x: np.ndarray, nodes_y: np.ndarray, distance: np.ndarray, goal_x: float,
           goal_y: float, contacts: int, impulses: np.ndarray, ranges: np.ndarray,
           range_max: float, out: np.ndarray, odom: np.ndarray, goal: np.ndarray,
           scan: np.ndarray) -> None:  # pragma: no cover - compiled
    """One instant of a robot's episode.

    Args:
        x, y, yaw: the robot's pose (m, rad); u, w, omega its twist in base_link (m/s, rad/s).
        t: the time (s); radius: the robot's radius (m).
        people (N, 2) m, radii (N,) m, velocities (N, 2) m/s: the people.
        nodes_x (W,), nodes_y (H,) m, distance (H, W, 1) m: the goal field's grid and its
            travel distance (the distance left unread with fewer than 2 nodes along an axis).
        goal_x, goal_y: the goal (m); contacts: the people in contact with the robot;
            impulses (K, 2) m/s: their impulses (K = 0 without contact), summed in the row
            as |impulse| (numpy's ``hypot``, ``sum`` and ``max``: impulse and largest).
        ranges (B,) m, range_max m: the latest scan's ranges, bounded into ``scan`` (B,).
        out (:data:`OUT`,): the row, the distance to go on the grid at the position clamped
            to the grid (m) and that position (m); odom (6,): x, y, yaw, the twist; goal (2,):
            the goal in base_link (m).
    """
    s, c = sincos(yaw)
    vx, vy = c * u - s * w, s * u + c * w
    out[0], out[1], out[2], out[3], out[4], out[5] = t, x, y, yaw, vx, vy
    if people.shape[0] == 0:
        out[6], out[7] = math.inf, math.inf
    else:
        nearest_pass(x, y, vx, vy, radius, people, radii, velocities, out[14:17])
        out[6] = out[14]
        out[7] = out[15] if out[16] > 0 else math.nan
    out[8], out[9], out[10] = contacts, 0.0, 0.0
    if impulses.shape[0]:
        size = np.empty(impulses.shape[0])
        for k in range(impulses.shape[0]):
            size[k] = np.hypot(impulses[k, 0], impulses[k, 1])
        out[9], out[10] = numpy_sum(size), largest(size)
    cx = clamp(x, nodes_x[0], nodes_x[nodes_x.shape[0] - 1])
    cy = clamp(y, nodes_y[0], nodes_y[nodes_y.shape[0] - 1])
    out[TOGO], out[CLAMPED_X], out[CLAMPED_Y] = math.nan, cx, cy
    if nodes_x.shape[0] >= 2 and nodes_y.shape[0] >= 2:
        q = np.empty((1, 2))
        q[0, 0], q[0, 1] = cx, cy
        at = np.empty((1, 1))
        bilinear(nodes_x, nodes_y, distance, q, at)
        out[TOGO] = at[0, 0]
    odom[0], odom[1], odom[2], odom[3], odom[4], odom[5] = x, y, yaw, u, w, omega
    dx, dy = goal_x - x, goal_y - y
    goal[0], goal[1] = c * dx + s * dy, -s * dx + c * dy
    bounded_ranges(ranges, range_max, scan)
