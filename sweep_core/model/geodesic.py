"""Navigation fields: drift along the shortest way round walls, obstacles and map cells.

    drift: {kind: geodesic, goal: [x, y] | region: {kind: rectangle, min, max}
                                                   | {kind: polygon, points},
            speed, cell: 0.1, wall_buffer: 0.3, slow_radius: 0.5, update_every: null,
            neighbours: 16}
    drift: {kind: exits, exits: [{goal | region, weight: 1}, ...], speed, cell, wall_buffer,
            slow_radius, update_every, neighbours}

The travel distance T(q) (m) to the goal is computed once, when the scene is built, on a grid
of ``cell`` m covering the scene (walls, obstacles, map, agents and goals, plus a margin), by
Dijkstra's algorithm (:func:`scipy.sparse.csgraph.dijkstra`) on a grid graph over the *free*
nodes: those at least ``wall_buffer`` m from every wall, obstacle and blocked map cell (the
true constraint values of :mod:`sweep_core.model.geometry` with radius 0, at t = 0). The
graph's steps (``neighbours``): 16, the default, are (1, 0), (1, 1), (2, 1) cells and their
rotations and reflections; 8 drops (2, 1); 32 adds (3, 1) and (3, 2). Requiring wall_buffer
>= half the longest step (sqrt(5) / 2 cell with 16 neighbours, sqrt(13) / 2 with 32) makes
sure no edge between two free nodes crosses a wall, however thin (one end of such an edge
would be within half its length of the wall). The goal's seeds are the free nodes within
wall_buffer + 2 cell of the goal (or of the region, or inside it) that see it in a straight
line; they start at their exact distance to it.

Moving obstacles count where they are at t = 0. With ``update_every: s`` (only when some
obstacle moves) T is computed again for each period [k s, (k + 1) s) with the obstacles where
they are at k s, the first time a step falls in it (so a run and its replay see the same
fields; about 15 ms for a 20 x 10 m room at 0.1 m); a goal then covered by an obstacle gives
U = 0 until it is free again. A moving half-plane counts where it is at t = 0, always.

Longer than 400 lines because it is one model: the field classes, the validation of their
specs and the grid solve they share (free nodes, the graph, Dijkstra from the goal's seeds,
the descent direction, the agents' reachability); the solve's helpers are private to it.

Metrication error: a path on the 16-neighbour graph is made of steps in 16 directions, so in
open space T is the Euclidean distance times a factor between 1 and 1.0275 (the worst case,
+2.75 %, is 13.3 degrees off a stencil direction; 8 neighbours: +8.2 %, 32: +1.3 %:
:data:`METRICATION`), plus up to about one cell where paths bend round corners. The direction
of steepest descent of such a T is that of the faces of the stencil's polygon, so it is off
the true geodesic direction by up to about 13 degrees in open space with 16 neighbours (21
with 8, 9 with 32: :data:`DIRECTION_ERROR`; progress towards the goal at cos 13 deg = 97 % of
the speed at worst); test/test_geodesic.py measures both. 32 neighbours cost about a third
more time than 16.

U(q) = speed * min(1, T(q) / slow_radius) * e(q), where e is minus the gradient of T (central
differences between free nodes, one-sided beside a wall) normalised at each node, and both e
and T are bilinear between nodes; at nodes that are not free (within wall_buffer of a wall)
e and T are those of the nearest free node that T reaches. So |U| <= speed, and U is
Lipschitz on the grid scale: each component of e is bilinear in a cell with corner values in
[-1, 1], so |grad e| <= 4 / cell, and |grad U| <= speed (4 / cell + |grad T| / slow_radius)
with |grad T| about 1 (T grows at most one metre per metre along a grid step), except across a
wall thinner than a cell within slow_radius of the goal, where the nodes on its two sides
carry different T. U slows down inside slow_radius of the goal as the ``goal`` drift does (it
stops inside a goal region). A grid cell straddling a thin wall mixes the directions of both
sides, so agents' radii should exceed sqrt(2) cell (a centre that far from a wall has its
cell's four nodes on its own side); with the default cell of 0.1 m, any radius above 0.15 m.

With ``exits``, T_k is computed for each exit and every node follows the exit with the
smallest weighted distance w_k T_k (a weight above 1 makes an exit look farther: a smaller
door); the slowing uses that exit's own T_k.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from sweep_core import checks
from sweep_core.errors import SceneError, show
from sweep_core.model.fields import Field, Groups, grid_cell
from sweep_core.model.geometry import Geometry, single_rows
from sweep_core.model.maps import OccupancyMap
from sweep_core.model.outlines import chain_points, points_in_polygon

#: most grid nodes a navigation field may have (building one takes about 1.2 s and 0.5 GB at
#: this size)
MAX_NODES = 1_000_000
#: the steps of the grid graph for each choice of ``neighbours``, in cells (with their
#: opposites)
STENCILS = {
    8: ((1, 0), (0, 1), (1, 1), (1, -1)),
    16: ((1, 0), (0, 1), (1, 1), (1, -1), (2, 1), (1, 2), (2, -1), (1, -2)),
    32: ((1, 0), (0, 1), (1, 1), (1, -1), (2, 1), (1, 2), (2, -1), (1, -2),
         (3, 1), (1, 3), (3, -1), (1, -3), (3, 2), (2, 3), (3, -2), (2, -3)),
}
#: worst relative excess of a stencil path over the straight distance
METRICATION = {8: 0.0824, 16: 0.0275, 32: 0.0131}
#: worst angle (degrees) between the descent direction and the true one, in open space
#: (measured: test/test_geodesic.py)
DIRECTION_ERROR = {8: 21.0, 16: 13.0, 32: 9.0}
#: defaults (m, m, m, neighbours)
CELL, WALL_BUFFER, SLOW_RADIUS, NEIGHBOURS = 0.1, 0.3, 0.5, 16


def buffer_cells(neighbours: int) -> float:
    """wall_buffer must be at least this many cells: half the stencil's longest step."""
    return max(math.hypot(*step) for step in STENCILS[neighbours]) / 2.0


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


