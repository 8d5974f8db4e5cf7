"""Where an entering agent is clear of the disks present: a cell grid over one source's region,
so that placing M agents in one step costs O(M) distance checks instead of O(M^2).

A candidate centre c with radius rc is clear of a disk (x_j, r_j) when |c - x_j|^2 >= (rc +
r_j)^2, computed as dx * dx + dy * dy against (rc + r_j) * (rc + r_j), the same comparison in
the same floating-point operations as a dense check over every disk. Only disks within rc +
max r_j of the region can fail it, and with cells at least that wide they lie in the 3 x 3
cells round the candidate's own.
"""
from __future__ import annotations

import math

import numba
import numpy as np

#: most cells of one grid: a region too large for cells of the reach is covered by wider ones
MAX_CELLS = 1 << 20


@numba.njit(cache=True, nogil=True)
def clear_of(cand: np.ndarray, rc: float, xs: np.ndarray, rs: np.ndarray, head: np.ndarray,
             nxt: np.ndarray, x0: float, y0: float, h: float, nx: int, ny: int
             ) -> np.ndarray:
    """Whether each candidate centre (M, 2) m of radius rc m is clear of the disks (xs (K, 2) m,
    rs (K,) m) filed in the cell lists head (nx * ny,) / nxt (K,) of cells h m wide from (x0,
    y0) (-1 ends a list): (M,) bool."""
    m = cand.shape[0]
    ok = np.ones(m, dtype=np.bool_)
    for a in range(m):
        cx = min(max(int(math.floor((cand[a, 0] - x0) / h)), 0), nx - 1)
        cy = min(max(int(math.floor((cand[a, 1] - y0) / h)), 0), ny - 1)
        for ix in range(max(cx - 1, 0), min(cx + 2, nx)):
            for iy in range(max(cy - 1, 0), min(cy + 2, ny)):
                j = head[ix * ny + iy]
                while j >= 0 and ok[a]:
                    dx = cand[a, 0] - xs[j, 0]
                    dy = cand[a, 1] - xs[j, 1]
                    s = rc + rs[j]
                    if dx * dx + dy * dy < s * s:
                        ok[a] = False
                    j = nxt[j]
    return ok


class EntryGrid:
    """The disks a source's entering agents must be clear of, filed by cell: those present
    within ``reach`` of the box [lo, hi] (m) where the candidates are drawn, and those placed
    since (:meth:`add`). ``reach`` (m) is at least the largest entering radius plus the largest
    radius of a disk filed."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray, reach: float, xs: np.ndarray,
                 rs: np.ndarray) -> None:
        self.x0, self.y0 = float(lo[0]) - reach, float(lo[1]) - reach
        w, d = float(hi[0] - lo[0]) + 2 * reach, float(hi[1] - lo[1]) + 2 * reach
        h = max(reach, math.sqrt(w * d / MAX_CELLS), 1e-9)
        self.h, self.nx, self.ny = h, max(1, math.ceil(w / h)), max(1, math.ceil(d / h))
        near = np.flatnonzero((xs[:, 0] >= self.x0) & (xs[:, 0] <= self.x0 + w)
                              & (xs[:, 1] >= self.y0) & (xs[:, 1] <= self.y0 + d))
        k = len(near)
        self.xs = np.empty((max(2 * k, 16), 2))
        self.rs = np.empty(len(self.xs))
        self.nxt = np.full(len(self.xs), -1, dtype=np.int64)
        self.head = np.full(self.nx * self.ny, -1, dtype=np.int64)
        self.xs[:k] = xs[near]
        self.rs[:k] = rs[near]
        self.count = k
        # the cell lists of the disks present, at once: each disk points to the next one of
        # its cell in sorted order, the first of each cell is its head
        cells = self._cells(self.xs[:k])
        order = np.argsort(cells, kind="stable")
        sorted_cells = cells[order]
        same = sorted_cells[1:] == sorted_cells[:-1]
        self.nxt[order[:-1][same]] = order[1:][same]
        first = np.concatenate([[True], ~same]) if k else np.zeros(0, dtype=bool)
        self.head[sorted_cells[first]] = order[first]

    def _cells(self, p: np.ndarray) -> np.ndarray:
        """The cell (K,) of each point (K, 2) m, edges clamped into the grid."""
        cx = np.clip(np.floor((p[:, 0] - self.x0) / self.h), 0, self.nx - 1).astype(np.int64)
        cy = np.clip(np.floor((p[:, 1] - self.y0) / self.h), 0, self.ny - 1).astype(np.int64)
        return cx * self.ny + cy

    def add(self, p: np.ndarray, r: float) -> None:
        """Files a disk of centre p (2,) m and radius r m."""
        if self.count == len(self.xs):
            grow = 2 * len(self.xs)
            self.xs = np.resize(self.xs, (grow, 2))
            self.rs = np.resize(self.rs, grow)
            self.nxt = np.resize(self.nxt, grow)
        k = self.count
        self.xs[k] = p
        self.rs[k] = r
        c = int(self._cells(np.asarray(p, dtype=np.float64)[None])[0])
        self.nxt[k] = self.head[c]
        self.head[c] = k
        self.count += 1

    def clear(self, cand: np.ndarray, rc: float) -> np.ndarray:
        """(M,) bool: whether each candidate (M, 2) m of radius rc m is clear of every disk
        filed, for candidates inside the box [lo, hi] the grid was built for (disks beyond
        ``reach`` of it were not filed) and rc + any filed radius at most ``reach``."""
        return clear_of(np.ascontiguousarray(cand, dtype=np.float64), float(rc), self.xs,
                        self.rs, self.head, self.nxt, self.x0, self.y0, self.h, self.nx,
                        self.ny)
