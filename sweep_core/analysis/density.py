"""The density map of ``sweep analyze``: counts of agent centres per square cell on a grid that
grows with the run, bounded by :data:`MAX_CELLS` (:class:`Hist2D`)."""
from __future__ import annotations

import math

import numpy as np

from sweep_core.errors import SweepError

#: most cells of the density map (``--cell``): 4e6 cells are 32 MB of counts, a 2000 x 2000 grid
MAX_CELLS = 4_000_000


def _cells(lo: float, hi: float, cell: float) -> int:
    """Cells of side ``cell`` spanned along one axis by points in [lo, hi] (m)."""
    return math.floor(hi / cell) - math.floor(lo / cell) + 1


class Hist2D:
    """Counts of points per square cell, on a grid that grows as needed up to MAX_CELLS.

    A grid that would grow beyond MAX_CELLS stops counting but keeps the extent of the points;
    :meth:`check` then refuses it, naming the smallest cell that fits the whole run.
    """

    def __init__(self, cell: float) -> None:
        self.cell = cell
        self.counts = np.zeros((0, 0), dtype=np.int64)
        self.ix0 = self.iy0 = 0
        self.lo = np.array([math.inf, math.inf])
        self.hi = -self.lo
        self.too_fine = False

    def add(self, q: np.ndarray) -> None:
        if not len(q):
            return
        self.lo = np.minimum(self.lo, q.min(axis=0))
        self.hi = np.maximum(self.hi, q.max(axis=0))
        if self.too_fine:
            return
        ix = np.floor(q[:, 0] / self.cell).astype(np.int64)
        iy = np.floor(q[:, 1] / self.cell).astype(np.int64)
        h, w = self.counts.shape
        if self.counts.size == 0:
            self.ix0, self.iy0 = int(ix.min()), int(iy.min())
        lo_x, lo_y = min(self.ix0, int(ix.min())), min(self.iy0, int(iy.min()))
        hi_x, hi_y = max(self.ix0 + w, int(ix.max()) + 1), max(self.iy0 + h, int(iy.max()) + 1)
        if (lo_x, lo_y, hi_x - lo_x, hi_y - lo_y) != (self.ix0, self.iy0, w, h):
            if (hi_x - lo_x) * (hi_y - lo_y) > MAX_CELLS:
                self.too_fine = True
                self.counts = np.zeros((0, 0), dtype=np.int64)
                return
            grown = np.zeros((hi_y - lo_y, hi_x - lo_x), dtype=np.int64)
            grown[self.iy0 - lo_y:self.iy0 - lo_y + h, self.ix0 - lo_x:self.ix0 - lo_x + w] = \
                self.counts
            self.counts, self.ix0, self.iy0 = grown, lo_x, lo_y
        np.add.at(self.counts, (iy - self.iy0, ix - self.ix0), 1)

    def _fits(self, cell: float) -> bool:
        (x0, y0), (x1, y1) = self.lo, self.hi
        return _cells(x0, x1, cell) * _cells(y0, y1, cell) <= MAX_CELLS

    def check(self) -> None:
        """Raises SweepError if the grid needed more than MAX_CELLS cells (see the class)."""
        if not self.too_fine:
            return
        (x0, y0), (x1, y1) = self.lo, self.hi
        nx, ny = _cells(x0, x1, self.cell), _cells(y0, y1, self.cell)
        c = max(math.sqrt((x1 - x0) * (y1 - y0) / MAX_CELLS), self.cell)
        while not self._fits(c):
            c *= 1.01
        # shown with 2 significant digits, rounded up to a cell that fits
        shown = float(f"{c:.2g}")
        while shown < c or not self._fits(shown):
            shown = float(f"{shown + 10.0 ** (math.floor(math.log10(shown)) - 1):.2g}")
        raise SweepError(f"--cell: {self.cell:g} m makes a density grid of {nx} x {ny} = "
                         f"{nx * ny:.3g} cells over the {x1 - x0:.3g} x {y1 - y0:.3g} m the "
                         f"agents cover, more than the limit {MAX_CELLS:g} "
                         f"(fix: --cell {shown:g} or larger)")
