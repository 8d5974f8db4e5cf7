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

The field classes and their specs are here; the targets (goal points, regions, exits) are
:mod:`sweep_core.model.targets`, the grid solve they share (free nodes, the graph, Dijkstra
from the goal's seeds, the descent direction, the agents' reachability)
:mod:`sweep_core.model.travel`.

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

from sweep_core import checks
from sweep_core.errors import SceneError, show
from sweep_core.model.bilinear import bilinear
from sweep_core.model.fields import Field, Groups, grid_cell
from sweep_core.model.geometry import Geometry
from sweep_core.model.maps import OccupancyMap
from sweep_core.model.targets import Target, navigation_targets, target_from_spec
from sweep_core.model.travel import (
    CELL,
    DIRECTION_ERROR,
    MAX_NODES,
    METRICATION,
    NEIGHBOURS,
    SLOW_RADIUS,
    STENCILS,
    WALL_BUFFER,
    buffer_cells,
    check_agents,
    check_target,
    grid_nodes,
    solve_grid,
)

__all__ = ["CELL", "DIRECTION_ERROR", "MAX_NODES", "METRICATION", "NEIGHBOURS", "SLOW_RADIUS",
           "STENCILS", "WALL_BUFFER", "Exits", "Geodesic", "Target", "buffer_cells",
           "navigation_fields", "navigation_from_spec", "navigation_targets"]


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
            sol = solve_grid(geometry.at(epoch * self.update_every), grid, targets,
                         [""] * len(targets), self.x, self.y, cell, buffer, neighbours,
                         strict=False)
            self.cache.update(epoch=epoch, arrays=(sol[0], sol[1]))
        return self.cache["arrays"]

    def _at(self, v: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Node values v (H, W) or (H, W, 2) bilinear at q (N, 2), clamped to the grid
        (compiled, :func:`~sweep_core.model.bilinear.bilinear`; numpy for a grid of one node
        along an axis)."""
        if self.x.size < 2 or self.y.size < 2:
            fx, ix = grid_cell(self.x, q[:, 0])
            fy, iy = grid_cell(self.y, q[:, 1])
            w = [((1 - fy) * (1 - fx)), ((1 - fy) * fx), (fy * (1 - fx)), (fy * fx)]
            if v.ndim == 3:
                w = [c[:, None] for c in w]
            return (w[0] * v[iy, ix] + w[1] * v[iy, ix + 1] + w[2] * v[iy + 1, ix]
                    + w[3] * v[iy + 1, ix + 1])
        nodes = v if v.ndim == 3 else v[:, :, None]
        out = np.empty((len(q), nodes.shape[2]))
        bilinear(self._nodes(self.x), self._nodes(self.y), self._nodes(nodes),
                 np.ascontiguousarray(q, dtype=np.float64), out)
        return out if v.ndim == 3 else out[:, 0]

    @staticmethod
    def _nodes(a: np.ndarray) -> np.ndarray:
        return a if a.flags.c_contiguous and a.dtype == np.float64 else \
            np.ascontiguousarray(a, dtype=np.float64)

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
        targets = [target_from_spec(checks.mapping(e, f"{field}.exits[{k}]"), f"{field}.exits[{k}]",
                           True) for k, e in enumerate(raw)]
        names = [f"{field}.exits[{k}]" for k in range(len(targets))]
    else:
        checks.mapping(spec, field, allowed={"kind", "goal", "region"} | common,
                       required={"speed"})
        targets = [target_from_spec(spec, field, False)]
        names = [field]
    speed = checks.speed(spec["speed"], f"{field}.speed")
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
    x, y = grid_nodes(geometry, grid, positions, targets, cell, buffer, field)
    for t, name in zip(targets, names):
        check_target(geometry, grid, t, name)
    direction, own, travel, free, choice = solve_grid(geometry, grid, targets, names, x, y, cell,
                                                  buffer, neighbours)
    check_agents(positions, x, y, free, travel, field, buffer)
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
