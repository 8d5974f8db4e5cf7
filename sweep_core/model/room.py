"""The most agents a scene's room can hold at once (:func:`most_present`), for the recording
size a run is estimated to reach (:func:`sweep_core.io.limits.check_run_size`): agents that
enter at sources cannot all be present when the room has no space for them.

The room is the smallest closed polyline wall (an outline) around every agent at t = 0 and
every source's region: agents never cross a wall, so every agent of the run stays inside it,
as disjoint disks of radius at least r (the smallest radius of the scene's agents and
sources, less the radius law's deepest shrink before the end of the run). Their number is
bounded

- in a convex room, by Oler's inequality on the centres, points at mutual distance at least
  d = 2 r in the room shrunk by r, a convex polygon K (Oler 1961, Canad. Math. Bull. 4, 153):
  n <= 2 A(K) / (sqrt(3) d^2) + P(K) / (2 d) + 1, A the area and P the perimeter;
- in any other room, by the disks' area: n pi r^2 <= the room's area.

Both are proofs, so the estimate they bound never refuses a run that fits for that reason;
the convex bound is within about 1.3 of what a full room holds (see test/test_estimates.py).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from sweep_core.model.outlines import perimeter, points_in_polygon, signed_area

__all__ = ["most_present"]


def _convex(points: np.ndarray) -> bool:
    """The closed polygon ``points`` (M, 2) turns one way only (collinear vertices allowed)."""
    e = np.roll(points, -1, axis=0) - points
    f = np.roll(e, -1, axis=0)
    cross = e[:, 0] * f[:, 1] - e[:, 1] * f[:, 0]
    return bool(np.all(cross >= 0) or np.all(cross <= 0))


def _shrunk(points: np.ndarray, r: float) -> np.ndarray:
    """The convex polygon ``points`` (M, 2) shrunk by r (m): the intersection of its edges'
    half-planes each moved r inwards (an empty (0, 2) array when nothing is left)."""
    pts = points if signed_area(points) > 0 else points[::-1]
    out = pts.copy()
    for a, b in zip(pts, np.roll(pts, -1, axis=0)):
        e = b - a
        norm = math.hypot(*e)
        if norm == 0.0:
            continue
        inward = np.array([-e[1], e[0]]) / norm
        if not len(out):
            break
        # >= 0: kept; x-then-y products (BLAS's kernels differ by CPU)
        side = (out[:, 0] - a[0]) * inward[0] + (out[:, 1] - a[1]) * inward[1] - r
        keep = []
        for k in range(len(out)):
            p, q = out[k], out[(k + 1) % len(out)]
            sp, sq = side[k], side[(k + 1) % len(out)]
            if sp >= 0:
                keep.append(p)
            if (sp >= 0) != (sq >= 0):
                keep.append(p + (q - p) * (sp / (sp - sq)))
        out = np.array(keep).reshape(-1, 2)
    return out


def _room_bound(points: np.ndarray, r: float) -> int:
    """Most disjoint disks of radius r (m) inside the closed polygon ``points`` (M, 2)."""
    if _convex(points):
        inner = _shrunk(points, r)
        if len(inner) < 3:
            return 1
        d = 2.0 * r
        return int(math.floor(2.0 * abs(signed_area(inner)) / (math.sqrt(3.0) * d * d)
                              + perimeter(inner) / (2.0 * d) + 1.0))
    return int(math.floor(abs(signed_area(points)) / (math.pi * r * r)))


def most_present(scene: Any, t_end: float) -> int | None:
    """The most agents of ``scene`` present at once during a run to ``t_end`` (s), bounded by
    the room that holds them (module docstring); None when no closed outline holds every
    initial agent and source region."""
    sources = scene.flows.sources if scene.flows is not None else ()
    radii = [float(np.min(scene.radius))] if scene.n_agents else []
    radii += [s.r_low for s in sources]
    if not radii:
        return None
    r = min(radii) + scene.radius_law.min_offset(t_end)
    if not r > 0:
        return None
    # a source region's vertices drawn a little towards its middle: a region may touch the
    # room's outline (never cross it: flow_checks.crossing_wall), so a vertex may lie on it
    inside = [scene.positions] + [p + 1e-6 * (p.mean(axis=0) - p)
                                  for p in (s.region.points for s in sources)]
    best: int | None = None
    for wall in scene.spec.get("walls", []):
        if wall.get("kind") != "polyline" or not wall.get("closed"):
            continue
        outline = np.asarray(wall["points"], dtype=np.float64)
        if all(bool(np.all(points_in_polygon(q, outline))) for q in inside if len(q)):
            bound = _room_bound(outline, r)
            best = bound if best is None else min(best, bound)
    return best
