"""What a scene's sources can never do, refused when the scene is built: a source whose region
has no point where its largest disk is clear of the walls and obstacles, outside blocked map
cells (that agent, and every one due after it, would wait for ever), a source whose region
lies inside a sink (every agent it emits would leave at once), and a source none of whose
points has a way round the walls to the first target its agents head for (every agent it
emits would walk into the walls between them and stay there).
:mod:`sweep_core.model.flows` calls :func:`check_sources` and :func:`check_source_ways`.

The room test is a proof, never a guess: the clearance c(q) (m) of a centre q, its distance to
the nearest wall or obstacle (negative inside a polygon obstacle), is 1-Lipschitz in q. On a
grid of step h over the region's bounding box every point p lies within delta = h / sqrt(2) of
a node g, so c(g) >= c(p) - delta and dist(g, region) <= delta. If no node within delta of the
region has c(g) >= r - delta, no point of the region has c(p) >= r: the source has no room.
A region too large for a grid of :data:`ROOM_NODES` nodes per axis to give delta < r, a
scene whose walls or obstacles move, and user constraints are not tested. Entries keep their
order, so one agent that can never enter stops its source for good: the test takes the
source's largest radius.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from sweep_core.errors import SceneError, show
from sweep_core.model.geometry import SEGMENT, single_rows
from sweep_core.model.outlines import points_in_polygon
from sweep_core.model.regions import Region
from sweep_core.model.travel import node_index, reach_grid

#: grid nodes per axis of the room test: at most 128 x 128 = 16384 candidate centres, tested
#: against the walls through the spatial index (a few milliseconds); a region up to about
#: 128 r / sqrt(2) across (36 m for r = 0.2 m) is tested
ROOM_NODES = 128
#: the grid step the room test aims at, r / FINE (m), where the cap of ROOM_NODES allows:
#: delta = r / (FINE / sqrt(2)) = r / 8, so a region whose best clearance is short of r by
#: more than an eighth of r is refused
FINE = 8 * math.sqrt(2.0)
#: slack (m) given to the clearance against rounding: the test refuses only when every node
#: is short of r - delta by more than this
ROOM_SLACK = 1e-9


def has_room(region: Region, r: float, geometry: Any, grid: Any = None) -> bool | None:
    """Whether some centre in ``region`` has clearance >= r (m) from the static walls and
    obstacles of ``geometry``, in a free cell of the map ``grid`` (an
    :class:`~sweep_core.model.maps.OccupancyMap` or None): True (a node shows it), False
    (proven: none has), or None (untested: moving geometry, user constraints, or a region
    too large; module docstring). A node within delta < r of such a centre lies in its disk,
    clear of the map's walls, so in a free cell too: blocked nodes are left out."""
    if geometry.is_empty and grid is None:
        return True
    if geometry.is_moving or len(geometry.user) or np.any(geometry.halfplane_velocity != 0):
        return None
    extent = float(np.max(region.hi - region.lo))
    per_axis = min(ROOM_NODES, max(2, math.ceil(extent / (r / FINE)) + 1))
    h = extent / (per_axis - 1)
    delta = h / math.sqrt(2.0)
    if delta >= r:
        return None
    xs = region.lo[0] + h * np.arange(per_axis)
    ys = region.lo[1] + h * np.arange(per_axis)
    nodes = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    nodes = nodes[region.distance(nodes) <= delta + ROOM_SLACK]
    if not len(nodes):
        return None
    ok = np.ones(len(nodes), dtype=bool) if grid is None else ~grid.is_blocked(nodes)
    rr = np.full(len(nodes), r - delta - ROOM_SLACK)
    for a, _, _, _, _ in single_rows(geometry, 0.0, nodes, rr, 0.0):
        ok[a] = False
    return bool(ok.any())


def inside(region: Region, sink: Region) -> bool:
    """Whether ``region`` lies inside ``sink`` (m), decided for a rectangular or convex sink
    (every vertex of the region inside it); False for a concave sink (not decided)."""
    pts = sink.points
    if not sink.is_rectangle:
        e = np.roll(pts, -1, axis=0) - pts
        turn = e[:, 0] * np.roll(e, -1, axis=0)[:, 1] - e[:, 1] * np.roll(e, -1, axis=0)[:, 0]
        if not (np.all(turn >= 0) or np.all(turn <= 0)):
            return False
        return bool(np.all(points_in_polygon(region.points, pts)))
    return bool(np.all(sink.contains(region.points)))


def check_sources(sources: Sequence[Any], sinks: Sequence[Region], geometry: Any,
                  grid: Any = None) -> None:
    """Refuse a source (``flows.sources[k]``) with no room for its largest disk (clear of the
    walls and obstacles, in a free cell of the map ``grid``), or inside a sink (module
    docstring)."""
    for k, src in enumerate(sources):
        field = f"flows.sources[{k}]"
        for m, sink in enumerate(sinks):
            if inside(src.region, sink):
                raise SceneError(f"{field}.region", f"lies inside flows.sinks[{m}]: every agent "
                                 "the source emits would leave at its first step",
                                 f"move {field}.region out of flows.sinks[{m}]")
        wall = crossing_wall(src.region, geometry)
        if wall is not None:
            what = geometry.describe(SEGMENT, wall)
            raise SceneError(f"{field}.region", f"is crossed by {what}: part of it lies on "
                             "the wall's far side (outside the room), where the source would "
                             "place agents that stay there",
                             f"keep {field}.region on one side of {geometry.path(SEGMENT, wall)}"
                             ", inside the room")
        if has_room(src.region, src.r_high, geometry, grid) is False:
            big = "radius" if src.r_high == src.r_low else "largest radius"
            maps = "" if grid is None else ", outside blocked map cells"
            raise SceneError(f"{field}.region", f"has no point {show(src.r_high)} m (the "
                             f"source's {big}) clear of the walls and obstacles{maps}: an agent "
                             "of that radius could never enter there, nor any after it",
                             f"move {field}.region into the free space, make it larger, or "
                             f"make {field}.radius smaller")


