"""A starting crowd for a scene's geometry: ``agents.spawn`` places non-overlapping disks in
the free space of a region (random sequential addition).

    agents:
      spawn: {region: {kind: rectangle, min: [x, y], max: [x, y]}
                      | {kind: polygon, points: [[x, y], ...]},
              count: N, radius: R | [R_min, R_max], seed: S}

Candidates are drawn uniformly in the region (radii uniformly in [R_min, R_max] when a range
is given), in batches; a candidate is kept when its centre is in the region, its disk lies
clear of every wall, obstacle and blocked map cell, and it does not overlap a disk kept
before (within a batch, the earlier candidate wins). A region that a closed polyline wall (a
room's outline, a pillar's) passes through is refused, as a source's is: agents would be
placed on both sides of it.

The count is compared with what the region can hold before anything is drawn. Random
sequential addition of equal disks jams when they cover about 0.547 of the plane (Feder 1980,
J. Theor. Biol. 87, 237; 0.547069 in Hinrichsen, Feder and Jossang 1986, J. Stat. Phys. 44,
793), and the disks, whose centres lie in the region, lie in the region grown by R: with n =
0.547 x area(region grown by R) / (pi R^2), a count above n + 3 sqrt(n) + 1 (the allowance
covers the spread of a finite region's jamming count) is refused at once. The grown area is
bounded from above (area + perimeter R + R^2 / 2 x the turn at convex corners: exact for a
rectangle or a convex polygon), and walls, obstacles and map cells are not subtracted, so the
bound only refuses counts that cannot fit. With a range of radii no jamming density is known
(mixtures pack denser): the count is refused above area(region grown by R_max) / (pi R_min^2),
the disks' area exceeding the area they lie in.

The work is bounded too: at most DRAWS x N candidates are drawn in all (in batches of at most
MAX_BATCH), and the draws stop earlier when PATIENCE batches in a row place nothing; the
scene is then refused with how many fitted. The positions and radii found are written into
the scene's spec, so a recording replays them without drawing again.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from sweep_core import checks
from sweep_core.errors import SceneError, show
from sweep_core.model import elementary
from sweep_core.model.flow_checks import crossing_wall
from sweep_core.model.geometry import SEGMENT, Geometry, single_rows
from sweep_core.model.maps import OccupancyMap
from sweep_core.model.outlines import chain_points, perimeter, points_in_polygon, signed_area
from sweep_core.model.regions import Region

#: jamming coverage of random sequential addition of equal disks (Hinrichsen, Feder and
#: Jossang 1986; Feder 1980 estimated 0.547)
JAMMING_COVERAGE = 0.547069
#: allowance above the jamming count n of a finite region, in units of sqrt(n) (plus 1): in
#: 100 seeded runs drawn to jamming in each of five small rectangles (0.4 x 0.4 m to 3 x 3 m,
#: radii 0.1-0.3 m, n = 6 to 33), the count placed spread with a standard deviation of about
#: 0.3 sqrt(n) and exceeded n by at most 1
FLUCTUATION = 3.0
#: candidates drawn per batch, per agent still to place (at least 64, at most MAX_BATCH)
BATCH = 4
#: most candidates drawn in one batch (memory: :func:`spawn_memory`, at most about 0.55 GB)
MAX_BATCH = 1 << 20
#: memory of a batch (bytes per candidate: positions, radii, masks and the k-d tree, and per
#: pair of candidates within 2 R of each other, found by the tree) and of the agents kept
#: (bytes each). Measured increase of the peak resident memory over a spawn of radius 0.2 m
#: in a square: 5e4 agents in 200 m, 1e5 in 300 m, 3e5 in 600 m, 1e6 in 1100 m, 262144 in
#: 262 m (near jamming): 44 / 83 / 208 / 156 / 426 MB (test/test_estimates.py checks it)
SPAWN_PER_CANDIDATE, SPAWN_PER_PAIR, SPAWN_PER_AGENT = 128, 48, 10
#: most candidates drawn in all, per agent asked for
DRAWS = 400
#: batches in a row that place nothing before the draws stop
PATIENCE = 50


def capacity(grown: float, lo_r: float, hi_r: float) -> int:
    """Most disks of radii in [lo_r, hi_r] (m) that can be spawned in a region whose area
    grown by hi_r is ``grown`` (m^2; see the module docstring)."""
    if hi_r > lo_r:
        return int(math.floor(grown / (math.pi * lo_r * lo_r)))
    jam = JAMMING_COVERAGE * grown / (math.pi * lo_r * lo_r)
    return int(math.floor(jam + FLUCTUATION * math.sqrt(jam) + 1.0))


def spawn_memory(count: int, area: float, hi_r: float) -> int:
    """The peak memory (bytes) of spawning ``count`` agents of radii at most ``hi_r`` (m) in a
    region of ``area`` (m^2): the first batch, the largest, of m candidates with m pi (2
    hi_r)^2 / area neighbours each on average, and the agents kept
    (:data:`SPAWN_PER_CANDIDATE` and the rest)."""
    m = min(max(64, BATCH * count), MAX_BATCH)
    pairs = m * math.pi * (2.0 * hi_r) ** 2 / area
    return int(m * (SPAWN_PER_CANDIDATE + SPAWN_PER_PAIR * pairs) + SPAWN_PER_AGENT * count)


def grown_area(points: np.ndarray, r: float) -> float:
    """An upper bound (m^2) on the area of the closed polygon ``points`` (M, 2) grown by r (m):
    area + perimeter r + r^2 / 2 x (sum of the turns at its convex corners); exact when the
    polygon is convex."""
    signed = signed_area(points)
    edge = np.roll(points, -1, axis=0) - points
    prev = np.roll(edge, 1, axis=0)
    turn = elementary.atan2_of(prev[:, 0] * edge[:, 1] - prev[:, 1] * edge[:, 0],
                      prev[:, 0] * edge[:, 0] + prev[:, 1] * edge[:, 1])
    convex = np.clip(np.sign(signed) * turn, 0.0, None)  # turns towards the inside
    return abs(signed) + perimeter(points) * r + 0.5 * r * r * float(np.sum(convex))


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
    inside, lo, hi, outline = _region(spec["region"], f"{field}.region")
    box = spec["region"]["kind"] == "rectangle"
    wall = crossing_wall(Region(outline, lo, hi, {}, box), geometry)
    if wall is not None:
        raise SceneError(f"{field}.region", f"is crossed by {geometry.describe(SEGMENT, wall)}: "
                         "part of it lies on the outline's other side, where agents would be "
                         "placed and stay",
                         f"keep {field}.region on one side of {geometry.path(SEGMENT, wall)}")
    most = capacity(grown_area(outline, hi_r), lo_r, hi_r)
    radius = show([lo_r, hi_r]) if hi_r > lo_r else f"{lo_r:g} m"
    if count > most:
        why = ("disks of a range of radii cannot cover more than the region grown by the "
               "largest radius" if hi_r > lo_r else
               f"random sequential addition of equal disks jams at {JAMMING_COVERAGE:.3f} of "
               "the area covered, Feder 1980, Hinrichsen, Feder and Jossang 1986; over the "
               f"region grown by {lo_r:g} m, with 3 sqrt(n) + 1 for a finite region's spread")
        raise SceneError(f"{field}.count", f"{count} agents of radius {radius} exceed the "
                         f"{most} that the region can hold ({why})",
                         f"set {field}.count to at most {most}, or use smaller radii or a "
                         "larger region")
    rng = np.random.default_rng(seed)
    kept_q = np.empty((0, 2))
    kept_r = np.empty(0)
    idle = 0
    budget = DRAWS * count
    while len(kept_q) < count and idle < PATIENCE and budget > 0:
        m = min(max(64, BATCH * (count - len(kept_q))), MAX_BATCH, budget)
        budget -= m
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
                # clear of the disks kept before: no kept disk overlapping
                near = cKDTree(q).sparse_distance_matrix(
                    cKDTree(kept_q), float(r.max() + kept_r.max()), output_type="ndarray")
                u, v, d = near["i"], near["j"], near["v"]
                free[u[d < r[u] + kept_r[v]]] = False
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
                         f"{radius} fit in the region's free space (random sequential "
                         f"addition, {DRAWS} draws per agent at most)",
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
        lo = checks.length(value[0], f"{field}[0]", positive=True)
        hi = checks.length(value[1], f"{field}[1]", positive=True)
        if hi < lo:
            raise SceneError(field, f"range {show([lo, hi])} is reversed",
                             f"write [{hi:g}, {lo:g}]")
        return lo, hi
    r = checks.length(value, field, positive=True)
    return r, r


def _region(value: Any, field: str) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray]:
    """A membership test (M, 2) -> (M,) bool, the bounding box of the region and its
    outline (K, 2)."""
    region = checks.mapping(value, field)
    kind = checks.kind(region, field, ("rectangle", "polygon"))
    if kind == "rectangle":
        checks.mapping(region, field, allowed={"kind", "min", "max"}, required={"min", "max"})
        lo = checks.point(region["min"], f"{field}.min")
        hi = checks.point(region["max"], f"{field}.max")
        if np.any(hi <= lo):
            raise SceneError(field, f"min {show(lo)} is not below max {show(hi)}",
                             "give the lower-left corner as min and the upper-right as max")
        box = np.array([lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]])
        return (lambda q: np.all((q >= lo) & (q <= hi), axis=1)), lo, hi, box
    checks.mapping(region, field, allowed={"kind", "points"}, required={"points"})
    points = chain_points(region["points"], f"{field}.points", True, 3)
    return ((lambda q: points_in_polygon(q, points)), points.min(axis=0), points.max(axis=0),
            points)
