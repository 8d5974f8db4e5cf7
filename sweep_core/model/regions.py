"""Regions of the plane for the flow features (sinks, sources, journey legs): a rectangle or a
closed polygon, validated, with an inside test and uniform draws in the bounding box.

    {kind: rectangle, min: [x, y], max: [x, y]} | {kind: polygon, points: [[x, y], ...]}
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from sweep_core import checks
from sweep_core.errors import SceneError, show
from sweep_core.model.outlines import chain_points, points_in_polygon, signed_area


@dataclass(frozen=True, eq=False)
class Region:
    """A closed outline ``points`` (M, 2) m; ``lo``, ``hi``: its bounding box (m);
    ``spec``: the normalised dict."""

    points: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    spec: dict
    is_rectangle: bool

    def contains(self, q: np.ndarray) -> np.ndarray:
        """(N,) bool: the points q (N, 2) lie in the region (rectangle: closed box)."""
        q = np.asarray(q, dtype=np.float64).reshape(-1, 2)
        if self.is_rectangle:
            return np.all((q >= self.lo) & (q <= self.hi), axis=1)
        return points_in_polygon(q, self.points)

    def distance(self, q: np.ndarray) -> np.ndarray:
        """(N,) distance (m) from the points q (N, 2) to the region, 0 inside."""
        q = np.asarray(q, dtype=np.float64).reshape(-1, 2)
        a, b = self.points, np.roll(self.points, -1, axis=0)
        ab = b - a
        rel = q[:, None, :] - a[None]
        s = np.clip(np.einsum("mkc,kc->mk", rel, ab) / np.einsum("kc,kc->k", ab, ab), 0.0, 1.0)
        foot = a[None] + s[..., None] * ab[None]
        d = np.hypot(*(q[:, None, :] - foot).transpose(2, 0, 1)).min(axis=1, initial=np.inf)
        return np.where(self.contains(q), 0.0, d)

    @property
    def area(self) -> float:
        """Area (m^2) of the outline."""
        return abs(signed_area(self.points))


def region_from_spec(value: Any, field: str) -> Region:
    """Validate a region dict (module docstring); errors name ``field``."""
    fix = (f"write {field} as {{kind: rectangle, min: [x, y], max: [x, y]}} or "
           "{kind: polygon, points: [[x, y], ...]}")
    if not isinstance(value, dict):
        raise SceneError(field, f"must be a mapping, got {show(value)}", fix)
    if checks.kind(value, field, ("rectangle", "polygon")) == "rectangle":
        checks.mapping(value, field, allowed={"kind", "min", "max"}, required={"min", "max"})
        lo, hi = checks.point(value["min"], f"{field}.min"), checks.point(value["max"],
                                                                           f"{field}.max")
        if np.any(hi <= lo):
            raise SceneError(field, f"min {show(lo)} is not below max {show(hi)}",
                             "give the lower-left corner as min and the upper-right as max")
        pts = np.array([lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]])
        return Region(pts, lo, hi, {"kind": "rectangle", "min": lo.tolist(),
                                    "max": hi.tolist()}, True)
    checks.mapping(value, field, allowed={"kind", "points"}, required={"points"})
    pts = chain_points(value["points"], f"{field}.points", True, 3)
    return Region(pts, pts.min(axis=0), pts.max(axis=0),
                  {"kind": "polygon", "points": pts.tolist()}, False)


def target_from_spec(value: Any, field: str) -> tuple[Region | np.ndarray, dict]:
    """A walking target given as ``{goal: [x, y]}`` or ``{region: {...}}`` (a journey's leg, an
    exit): the point (2,) m or the region, and its normalised spec."""
    checks.mapping(value, field, allowed={"goal", "region"})
    if ("goal" in value) == ("region" in value):
        raise SceneError(field, f"gives {'both' if 'goal' in value else 'neither'} goal and "
                         "region", f"give {field}.goal: [x, y] or {field}.region: {{kind: "
                         "rectangle, min: [x, y], max: [x, y]}")
    if "goal" in value:
        goal = checks.point(value["goal"], f"{field}.goal")
        return goal, {"goal": goal.tolist()}
    region = region_from_spec(value["region"], f"{field}.region")
    return region, {"region": region.spec}