def _closed_outlines(geometry: Any) -> np.ndarray:
    """(S,) bool: the segment is a piece of a closed polyline wall (a room's outline)."""
    kind = np.array(geometry.segment_kind or ("segment",) * len(geometry.segment_a))
    wall = geometry.segment_index
    out = np.zeros(len(kind), dtype=bool)
    for w in np.unique(wall[kind == "polyline"]):
        mine = np.flatnonzero((wall == w) & (kind == "polyline"))
        first = mine[np.argmin(geometry.segment_part[mine])]
        last = mine[np.argmax(geometry.segment_part[mine])]
        out[mine] = bool(np.all(geometry.segment_a[first] == geometry.segment_b[last]))
    return out


def crossing_wall(region: Region, geometry: Any) -> int | None:
    """The first static piece of a closed polyline wall (a room's outline) that passes
    through the inside of ``region`` (touching its outline is not crossing), or None: such a
    region lies partly inside the room and partly outside it. The pieces of each segment
    between its meetings with the region's outline are tested at their midpoints: a piece
    inside the region farther than 1e-9 m from its outline crosses it. (A lone segment or an
    open polyline across a region divides the room; :func:`check_source_ways` judges that.)"""
    a, b = geometry.segment_a, geometry.segment_b
    if not len(a):
        return None
    near = np.flatnonzero((np.minimum(a, b) < region.hi).all(axis=1)
                          & (np.maximum(a, b) > region.lo).all(axis=1)
                          & (geometry.segment_polygon < 0) & (geometry.segment_motion < 0)
                          & _closed_outlines(geometry))
    p, q = region.points, np.roll(region.points, -1, axis=0)
    for s in near:
        d = b[s] - a[s]
        e = q - p
        den = d[0] * e[:, 1] - d[1] * e[:, 0]
        w = p - a[s]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (w[:, 0] * e[:, 1] - w[:, 1] * e[:, 0]) / den
            u = (w[:, 0] * d[1] - w[:, 1] * d[0]) / den
        cut = t[(den != 0) & (u >= 0) & (u <= 1) & (t > 0) & (t < 1)]
        ts = np.unique(np.concatenate([[0.0, 1.0], cut]))
        mid = a[s] + 0.5 * (ts[:-1] + ts[1:])[:, None] * d
        inner = region.contains(mid)
        if np.any(inner):
            # inside and off the outline: the distance to the outline's edges
            ab = e
            rel = mid[inner][:, None, :] - p[None]
            f = np.clip(np.einsum("mkc,kc->mk", rel, ab) / np.einsum("kc,kc->k", ab, ab), 0, 1)
            gap = np.hypot(*(rel - f[..., None] * ab[None]).transpose(2, 0, 1)).min(axis=1)
            if np.any(gap > 1e-9):
                return int(s)
    return None


#: grid nodes tested for lying inside a source's region at a time: the test stops at the first
#: node inside whose nearest free node has a way, usually in the first batch
WAY_BATCH = 4096


def has_way(region: Region, x: np.ndarray, y: np.ndarray, good: np.ndarray) -> bool:
    """Whether some point of ``region`` has a way to a navigation field's target: its corners,
    the centre of its bounding box when inside, or a grid node (x (W,), y (H,) m) inside it,
    whose nearest grid node is marked in ``good`` (H, W) bool (:func:`.travel.reach_grid`:
    its nearest free node has a way), as an agent there is led."""
    centre = 0.5 * (region.lo + region.hi)[None]
    points = np.concatenate([region.points, centre[region.contains(centre)]])
    if good[node_index(points, x, y)].any():
        return True
    x0, x1 = np.searchsorted(x, region.lo[0]), np.searchsorted(x, region.hi[0], side="right")
    y0, y1 = np.searchsorted(y, region.lo[1]), np.searchsorted(y, region.hi[1], side="right")
    gy, gx = np.nonzero(good[y0:y1, x0:x1])
    for s in range(0, len(gy), WAY_BATCH):
        nodes = np.stack([x[x0 + gx[s:s + WAY_BATCH]], y[y0 + gy[s:s + WAY_BATCH]]], axis=1)
        if region.contains(nodes).any():
            return True
    return False


def check_source_ways(sources: Sequence[Any], ways: dict[int, tuple[str, list]]) -> None:
    """Refuse a source (``flows.sources[k]``) whose agents' group g has navigation fields
    ``ways[g]`` = (what they lead to, [fields]) none of which has a way from the source's
    region (:func:`has_way`). Sources of groups without a navigation field (a straight goal,
    no drift) and fields recomputed as obstacles move are not tested. One distance transform
    per field, however many sources use it."""
    grids: dict[int, np.ndarray] = {}

    def good(f: Any) -> np.ndarray:
        if id(f) not in grids:
            grids[id(f)] = reach_grid(f.free, f.travel)
        return grids[id(f)]

    for k, src in enumerate(sources):
        what, fields = ways.get(src.group, ("", []))
        fields = [f for f in fields if f.update_every is None]
        if fields and not any(has_way(src.region, f.x, f.y, good(f)) for f in fields):
            raise SceneError(f"flows.sources[{k}].region", f"has no point with a way round "
                             f"the walls to {what}: every agent the source emits would walk "
                             "into a wall and stay there",
                             f"move flows.sources[{k}].region to where {what} can be reached, "
                             "open a passage, or move the target")
