"""What a scene costs to build, bounded before it is built: the counts of its wall and obstacle
items, their segments and its groups (:func:`check_item_counts`), and the grid nodes of
every geodesic or exits drift (the scene's drift, its groups' drifts), every journey leg and
every exit of an exit choice, each at least the scene's extent (agents, walls, obstacles, the
map) divided by its cell, summed and held to :data:`~sweep_core.model.travel.MAX_SCENE_NODES`
(:func:`check_navigation_cost`). The estimate is a lower bound of what the build lays out
(the grids also cover the targets and a margin), so it refuses no scene the build would take;
the build counts the true grids as it goes (:func:`~sweep_core.model.travel.node_budget`)."""
from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np

from sweep_core.errors import CostError
from sweep_core.model.geometry import Geometry
from sweep_core.model.maps import OccupancyMap
from sweep_core.model.travel import CELL, MAX_SCENE_NODES

#: the drift kinds solved on a grid
NAVIGATION_KINDS = ("geodesic", "exits")
#: items of a scene's walls and obstacles together (each is validated on its own)
MAX_PIECES = 16_384
#: straight segments of a scene's walls and obstacles together (a polyline or polygon of M
#: points counts M; a map's own walls are bounded by its MAX_MAP_WALLS)
MAX_SEGMENTS = 250_000
#: groups of a scene (``agents.groups`` or a ``groups`` drift; each builds its own drift)
MAX_GROUPS = 4_096


def check_item_counts(data: dict) -> None:
    """Refuse, before any is validated or built, a scene with more wall and obstacle items
    than MAX_PIECES, more segments in them than MAX_SEGMENTS, or more groups than MAX_GROUPS
    (CostError naming the list). Lists of another type are left to their validators."""
    pieces = segments = 0
    for key in ("walls", "obstacles"):
        items = data.get(key)
        if not isinstance(items, list):
            continue
        pieces += len(items)
        if pieces > MAX_PIECES:
            raise CostError(key, f"brings the walls and obstacles to {pieces} items, more "
                            f"than {MAX_PIECES}", "join straight runs into polylines, or "
                            "give a large layout as a map (map: an occupancy grid)")
        for item in items:
            points = item.get("points") if isinstance(item, dict) else None
            segments += len(points) if isinstance(points, list) else 1
        if segments > MAX_SEGMENTS:
            raise CostError(key, f"brings the segments of the walls and obstacles to "
                            f"{segments}, more than {MAX_SEGMENTS}", "give the outlines with "
                            "fewer points, or a large layout as a map (an occupancy grid)")
    agents, drift = data.get("agents"), data.get("drift")
    for field, groups in (("agents.groups", agents.get("groups") if isinstance(agents, dict)
                           else None),
                          ("drift.groups", drift.get("groups") if isinstance(drift, dict)
                           else None)):
        if isinstance(groups, list) and len(groups) > MAX_GROUPS:
            raise CostError(field, f"lists {len(groups)} groups, more than {MAX_GROUPS}",
                            "give agents that share a drift and a speed one group")


def _cell(value: Any) -> float | None:
    """A cell (m) as given, or None when it is no positive finite number (its validator
    refuses it later)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    cell = float(value)
    return cell if math.isfinite(cell) and cell > 0 else None


def _drifts(value: Any, field: str) -> Iterator[tuple[str, float | None, int]]:
    """(field, cell, grids) of every navigation drift in a drift spec and those nested in it
    (a groups drift), walked without recursion."""
    stack = [(value, field)]
    while stack:
        item, where = stack.pop()
        if isinstance(item, dict):
            if item.get("kind") in NAVIGATION_KINDS:
                yield where, _cell(item.get("cell", CELL)), 1
            stack.extend((v, f"{where}.{k}") for k, v in item.items() if isinstance(v, (dict, list)))
        elif isinstance(item, list):
            stack.extend((v, f"{where}[{k}]") for k, v in enumerate(item))


def _fields(data: dict) -> Iterator[tuple[str, float | None, int]]:
    """(field, cell, grids) of every navigation field the scene ``data`` asks for."""
    yield from _drifts(data.get("drift"), "drift")
    agents = data.get("agents")
    if isinstance(agents, dict):
        yield from _drifts(agents.get("groups"), "agents.groups")
    flows = data.get("flows")
    if not isinstance(flows, dict):
        return
    for key, parts in (("journeys", "legs"), ("exit_choice", "exits")):
        items = flows.get(key)
        for k, item in enumerate(items if isinstance(items, list) else []):
            if isinstance(item, dict) and isinstance(item.get(parts), list):
                yield f"flows.{key}[{k}]", _cell(item.get("cell", CELL)), len(item[parts])


def extent(geometry: Geometry, grid: OccupancyMap | None, positions: np.ndarray
           ) -> tuple[float, float]:
    """Width and height (m) of the box around the agents, walls, obstacles and map: every
    navigation grid covers at least this box."""
    pts = [positions.reshape(-1, 2), geometry.segment_a, geometry.segment_b]
    r = geometry.circle_radius[:, None]
    pts += [geometry.circle_center - r, geometry.circle_center + r]
    if grid is not None:
        h, w = grid.shape
        pts.append(grid.to_world(np.array([[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]])
                                 * grid.resolution))
    allp = np.concatenate([p for p in pts if len(p)]) if any(len(p) for p in pts) else None
    if allp is None:
        return 0.0, 0.0
    span = allp.max(axis=0) - allp.min(axis=0)
    return float(span[0]), float(span[1])


def check_navigation_cost(data: dict, geometry: Geometry, grid: OccupancyMap | None,
                          positions: np.ndarray) -> None:
    """Refuse, before any grid is built, a scene whose navigation fields together would lay
    out more than MAX_SCENE_NODES grid nodes (SceneError naming the field that passes it)."""
    w, h = extent(geometry, grid, positions)
    total = 0
    for field, cell, grids in _fields(data):
        if cell is None:
            continue
        nodes = (math.floor(w / cell) + 1) * (math.floor(h / cell) + 1)
        total += grids * nodes
        if total > MAX_SCENE_NODES:
            raise CostError(f"{field}.cell", f"{cell:g} m gives grids of at least {nodes} "
                             f"nodes over the scene's {w:g} x {h:g} m; with the other "
                             f"navigation fields that is at least {total} nodes, more than "
                             f"{MAX_SCENE_NODES}", f"set {field}.cell coarser, or use fewer "
                             "navigation fields (journey legs, exits, geodesic drifts)")