@dataclass(frozen=True, eq=False)
class Geodesic(Field):
    """The navigation field (see the module docstring). x (W,), y (H,): node coordinates (m);
    direction (H, W, 2): the unit descent direction at each node; distance (H, W): the
    followed exit's T (m) at each node, free or filled; travel (H, W): min_k w_k T_k (m), inf
    at nodes that are not free or not reached; free (H, W) bool."""

    x: np.ndarray
    y: np.ndarray
    direction: np.ndarray
    distance: np.ndarray
    travel: np.ndarray
    free: np.ndarray
    speed: float
    slow_radius: float
    spec: dict = field(default_factory=dict)
    #: recompute every this many seconds (moving obstacles), None: at t = 0 only
    update_every: float | None = None
    #: what a recomputation needs: (geometry, map, targets, cell, wall_buffer, neighbours)
    source: tuple = ()
    #: the latest recomputation: {"epoch": k, "arrays": (direction, distance)}
    cache: dict = field(default_factory=dict, repr=False)
    #: (H, W) int: the target (exit) each node follows at t = 0, as listed in the spec
    choice: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), dtype=np.intp))
    kind = "geodesic"

    def __call__(self, t: float, q: np.ndarray) -> np.ndarray:
        direction, distance = self.arrays(t)
        slow = np.minimum(1.0, self._at(distance, q) / self.slow_radius)
        return self._at(direction, q) * (self.speed * slow)[:, None]

    def travel_distance(self, q: np.ndarray, t: float = 0.0) -> np.ndarray:
        """(N,) m: the followed exit's travel distance T at q (N, 2) at time t (s), bilinear
        between nodes (travel time = T / speed)."""
        return self._at(self.arrays(t)[1], q)

    def target_of(self, q: np.ndarray) -> np.ndarray:
        """(N,) int: the target (exit, in the spec's order) that positions q (N, 2) head for
        at t = 0: that of the nearest grid node (0 for a single goal)."""
        if self.choice.size == 0:
            return np.zeros(len(q), dtype=np.intp)
        cell = float(self.x[1] - self.x[0])
        ix = np.clip(np.rint((q[:, 0] - self.x[0]) / cell).astype(np.intp), 0, len(self.x) - 1)
        iy = np.clip(np.rint((q[:, 1] - self.y[0]) / cell).astype(np.intp), 0, len(self.y) - 1)
        return self.choice[iy, ix]

    def arrays(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The direction (H, W, 2) and distance (H, W) in effect at t (s): those of t = 0, or
        with update_every those computed at the start of the period holding t (the obstacles
        where they are then), recomputed the first time that period is asked for."""
        if self.update_every is None:
            return self.direction, self.distance
        epoch = int(math.floor(t / self.update_every + 1e-9))
        if epoch <= 0:
            return self.direction, self.distance
        if self.cache.get("epoch") != epoch:
            geometry, grid, targets, cell, buffer, neighbours = self.source
            sol = _solve(geometry.at(epoch * self.update_every), grid, targets,
                         [""] * len(targets), self.x, self.y, cell, buffer, neighbours,
                         strict=False)
            self.cache.update(epoch=epoch, arrays=(sol[0], sol[1]))
        return self.cache["arrays"]

    def _at(self, v: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Node values v (H, W) or (H, W, 2) bilinear at q (N, 2), clamped to the grid."""
        fx, ix = grid_cell(self.x, q[:, 0])
        fy, iy = grid_cell(self.y, q[:, 1])
        w = [((1 - fy) * (1 - fx)), ((1 - fy) * fx), (fy * (1 - fx)), (fy * fx)]
        if v.ndim == 3:
            w = [c[:, None] for c in w]
        return (w[0] * v[iy, ix] + w[1] * v[iy, ix + 1] + w[2] * v[iy + 1, ix]
                + w[3] * v[iy + 1, ix + 1])

    @property
    def max_speed(self) -> float:
        return self.speed

    def to_spec(self) -> dict:
        return {"kind": self.kind, **{k: v for k, v in self.spec.items() if k != "kind"}}


class Exits(Geodesic):
    """Several exits: each agent heads for the one with the least weighted travel distance."""

    kind = "exits"


def navigation_fields(drift: Field) -> list[tuple[int, Geodesic]]:
    """The navigation fields (geodesic, exits) of a drift: [(group, field)], group -1 for the
    whole drift or a groups drift's rest, k for its group k; empty when it has none."""
    if isinstance(drift, Geodesic):
        return [(-1, drift)]
    if isinstance(drift, Groups):
        out = [(k, f) for k, f in enumerate(drift.fields) if isinstance(f, Geodesic)]
        return out + ([(-1, drift.rest)] if isinstance(drift.rest, Geodesic) else [])
    return []


def navigation_targets(spec: dict, field: str = "drift") -> list[tuple[str, Target]]:
    """The goals of a ``geodesic`` or ``exits`` drift spec, named for reports: [("goal" or
    "region", target)] or [("exits[k]", target), ...] (for arrivals per exit: see
    :meth:`Target.arrived`)."""
    if spec.get("kind") == "exits":
        raw = spec.get("exits")
        if not isinstance(raw, list):
            raise SceneError(f"{field}.exits", f"must be a list, got {show(raw)}",
                             f"write {field}.exits as a list of {{goal: [x, y]}} items")
        return [(f"exits[{k}]", _target(checks.mapping(e, f"{field}.exits[{k}]"),
                                        f"{field}.exits[{k}]", True))
                for k, e in enumerate(raw)]
    target = _target(spec, field, False)
    return [("region" if target.is_region else "goal", target)]


def _target(spec: dict, field: str, weighted: bool) -> Target:
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


def navigation_from_spec(spec: dict, field: str, geometry: Geometry | None,
                         grid: OccupancyMap | None, positions: np.ndarray) -> Geodesic:
    """Validate and build a ``geodesic`` or ``exits`` drift (module docstring) for a scene's
    geometry, map and agents' positions (N, 2) m."""
    kind = spec.get("kind")
    if geometry is None:
        raise SceneError(f"{field}.kind", f"{kind} needs the scene's walls to be computed",
                         f"give the {kind} drift in the scene's drift, not as a command")
    common = {"speed", "cell", "wall_buffer", "slow_radius", "update_every", "neighbours"}
    if kind == "exits":
        checks.mapping(spec, field, allowed={"kind", "exits"} | common,
                       required={"exits", "speed"})
        raw = spec["exits"]
        if not isinstance(raw, list) or not raw:
            raise SceneError(f"{field}.exits", f"must be a non-empty list, got {show(raw)}",
                             f"write {field}.exits as a list of {{goal: [x, y]}} or "
                             "{region: ...} items, one per exit")
        targets = [_target(checks.mapping(e, f"{field}.exits[{k}]"), f"{field}.exits[{k}]",
                           True) for k, e in enumerate(raw)]
        names = [f"{field}.exits[{k}]" for k in range(len(targets))]
    else:
        checks.mapping(spec, field, allowed={"kind", "goal", "region"} | common,
                       required={"speed"})
        targets = [_target(spec, field, False)]
        names = [field]
    speed = checks.number(spec["speed"], f"{field}.speed", nonnegative=True)
    cell = checks.number(spec.get("cell", CELL), f"{field}.cell", positive=True)
    buffer = checks.number(spec.get("wall_buffer", WALL_BUFFER), f"{field}.wall_buffer",
                           positive=True)
    slow = checks.number(spec.get("slow_radius", SLOW_RADIUS), f"{field}.slow_radius",
                         positive=True)
    neighbours = spec.get("neighbours", NEIGHBOURS)
    if isinstance(neighbours, bool) or neighbours not in STENCILS:
        raise SceneError(f"{field}.neighbours", f"must be 8, 16 or 32, got {show(neighbours)}",
                         f"set {field}.neighbours to 16 (the default) or 32 (finer "
                         "directions, slower)")
    neighbours = int(neighbours)
    cells = buffer_cells(neighbours)
    if buffer < cells * cell:
        raise SceneError(f"{field}.cell", f"{cell:g} m is too coarse for {field}.wall_buffer "
                         f"{buffer:g} m: a grid step (up to {2 * cells:.4g} cells) could "
                         "cross a thin wall unseen",
                         f"set {field}.cell to at most {buffer / cells:.4g} m or "
                         f"{field}.wall_buffer to at least {cells * cell:.4g} m")
    every = None
    if spec.get("update_every") is not None:
        every = checks.number(spec["update_every"], f"{field}.update_every", positive=True)
        if not geometry.is_moving:
            raise SceneError(f"{field}.update_every", f"is {every:g} s but no obstacle moves",
                             f"remove {field}.update_every (the field is computed once)")
    moving = geometry
    geometry = geometry.at(0.0)
    x, y = _nodes(geometry, grid, positions, targets, cell, buffer, field)
    for t, name in zip(targets, names):
        _check_target(geometry, grid, t, name)
    direction, own, travel, free, choice = _solve(geometry, grid, targets, names, x, y, cell,
                                                  buffer, neighbours)
    _check_agents(positions, x, y, free, travel, field, buffer)
    out: dict[str, Any] = {"kind": kind}
    if kind == "exits":
        out["exits"] = [t.spec for t in targets]
    else:
        out.update(targets[0].spec)
    out.update(speed=speed, cell=cell, wall_buffer=buffer, slow_radius=slow,
               neighbours=neighbours)
    if every is not None:
        out["update_every"] = every
    cls = Exits if kind == "exits" else Geodesic
    return cls(x=x, y=y, direction=direction, distance=own, travel=travel, free=free,
               speed=speed, slow_radius=slow, spec=out, update_every=every,
               source=(moving, grid, targets, cell, buffer, neighbours) if every is not None
               else (), choice=choice)


def _solve(geometry: Geometry, grid: OccupancyMap | None, targets: list[Target],
           names: list[str], x: np.ndarray, y: np.ndarray, cell: float, buffer: float,
           neighbours: int = NEIGHBOURS, strict: bool = True
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Direction (H, W, 2), the followed exit's distance (H, W) (both filled at nodes not
    reached), travel min_k w_k T_k (H, W) (inf where not reached), free (H, W) and the
    followed exit's index (H, W) (filled too) for a static geometry. strict: refuse a target
    no free node sees (else that target is unreachable, and where no target is, the field is
    0)."""
    nodes = np.stack(np.meshgrid(x, y), axis=-1).reshape(-1, 2)
    free = _free(geometry, grid, nodes, buffer).reshape(len(y), len(x))
    graph, index = _graph(free, cell, STENCILS[neighbours])
    dists = [_travel(geometry, t, name, nodes, free, graph, index, cell, buffer, strict)
             for t, name in zip(targets, names)]
    weighted = np.stack([t.weight * d for t, d in zip(targets, dists)])
    which = np.argmin(weighted, axis=0)
    travel = np.take_along_axis(weighted, which[None], 0)[0]
    own = np.take_along_axis(np.stack(dists), which[None], 0)[0]
    direction = _descent(travel, cell)
    reached = np.isfinite(travel)
    if not np.any(reached):
        return direction, np.zeros_like(own), travel, free, which
    if np.any(~reached):  # nearest reached node's direction, distance and exit
        _, (iy, ix) = ndimage.distance_transform_edt(~reached, return_indices=True)
        direction = direction[iy, ix]
        own = own[iy, ix]
        which = which[iy, ix]
    return direction, own, travel, free, which


def _nodes(geometry: Geometry, grid: OccupancyMap | None, positions: np.ndarray,
           targets: list[Target], cell: float, buffer: float, field: str
           ) -> tuple[np.ndarray, np.ndarray]:
    """Node coordinates (m) covering the scene, with a margin of wall_buffer + 2 cells."""
    pts = [positions.reshape(-1, 2), geometry.segment_a, geometry.segment_b]
    pts += [t.points for t in targets]
    r = geometry.circle_radius[:, None]
    pts += [geometry.circle_center - r, geometry.circle_center + r]
    if grid is not None:
        h, w = grid.shape
        pts.append(grid.to_world(np.array([[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]])
                                 * grid.resolution))
    allp = np.concatenate(pts)
    margin = buffer + 2.0 * cell
    lo, hi = allp.min(axis=0) - margin, allp.max(axis=0) + margin
    size = np.ceil((hi - lo) / cell).astype(np.int64) + 1
    count = int(size[0]) * int(size[1])
    if count > MAX_NODES:
        need = cell * math.sqrt(count / MAX_NODES) * 1.01
        raise SceneError(f"{field}.cell", f"{cell:g} m makes a grid of {int(size[0])} x "
                         f"{int(size[1])} = {count} nodes over the scene's "
                         f"[{lo[0]:g}, {hi[0]:g}] x [{lo[1]:g}, {hi[1]:g}] m, more than "
                         f"{MAX_NODES}", f"set {field}.cell to at least {need:.3g} m")
    return lo[0] + cell * np.arange(size[0]), lo[1] + cell * np.arange(size[1])


def _free(geometry: Geometry, grid: OccupancyMap | None, q: np.ndarray, buffer: float,
          chunk: int = 16384) -> np.ndarray:
    """(M,) bool: the point is at least buffer m from every wall and obstacle and not in a
    blocked map cell (values at t = 0, radius 0)."""
    ok = np.ones(len(q), dtype=bool) if grid is None else ~grid.is_blocked(q)
    if geometry.is_empty:
        return ok
    for s in range(0, len(q), chunk):
        part = q[s:s + chunk]
        for a, _, g, _, _ in single_rows(geometry, 0.0, part, np.zeros(len(part)), buffer):
            ok[s + a[g < buffer]] = False
    return ok


def _check_target(geometry: Geometry, grid: OccupancyMap | None, target: Target,
                  name: str) -> None:
    """Refuse a goal point inside a wall, an obstacle or a blocked map cell."""
    if target.is_region:
        return
    g = target.points
    where = None
    if grid is not None and grid.is_blocked(g)[0]:
        where = "a blocked (occupied or unknown) cell of the map"
    elif not geometry.is_empty:
        for kind, (_, k, v, _, _) in enumerate(single_rows(geometry, 0.0, g, np.zeros(1), 0.0)):
            if len(v) and float(v.min()) < 1e-9:
                where = geometry.describe(kind, int(k[int(np.argmin(v))]))
                break
    if where is not None:
        raise SceneError(f"{name}.goal", f"{show(g[0])} lies in or on {where}",
                         f"move {name}.goal into the free space")


def _graph(free: np.ndarray, cell: float, stencil: tuple) -> tuple[Any, np.ndarray]:
    """The grid graph (steps ``stencil`` and their opposites) over free nodes (CSR, one extra
    node last for the sources) and the graph index of each grid node (-1: not free)."""
    h, w = free.shape
    index = np.full(free.shape, -1, dtype=np.int32)
    m = int(free.sum())
    index[free] = np.arange(m, dtype=np.int32)
    rows, cols, wts = [], [], []
    for dx, dy in stencil:
        ys0, ys1 = max(0, -dy), min(h, h - dy)
        xs0, xs1 = max(0, -dx), min(w, w - dx)
        a = index[ys0:ys1, xs0:xs1]
        b = index[ys0 + dy:ys1 + dy, xs0 + dx:xs1 + dx]
        both = (a >= 0) & (b >= 0)
        rows.append(a[both])
        cols.append(b[both])
        wts.append(np.full(int(both.sum()), cell * math.hypot(dx, dy)))
    r, c, v = np.concatenate(rows), np.concatenate(cols), np.concatenate(wts)
    # each edge once: the search treats the graph as undirected
    graph = coo_matrix((v, (r, c)), shape=(m + 1, m + 1)).tocsr()
    return graph, index


#: added to every source edge (csgraph reads an explicit 0 weight as no edge), then removed
_SOURCE_OFFSET = 1.0


def _travel(geometry: Geometry, target: Target, name: str, nodes: np.ndarray, free: np.ndarray,
            graph: Any, index: np.ndarray, cell: float, buffer: float, strict: bool = True
            ) -> np.ndarray:
    """T (H, W) m to the target: inf where not free or not reached."""
    flat = np.flatnonzero(free.ravel())
    near = buffer + 2.0 * cell
    d, p = target.nearest(nodes[flat])
    close = d <= near
    seeds, d, p = flat[close], d[close], p[close]
    seen = _visible(geometry, nodes[seeds], p)
    seeds, d = seeds[seen], d[seen]
    what = "region" if target.is_region else "goal"
    if len(seeds) == 0 and not strict:
        return np.full(free.shape, np.inf)
    if len(seeds) == 0:
        raise SceneError(f"{name}.{what}", f"{show(target.spec[what])} has no free grid node "
                         f"within {near:g} m in sight: it is closer than wall_buffer "
                         f"{buffer:g} m to walls all round",
                         f"move {name}.{what} into the open, or lower wall_buffer and cell")
    m = graph.shape[0] - 1
    src = coo_matrix((d + _SOURCE_OFFSET, (np.full(len(seeds), m, dtype=np.int32),
                                           index.ravel()[seeds])), shape=graph.shape).tocsr()
    dist = dijkstra(graph + src, directed=False, indices=m)
    out = np.full(free.size, np.inf)
    out[flat] = dist[:m] - _SOURCE_OFFSET
    return out.reshape(free.shape)


def _visible(geometry: Geometry, a: np.ndarray, b: np.ndarray, chunk: int = 256) -> np.ndarray:
    """(M,) bool: the segment a -> b (M, 2 each) crosses no wall segment, circle or
    half-plane (the end b may touch one)."""
    ok = np.ones(len(a), dtype=bool)
    for n, c0 in zip(geometry.halfplane_normal, geometry.halfplane_offset):
        ok &= b[:, 0] * n[0] + b[:, 1] * n[1] - c0 >= -1e-12  # not BLAS: CPU-independent
    if len(geometry.circle_radius):
        ab = b - a
        rel = geometry.circle_center[None] - a[:, None]
        s = np.clip(np.einsum("mkc,mc->mk", rel, ab)
                    / np.maximum(np.einsum("mc,mc->m", ab, ab), 1e-300)[:, None], 0, 1)
        d = np.hypot(*(a[:, None] + s[..., None] * ab[:, None] - geometry.circle_center[None]
                       ).transpose(2, 0, 1))
        ok &= np.all(d >= geometry.circle_radius[None] - 1e-12, axis=1)
    sa, sb = geometry.segment_a, geometry.segment_b
    if len(sa) == 0:
        return ok

    def orient(p: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
        return ((q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1])
                - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0]))

    for s in range(0, len(a), chunk):
        pa, pb = a[s:s + chunk], b[s:s + chunk]
        lo = np.minimum(pa, pb).min(axis=0)
        hi = np.maximum(pa, pb).max(axis=0)
        keep = np.all((np.maximum(sa, sb) >= lo) & (np.minimum(sa, sb) <= hi), axis=1)
        if not np.any(keep):
            continue
        wa, wb = sa[keep][None], sb[keep][None]
        p, q = pa[:, None], pb[:, None]
        o1, o2 = orient(p, q, wa), orient(p, q, wb)
        o3, o4 = orient(wa, wb, p), orient(wa, wb, q)
        cross = (o1 * o2 < 0) & (o3 * o4 < 0)
        ok[s:s + chunk] &= ~np.any(cross, axis=1)
    return ok


def _descent(travel: np.ndarray, cell: float) -> np.ndarray:
    """(H, W, 2): minus the gradient of T normalised (0 where T is flat or not reached):
    central differences where both neighbours are reached, one-sided beside a wall."""
    out = np.zeros(travel.shape + (2,))
    fin = np.isfinite(travel)
    t = np.where(fin, travel, 0.0)
    for axis in (1, 0):  # x along columns, y along rows
        fwd = np.zeros_like(t)
        bwd = np.zeros_like(t)
        has_f = np.zeros_like(fin)
        has_b = np.zeros_like(fin)
        sl = [slice(None)] * 2
        sl_next = [slice(None)] * 2
        sl[axis], sl_next[axis] = slice(0, -1), slice(1, None)
        ok = fin[tuple(sl)] & fin[tuple(sl_next)]
        diff = (t[tuple(sl_next)] - t[tuple(sl)]) / cell
        fwd[tuple(sl)] = np.where(ok, diff, 0.0)
        has_f[tuple(sl)] = ok
        bwd[tuple(sl_next)] = np.where(ok, diff, 0.0)
        has_b[tuple(sl_next)] = ok
        grad = np.where(has_f & has_b, 0.5 * (fwd + bwd), np.where(has_f, fwd, bwd))
        out[..., 1 - axis] = -grad
    size = np.hypot(out[..., 0], out[..., 1])
    out /= np.where(size > 1e-12, size, np.inf)[..., None]
    out[~fin] = 0.0
    return out


def _check_agents(positions: np.ndarray, x: np.ndarray, y: np.ndarray, free: np.ndarray,
                  travel: np.ndarray, field: str, buffer: float) -> None:
    """Refuse when an agent's nearest free node has no free path to the goal."""
    if len(positions) == 0:
        return
    if not np.any(free):
        raise SceneError(f"{field}.wall_buffer", f"{buffer:g} m leaves no free grid node: "
                         "everything is within it of a wall",
                         f"lower {field}.wall_buffer (and {field}.cell with it)")
    cell = float(x[1] - x[0])
    ix = np.clip(np.rint((positions[:, 0] - x[0]) / cell).astype(np.int64), 0, len(x) - 1)
    iy = np.clip(np.rint((positions[:, 1] - y[0]) / cell).astype(np.int64), 0, len(y) - 1)
    _, (ny, nx) = ndimage.distance_transform_edt(~free, return_indices=True)
    ny, nx = ny[iy, ix], nx[iy, ix]
    bad = np.flatnonzero(~np.isfinite(travel[ny, nx]))
    if len(bad):
        a = int(bad[0])
        more = f" ({len(bad)} agents in all)" if len(bad) > 1 else ""
        raise SceneError(field, f"agent {a} at {show(positions[a])} has no way to the goal "
                         f"that keeps wall_buffer {buffer:g} m from walls (from the free grid "
                         f"node [{x[nx[a]]:g}, {y[ny[a]]:g}]){more}",
                         f"open a passage at least 2 x {field}.wall_buffer wide, lower "
                         f"{field}.wall_buffer, or move the goal")
