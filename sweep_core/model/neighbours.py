"""Neighbour search: the pairs of centres within a distance, by a compiled cell list.

The plane is cut into square cells of side ``reach``; two centres at most ``reach`` apart lie in
the same cell or in adjacent ones, so each occupied cell is compared with itself and four of its
eight neighbours (the other four see it from their side). Cells are found by sorting the
agents by cell key (no grid is allocated, so a crowd spread over kilometres costs what a dense one
does): O(N log N + pairs). The order of the pairs is a function of the positions alone
(deterministic), which keeps seeded runs bit for bit reproducible.

Compiled with numba (``cache=True``: compiled once per machine, the cache in ``__pycache__`` beside
this file or, where the package folder is read-only, in numba's user-wide cache directory;
``NUMBA_CACHE_DIR`` sets another).
"""
from __future__ import annotations

import numba
import numpy as np

#: the four neighbour cells each cell is compared with (the other four compare with it)
_HALF_STENCIL = np.array([[1, -1], [1, 0], [1, 1], [0, 1]], dtype=np.int64)


@numba.njit(cache=True, nogil=True)
def _compare(q: np.ndarray, r2: float, order: np.ndarray, a0: int, a1: int, b0: int, b1: int,
             same: bool, out_i: np.ndarray, out_j: np.ndarray, found: int) -> int:
    """Pairs within sqrt(r2) between the agents order[a0:a1] and order[b0:b1] (the same run
    when ``same``), written while the output has room; returns the new count."""
    cap = out_i.shape[0]
    for u in range(a0, a1):
        i = order[u]
        xi, yi = q[i, 0], q[i, 1]
        for v in range(u + 1 if same else b0, b1):
            j = order[v]
            dx = xi - q[j, 0]
            dy = yi - q[j, 1]
            if dx * dx + dy * dy <= r2:
                if found < cap:
                    out_i[found] = min(i, j)
                    out_j[found] = max(i, j)
                found += 1
    return found


@numba.njit(cache=True, nogil=True)
def _pairs_grid(q: np.ndarray, reach: float, x0: float, y0: float, nx: int, ny: int,
                out_i: np.ndarray, out_j: np.ndarray) -> int:
    """Dense grid of nx x ny cells of side reach (counting sort, O(N + cells + pairs))."""
    n = q.shape[0]
    cells = nx * ny
    cell = np.empty(n, dtype=np.int64)
    start = np.zeros(cells + 1, dtype=np.int64)
    for a in range(n):
        c = int((q[a, 0] - x0) / reach) * ny + int((q[a, 1] - y0) / reach)
        cell[a] = c
        start[c + 1] += 1
    for c in range(cells):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(n, dtype=np.int64)
    for a in range(n):
        order[fill[cell[a]]] = a
        fill[cell[a]] += 1
    r2 = reach * reach
    found = 0
    for cx in range(nx):
        for cy in range(ny):
            c = cx * ny + cy
            a0, a1 = start[c], start[c + 1]
            if a0 == a1:
                continue
            found = _compare(q, r2, order, a0, a1, a0, a1, True, out_i, out_j, found)
            for s in range(4):
                dx, dy = _HALF_STENCIL[s, 0], _HALF_STENCIL[s, 1]
                ox, oy = cx + dx, cy + dy
                if ox < 0 or ox >= nx or oy < 0 or oy >= ny:
                    continue
                o = ox * ny + oy
                found = _compare(q, r2, order, a0, a1, start[o], start[o + 1], False,
                                 out_i, out_j, found)
    return found


