"""The grid solve of a navigation field (:mod:`sweep_core.model.geodesic`): the nodes covering
the scene (:func:`grid_nodes`), the free ones (at least wall_buffer m from every wall, obstacle
and blocked map cell), the grid graph of a stencil, Dijkstra's travel distance T (m) from each
target's seeds, the minimum over weighted exits, the descent direction (:func:`solve_grid`),
and the checks of goals (:func:`check_target`) and agents (:func:`check_agents`) against it.
Shapes: x (W,), y (H,) node coordinates (m); arrays over the grid are (H, W) (row = y)."""
from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from sweep_core.errors import CostError, SceneError, show
from sweep_core.model.geometry import Geometry, single_rows
from sweep_core.model.maps import OccupancyMap
from sweep_core.model.targets import Target

#: most grid nodes a navigation field may have (building one takes about 1.2 s and 0.5 GB at
#: this size)
MAX_NODES = 1_000_000
#: most grid nodes of all the navigation fields one scene builds (its drift, its groups'
#: drifts, every journey leg, every exit of an exit choice): a field holds about 40 bytes a
#: node and its solve takes about 3 us a node (measured: 64 legs of 0.8 million nodes each
#: took 70 s and 2 GB before this bound)
MAX_SCENE_NODES = 4_000_000
#: the nodes charged so far while a scene is built (None: no scene is being built)
_CHARGED: ContextVar[list[int] | None] = ContextVar("scene_nodes", default=None)
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


def solve_grid(geometry: Geometry, grid: OccupancyMap | None, targets: list[Target],
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


def grid_nodes(geometry: Geometry, grid: OccupancyMap | None, positions: np.ndarray,
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
        raise CostError(f"{field}.cell", f"{cell:g} m makes a grid of {int(size[0])} x "
                         f"{int(size[1])} = {count} nodes over the scene's "
                         f"[{lo[0]:g}, {hi[0]:g}] x [{lo[1]:g}, {hi[1]:g}] m, more than "
                         f"{MAX_NODES}", f"set {field}.cell to at least {need:.3g} m")
    charge_nodes(count, field, cell)
    return lo[0] + cell * np.arange(size[0]), lo[1] + cell * np.arange(size[1])


@contextmanager
def node_budget() -> Iterator[None]:
    """Within it, every grid :func:`grid_nodes` lays out counts against the scene's
    :data:`MAX_SCENE_NODES` (a scene's build: :mod:`sweep_core.model.scene`)."""
    token = _CHARGED.set([0])
    try:
        yield
    finally:
        _CHARGED.reset(token)


def charge_nodes(count: int, field: str, cell: float) -> None:
    """Count ``count`` grid nodes of ``field`` (cell m) against the scene's budget, before
    they are allocated; raise SceneError naming ``field`` when the scene's fields together
    would pass :data:`MAX_SCENE_NODES` (outside :func:`node_budget`: nothing counted)."""
    charged = _CHARGED.get()
    if charged is None:
        return
    charged[0] += count
    if charged[0] > MAX_SCENE_NODES:
        raise CostError(f"{field}.cell", f"{cell:g} m brings the grid nodes of the scene's "
                         f"navigation fields to {charged[0]}, more than {MAX_SCENE_NODES} "
                         "(drift, groups, journey legs and exits together)",
                         f"set {field}.cell coarser, or use fewer navigation fields")


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


def check_target(geometry: Geometry, grid: OccupancyMap | None, target: Target,
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


def node_index(positions: np.ndarray, x: np.ndarray, y: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """The row and column indices (M,) of the grid node (x (W,), y (H,) m) nearest each
    position (M, 2) m, clipped to the grid."""
    cell = float(x[1] - x[0])
    ix = np.clip(np.rint((positions[:, 0] - x[0]) / cell).astype(np.int64), 0, len(x) - 1)
    iy = np.clip(np.rint((positions[:, 1] - y[0]) / cell).astype(np.int64), 0, len(y) - 1)
    return iy, ix


def nearest_free(positions: np.ndarray, x: np.ndarray, y: np.ndarray, free: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The row and column indices (M,) of the free node nearest each position (M, 2) m (some
    node must be free)."""
    iy, ix = node_index(positions, x, y)
    _, (ny, nx) = ndimage.distance_transform_edt(~free, return_indices=True)
    return ny[iy, ix], nx[iy, ix]


def reach_grid(free: np.ndarray, travel: np.ndarray) -> np.ndarray:
    """(H, W) bool: the free node nearest each node of the grid has a free path to the goal
    (False everywhere when no node is free); one distance transform for any number of
    positions (:func:`node_index` finds theirs)."""
    if not np.any(free):
        return np.zeros(free.shape, dtype=bool)
    _, (ny, nx) = ndimage.distance_transform_edt(~free, return_indices=True)
    return np.isfinite(travel[ny, nx])


def reaches(positions: np.ndarray, x: np.ndarray, y: np.ndarray, free: np.ndarray,
            travel: np.ndarray) -> np.ndarray:
    """(M,) bool: the free node nearest each position (M, 2) m has a free path to the goal
    (False everywhere when no node is free)."""
    if len(positions) == 0:
        return np.zeros(0, dtype=bool)
    iy, ix = node_index(positions, x, y)
    return reach_grid(free, travel)[iy, ix]


def check_agents(positions: np.ndarray, x: np.ndarray, y: np.ndarray, free: np.ndarray,
                  travel: np.ndarray, field: str, buffer: float) -> None:
    """Refuse when an agent's nearest free node has no free path to the goal."""
    if len(positions) == 0:
        return
    if not np.any(free):
        raise SceneError(f"{field}.wall_buffer", f"{buffer:g} m leaves no free grid node: "
                         "everything is within it of a wall",
                         f"lower {field}.wall_buffer (and {field}.cell with it)")
    ny, nx = nearest_free(positions, x, y, free)
    bad = np.flatnonzero(~np.isfinite(travel[ny, nx]))
    if len(bad):
        a = int(bad[0])
        more = f" ({len(bad)} agents in all)" if len(bad) > 1 else ""
        raise SceneError(field, f"agent {a} at {show(positions[a])} has no way to the goal "
                         f"that keeps wall_buffer {buffer:g} m from walls (from the free grid "
                         f"node [{x[nx[a]]:g}, {y[ny[a]]:g}]){more}",
                         f"open a passage at least 2 x {field}.wall_buffer wide, lower "
                         f"{field}.wall_buffer, or move the goal")
