"""Bilinear interpolation of node values on a rectilinear grid, compiled (numba): the
navigation fields' T and e at the agents (:meth:`sweep_core.model.geodesic.Geodesic._at`).

:func:`bilinear` does what :func:`sweep_core.model.fields.grid_cell` and the four-corner sum
do in numpy, with the same floating-point operations in the same order (no fused
multiply-add: numba compiles without fastmath), so the values' bits are those of the numpy
form on every CPU. Compiled with ``cache=True`` (see :mod:`sweep_core.model.neighbours`).
"""
from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def _cell(nodes: np.ndarray, s: float) -> tuple[float, int]:
    """The fraction and the cell index of coordinate s on sorted nodes (>= 2), clamped."""
    last = nodes.shape[0] - 1
    s = min(max(s, nodes[0]), nodes[last])
    i = np.searchsorted(nodes, s, side="right") - 1
    i = min(max(i, 0), last - 1)
    return (s - nodes[i]) / (nodes[i + 1] - nodes[i]), i


@numba.njit(cache=True, nogil=True)
def bilinear(x: np.ndarray, y: np.ndarray, v: np.ndarray, q: np.ndarray, out: np.ndarray
             ) -> None:
    """out (N, C) = the node values v (H, W, C) on nodes x (W,), y (H,) (each >= 2, sorted)
    bilinear at q (N, 2), q clamped to the grid."""
    for a in range(q.shape[0]):
        fx, ix = _cell(x, q[a, 0])
        fy, iy = _cell(y, q[a, 1])
        w0, w1 = (1 - fy) * (1 - fx), (1 - fy) * fx
        w2, w3 = fy * (1 - fx), fy * fx
        for c in range(v.shape[2]):
            out[a, c] = (w0 * v[iy, ix, c] + w1 * v[iy, ix + 1, c] + w2 * v[iy + 1, ix, c]
                         + w3 * v[iy + 1, ix + 1, c])
