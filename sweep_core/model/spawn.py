"""A starting crowd for a scene's geometry: ``agents.spawn`` places non-overlapping disks in
the free space of a region (random sequential addition).

    agents:
      spawn: {region: {kind: rectangle, min: [x, y], max: [x, y]}
                      | {kind: polygon, points: [[x, y], ...]},
              count: N, radius: R | [R_min, R_max], seed: S}

Candidates are drawn uniformly in the region (radii uniformly in [R_min, R_max] when a range
is given), in batches; a candidate is kept when its centre is in the region, its disk lies
clear of every wall, obstacle and blocked map cell, and it does not overlap a disk kept
before (within a batch, the earlier candidate wins). The draws stop when N disks are placed,
or when 50 batches in a row place nothing: then the scene is refused with how many fitted.
Random sequential addition jams near 55 % of the plane covered by equal disks (Feder 1980),
so a region asked for more than about half of its area cannot be filled this way. The
positions and radii found are written into the scene's spec, so a recording replays them
without drawing again.
"""
from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from sweep_core import checks
from sweep_core.errors import SceneError, show
from sweep_core.model.geometry import Geometry, single_rows
from sweep_core.model.maps import OccupancyMap
from sweep_core.model.outlines import chain_points, points_in_polygon

#: candidates drawn per batch, per agent still to place (at least 64)
BATCH = 4
#: batches in a row that place nothing before the draws stop
PATIENCE = 50


def spawn(value: Any, field: str, geometry: Geometry, grid: OccupancyMap | None
          ) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 2) and radii (N,) (m) of ``agents.spawn`` (see the module docstring)."""
    spec = checks.mapping(value, field, allowed={"region", "count", "radius", "seed"},
                          required={"region", "count", "radius"})
    count = checks.integer(spec["count"], f"{field}.count", low=1,
                           fix=f"set {field}.count to the number of agents, e.g. 100")
    seed = checks.integer(spec.get("seed", 0), f"{field}.seed", low=0,
                          fix=f"set {field}.seed to an integer >= 0")
    lo_r, hi_r = _radius(spec["radius"], f"{field}.radius")
    inside, lo, hi = _region(spec["region"], f"{field}.region")
    rng = np.random.default_rng(seed)
    kept_q = np.empty((0, 2))
    kept_r = np.empty(0)
    idle = 0
    while len(kept_q) < count and idle < PATIENCE:
        m = max(64, BATCH * (count - len(kept_q)))
        q = lo + rng.random((m, 2)) * (hi - lo)
        r = lo_r + rng.random(m) * (hi_r - lo_r) if hi_r > lo_r else np.full(m, lo_r)
        ok = inside(q)
        if grid is not None:
            ok &= ~grid.is_blocked(q)
        q, r = q[ok], r[ok]
        if not geometry.is_empty and len(q):
            clear = np.ones(len(q), dtype=bool)
            for a, _, _, _, _ in single_rows(geometry, 0.0, q, r, 0.0):
                clear[a] = False  # some wall or obstacle value <= 0
            q, r = q[clear], r[clear]
        added = 0
        if len(q):
            free = np.ones(len(q), dtype=bool)
            if len(kept_q):
                # clear of the disks kept before: no kept centre within r + r_max
                tree = cKDTree(kept_q)
                near = tree.query_ball_point(q, r + kept_r.max())
                for u, js in enumerate(near):
                    if js and np.any(np.hypot(*(kept_q[js] - q[u]).T) < r[u] + kept_r[js]):
                        free[u] = False
            q, r = q[free], r[free]
            keep = _greedy(q, r)
            room = count - len(kept_q)
            keep = keep[:room]
            kept_q = np.concatenate([kept_q, q[keep]])
            kept_r = np.concatenate([kept_r, r[keep]])
            added = len(keep)
        idle = 0 if added else idle + 1
    if len(kept_q) < count:
        raise SceneError(f"{field}.count", f"only {len(kept_q)} of {count} agents of radius "
                         f"{show([lo_r, hi_r]) if hi_r > lo_r else f'{lo_r:g} m'} fit in the "
                         "region's free space (random sequential addition)",
                         f"lower {field}.count or the radius, or enlarge {field}.region")
    return kept_q, kept_r


def _greedy(q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Indices of the candidates kept in order: each kept unless it overlaps an earlier kept
    one."""
    if len(q) < 2:
        return np.arange(len(q))
    tree = cKDTree(q)
    pairs = tree.query_pairs(2.0 * float(r.max()), output_type="ndarray")
    d = np.hypot(*(q[pairs[:, 0]] - q[pairs[:, 1]]).T)
    pairs = pairs[d < r[pairs[:, 0]] + r[pairs[:, 1]]]
    clash: list[list[int]] = [[] for _ in range(len(q))]
    for i, j in pairs:  # i < j: the earlier candidate of each clash
        clash[int(j)].append(int(i))
    kept = np.zeros(len(q), dtype=bool)
    for u in range(len(q)):
        kept[u] = not any(kept[v] for v in clash[u])
    return np.flatnonzero(kept)


def _radius(value: Any, field: str) -> tuple[float, float]:
    if isinstance(value, list):
        if len(value) != 2:
            raise SceneError(field, f"has {len(value)} numbers",
                             "give one radius R or a range [R_min, R_max] (m)")
        lo = checks.number(value[0], f"{field}[0]", positive=True)
        hi = checks.number(value[1], f"{field}[1]", positive=True)
        if hi < lo:
            raise SceneError(field, f"range {show([lo, hi])} is reversed",
                             f"write [{hi:g}, {lo:g}]")
        return lo, hi
    r = checks.number(value, field, positive=True)
    return r, r


def _region(value: Any, field: str) -> tuple[Any, np.ndarray, np.ndarray]:
    """A membership test (M, 2) -> (M,) bool and the bounding box of the region."""
    region = checks.mapping(value, field)
    kind = checks.kind(region, field, ("rectangle", "polygon"))
    if kind == "rectangle":
        checks.mapping(region, field, allowed={"kind", "min", "max"}, required={"min", "max"})
        lo = checks.vec2(region["min"], f"{field}.min")
        hi = checks.vec2(region["max"], f"{field}.max")
        if np.any(hi <= lo):
            raise SceneError(field, f"min {show(lo)} is not below max {show(hi)}",
                             "give the lower-left corner as min and the upper-right as max")
        return (lambda q: np.all((q >= lo) & (q <= hi), axis=1)), lo, hi
    checks.mapping(region, field, allowed={"kind", "points"}, required={"points"})
    points = chain_points(region["points"], f"{field}.points", True, 3)
    return (lambda q: points_in_polygon(q, points)), points.min(axis=0), points.max(axis=0)
