"""Outlines: the vertex lists of polylines, polygons and regions, checked, and point-in-polygon.
Coordinates in m, points (M, 2)."""
from __future__ import annotations

from typing import Any

import numpy as np

from sweep_core import checks
from sweep_core.errors import SceneError


def chain_points(value: Any, field: str, closed: bool, least: int) -> np.ndarray:
    """The vertices (M, 2) of a polyline or polygon, checked: at least ``least`` points, no
    edge of zero length, and for a closed chain no two edges crossing (a closed chain given
    with its first point repeated at the end is accepted without the repeat)."""
    points = checks.array(value, field, (None, 2), "as [[x, y], ...]")
    if closed and len(points) > 1 and np.array_equal(points[0], points[-1]):
        points = points[:-1]
    if len(points) < least:
        shape = "a closed outline" if closed else "a chain"
        raise SceneError(field, f"has {len(points)} points; {shape} needs at least {least}",
                         "list the vertices in order, e.g. [[0, 0], [4, 0], [4, 3]]")
    ends = np.roll(points, -1, axis=0) if closed else points[1:]
    length = np.hypot(*(ends - points[: len(ends)]).T)
    if length.min() < 1e-12:
        k = int(np.argmin(length))
        raise SceneError(field, f"points {k} and {(k + 1) % len(points)} coincide at "
                         f"[{points[k, 0]:g}, {points[k, 1]:g}] (an edge of zero length)",
                         "remove the repeated point")
    if closed:
        crossing = first_crossing(points)
        if crossing is not None:
            i, j = crossing
            raise SceneError(field, f"edges {i} and {j} cross (the outline is not simple)",
                             "give the vertices in order around the outline, or split it into "
                             "several polygons")
    return points


def first_crossing(points: np.ndarray) -> tuple[int, int] | None:
    """The first pair of non-adjacent edges of a closed chain that intersect, or None."""
    a, b = points, np.roll(points, -1, axis=0)
    m = len(points)

    def orient(p: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
        return np.sign((q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1])
                       - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0]))

    for i in range(m - 2):
        j = np.arange(i + 2, m if i > 0 else m - 1)
        if len(j) == 0:
            continue
        o1 = orient(a[i], b[i], a[j])
        o2 = orient(a[i], b[i], b[j])
        o3 = orient(a[j], b[j], a[i])
        o4 = orient(a[j], b[j], b[i])
        hit = (o1 * o2 <= 0) & (o3 * o4 <= 0)
        if np.any(hit):
            return i, int(j[np.argmax(hit)])
    return None


def points_in_polygon(q: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(N,) bool: q (N, 2) inside the closed outline ``points`` (M, 2), even-odd rule on a ray
    towards +x."""
    a, b = points, np.roll(points, -1, axis=0)
    y = q[:, 1:2]
    straddle = (a[:, 1][None] > y) != (b[:, 1][None] > y)
    dy = np.where(b[:, 1] != a[:, 1], b[:, 1] - a[:, 1], 1.0)
    x_cross = a[:, 0][None] + (y - a[:, 1][None]) * (b[:, 0] - a[:, 0])[None] / dy
    return (np.count_nonzero(straddle & (x_cross > q[:, 0:1]), axis=1) % 2) == 1