@numba.njit(cache=True, nogil=True)
def _sorted_cells(q: np.ndarray, reach: float, x0: float, y0: float, ny: int
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The agents sorted by cell key (cells of side reach, key (column + 1) ny + row + 1):
    their order, the sorted keys, the first position of each occupied cell in that order
    (cells + 1 entries, the last n) and the count of occupied cells."""
    n = q.shape[0]
    key = np.empty(n, dtype=np.int64)
    for a in range(n):
        key[a] = (int((q[a, 0] - x0) / reach) + 1) * ny + int((q[a, 1] - y0) / reach) + 1
    order = np.argsort(key, kind="mergesort")
    sk = key[order]
    starts = np.empty(n + 1, dtype=np.int64)
    cells = 0
    for k in range(n):
        if k == 0 or sk[k] != sk[k - 1]:
            starts[cells] = k
            cells += 1
    starts[cells] = n
    return order, sk, starts, cells


@numba.njit(cache=True, nogil=True)
def _first_cell(sk: np.ndarray, starts: np.ndarray, cells: int, want: int) -> int:
    """The first of the ``cells`` runs of cell-sorted agents (run c starts at ``starts[c]``)
    whose cell key ``sk`` is >= want (binary search; ``cells`` when there is none)."""
    lo, hi = 0, cells
    while lo < hi:
        mid = (lo + hi) // 2
        if sk[starts[mid]] < want:
            lo = mid + 1
        else:
            hi = mid
    return lo


@numba.njit(cache=True, nogil=True)
def _pairs_sorted(q: np.ndarray, reach: float, x0: float, y0: float, ny: int,
                  out_i: np.ndarray, out_j: np.ndarray) -> int:
    """Sparse crowds: agents sorted by cell key, neighbour cells found by binary search
    (O(N log N + pairs), no grid allocated)."""
    order, sk, starts, cells = _sorted_cells(q, reach, x0, y0, ny)
    r2 = reach * reach
    found = 0
    for c in range(cells):
        a0, a1 = starts[c], starts[c + 1]
        found = _compare(q, r2, order, a0, a1, a0, a1, True, out_i, out_j, found)
        for s in range(4):
            want = sk[a0] + _HALF_STENCIL[s, 0] * ny + _HALF_STENCIL[s, 1]
            lo = _first_cell(sk, starts, cells, want)
            if lo < cells and sk[starts[lo]] == want:
                found = _compare(q, r2, order, a0, a1, starts[lo], starts[lo + 1], False,
                                 out_i, out_j, found)
    return found


#: a dense grid is used while it has at most this many cells per agent (plus a constant)
_GRID_CELLS_PER_AGENT = 4


def pairs_within(q: np.ndarray, reach: float, expect: int = 0
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Index arrays (i, j), i < j, of the pairs of centres q (N, 2) at most ``reach`` m apart
    (``reach`` > 0), in an order that depends on the positions alone. ``expect``: about how
    many pairs the caller expects (its last count, say): room for max(4 N, expect) pairs is
    made first, and the search runs again only when more are found (the pairs are the same
    either way)."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    n = len(q)
    if n < 2:
        return _NONE, _NONE
    # the output made here and filled by the compiled search (an array made inside a
    # compiled function costs more to hand back than the search itself on a small crowd)
    capacity = max(4 * n, int(expect))
    while True:
        i = np.empty(capacity, dtype=np.intp)
        j = np.empty(capacity, dtype=np.intp)
        found = pairs_into(q, float(reach), i, j)
        if found <= capacity:
            return i[:found], j[:found]
        capacity = found


_NONE = np.empty(0, dtype=np.intp)


class SizedSearch:
    """:func:`pairs_within` for one call site whose searches find many more pairs than 4 per
    agent (a speed law's reach): each search makes room first for the last one's count and a
    quarter more, so that it rarely runs twice. The count is a hint only (the pairs found do
    not depend on it); one instance may serve any number of simulations and threads."""

    def __init__(self) -> None:
        self.expect = 0

    def __call__(self, q: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
        i, j = pairs_within(q, reach, self.expect)
        self.expect = len(i) + len(i) // 4
        return i, j


@numba.njit(cache=True, nogil=True)
def pairs_into(q: np.ndarray, reach: float, out_i: np.ndarray, out_j: np.ndarray
               ) -> int:  # pragma: no cover - compiled
    """:func:`pairs_within`'s search for N >= 2 (for compiled callers): the grid's extent,
    then the dense grid or the sorted cells writing the pairs while out_i, out_j have room;
    the count of pairs found (more than their length: search again with more room)."""
    n = q.shape[0]
    x0, y0, x1, y1 = q[0, 0], q[0, 1], q[0, 0], q[0, 1]
    for a in range(1, n):
        x0, x1 = min(x0, q[a, 0]), max(x1, q[a, 0])
        y0, y1 = min(y0, q[a, 1]), max(y1, q[a, 1])
    nx = int((x1 - x0) / reach) + 1
    ny = int((y1 - y0) / reach) + 1
    if nx * ny <= _GRID_CELLS_PER_AGENT * n + 64:
        return _pairs_grid(q, reach, x0, y0, nx, ny, out_i, out_j)
    return _pairs_sorted(q, reach, x0, y0, ny + 2, out_i, out_j)


@numba.njit(cache=True, nogil=True)
def _segments_sorted(q: np.ndarray, a: np.ndarray, b: np.ndarray, reach: float, x0: float,
                     y0: float, ny: int, out_a: np.ndarray, out_s: np.ndarray) -> int:
    """Agents sorted by cell key (cells of side reach); each segment visits the cells its
    bounding box, grown by reach, covers, and keeps the agents within reach of it."""
    order, sk, starts, cells = _sorted_cells(q, reach, x0, y0, ny)
    r2 = reach * reach
    cap = out_a.shape[0]
    found = 0
    for s in range(a.shape[0]):
        ax, ay, bx, by = a[s, 0], a[s, 1], b[s, 0], b[s, 1]
        ex, ey = bx - ax, by - ay
        ee = ex * ex + ey * ey
        lo_x = int((min(ax, bx) - reach - x0) / reach + 1.0) if min(ax, bx) - reach > x0 else 0
        lo_y = int((min(ay, by) - reach - y0) / reach + 1.0) if min(ay, by) - reach > y0 else 0
        hi_x = int((max(ax, bx) + reach - x0) / reach) + 1
        hi_y = int((max(ay, by) + reach - y0) / reach) + 1
        hi_y = min(hi_y, ny - 1)
        for cx in range(lo_x, hi_x + 1):
            base = cx * ny
            # the cells of this column in range lie in one run of sorted keys
            c = _first_cell(sk, starts, cells, base + lo_y)
            while c < cells and sk[starts[c]] <= base + hi_y:
                for v in range(starts[c], starts[c + 1]):
                    u = order[v]
                    px, py = q[u, 0] - ax, q[u, 1] - ay
                    t = (px * ex + py * ey) / ee
                    t = 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)
                    dx, dy = px - t * ex, py - t * ey
                    if dx * dx + dy * dy <= r2:
                        if found < cap:
                            out_a[found] = u
                            out_s[found] = s
                        found += 1
                c += 1
    return found


def segments_within(q: np.ndarray, a: np.ndarray, b: np.ndarray, reach: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Index arrays (agent, segment) of the centres q (N, 2) at most ``reach`` m (> 0) from
    the segments [a_s, b_s] (S, 2), in an order that depends on the inputs alone. Agents are
    hashed into cells of side ``reach``; a segment costs the cells of its bounding box grown
    by ``reach`` (few for the axis-aligned walls of a map, more for long diagonal ones)."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    a = np.ascontiguousarray(a, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)
    if len(q) == 0 or len(a) == 0:
        empty = np.empty(0, dtype=np.intp)
        return empty, empty
    reach = float(reach)
    x0, y0 = float(q[:, 0].min()), float(q[:, 1].min())
    ny = int((float(q[:, 1].max()) - y0) / reach) + 3
    capacity = 4 * len(q) + len(a)
    while True:
        out_a = np.empty(capacity, dtype=np.intp)
        out_s = np.empty(capacity, dtype=np.intp)
        found = _segments_sorted(q, a, b, reach, x0, y0, ny, out_a, out_s)
        if found <= capacity:
            return out_a[:found], out_s[:found]
        capacity = found
