"""The targets of a navigation field: a goal point, a goal region (rectangle or polygon), or
one of several weighted exits (:class:`Target`), validated from their scene dicts
(:func:`target_from_spec`, :func:`navigation_targets`); see :mod:`sweep_core.model.geodesic`."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sweep_core import checks
from sweep_core.errors import SceneError, show
from sweep_core.model.outlines import chain_points, points_in_polygon


@dataclass(frozen=True, eq=False)
class Target:
    """A goal point (``points`` of one row) or a goal region (a closed outline), normalised
    spec and weight."""

    points: np.ndarray
    is_region: bool
    spec: dict
    weight: float = 1.0

    def nearest(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance (M,) m from q (M, 2) to the target (0 inside a region) and the nearest
        point of the target (M, 2)."""
        if not self.is_region:
            d = q - self.points[0]
            return np.hypot(d[:, 0], d[:, 1]), np.broadcast_to(self.points[0], q.shape).copy()
        a, b = self.points, np.roll(self.points, -1, axis=0)
        ab = b - a
        rel = q[:, None, :] - a[None]
        s = np.clip(np.einsum("mkc,kc->mk", rel, ab) / np.einsum("kc,kc->k", ab, ab), 0.0, 1.0)
        foot = a[None] + s[..., None] * ab[None]
        dist = np.hypot(*(q[:, None, :] - foot).transpose(2, 0, 1))
        k = np.argmin(dist, axis=1)
        rows = np.arange(len(q))
        d, p = dist[rows, k], foot[rows, k]
        inside = points_in_polygon(q, self.points)
        return np.where(inside, 0.0, d), np.where(inside[:, None], q, p)

    def arrived(self, q: np.ndarray, radius: float) -> np.ndarray:
        """(N,) bool: q (N, 2) is within radius m of the goal point, or inside the region."""
        d, _ = self.nearest(q)
        return d <= (0.0 if self.is_region else radius)


def navigation_targets(spec: dict, field: str = "drift") -> list[tuple[str, Target]]:
    """The goals of a ``geodesic`` or ``exits`` drift spec, named for reports: [("goal" or
    "region", target)] or [("exits[k]", target), ...] (for arrivals per exit: see
    :meth:`Target.arrived`)."""
    if spec.get("kind") == "exits":
        raw = spec.get("exits")
        if not isinstance(raw, list):
            raise SceneError(f"{field}.exits", f"must be a list, got {show(raw)}",
                             f"write {field}.exits as a list of {{goal: [x, y]}} items")
        return [(f"exits[{k}]", target_from_spec(checks.mapping(e, f"{field}.exits[{k}]"),
                                        f"{field}.exits[{k}]", True))
                for k, e in enumerate(raw)]
    target = target_from_spec(spec, field, False)
    return [("region" if target.is_region else "goal", target)]


def target_from_spec(spec: dict, field: str, weighted: bool) -> Target:
    keys = {"goal", "region"} | ({"weight"} if weighted else set())
    if ("goal" in spec) == ("region" in spec):
        raise SceneError(field, f"gives {'both' if 'goal' in spec else 'neither'} goal and region",
                         f"give {field}.goal: [x, y] or {field}.region: {{kind: rectangle, "
                         "min: [x, y], max: [x, y]}")
    if weighted:
        checks.mapping(spec, field, allowed=keys)
    weight = 1.0
    out: dict = {}
    if weighted:
        weight = checks.number(spec.get("weight", 1.0), f"{field}.weight", positive=True)
    if "goal" in spec:
        g = checks.point(spec["goal"], f"{field}.goal")
        out["goal"] = g.tolist()
        target = Target(g[None], False, out, weight)
    else:
        rf = f"{field}.region"
        region = checks.mapping(spec["region"], rf)
        if checks.kind(region, rf, ("rectangle", "polygon")) == "rectangle":
            checks.mapping(region, rf, allowed={"kind", "min", "max"}, required={"min", "max"})
            lo, hi = checks.point(region["min"], f"{rf}.min"), checks.point(region["max"], f"{rf}.max")
            if np.any(hi <= lo):
                raise SceneError(rf, f"min {show(lo)} is not below max {show(hi)}",
                                 "give the lower-left corner as min and the upper-right as max")
            points = np.array([lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]])
            out["region"] = {"kind": "rectangle", "min": lo.tolist(), "max": hi.tolist()}
        else:
            checks.mapping(region, rf, allowed={"kind", "points"}, required={"points"})
            points = chain_points(region["points"], f"{rf}.points", True, 3)
            out["region"] = {"kind": "polygon", "points": points.tolist()}
        target = Target(points, True, out, weight)
    if weighted:
        out["weight"] = weight
    return target
