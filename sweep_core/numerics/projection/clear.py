"""A prediction that needs no projection, decided without building the rows (one compiled
pass over a small scene).

:func:`~sweep_core.numerics.projection.project.project` builds the rows of the linearised set
C~(t1, q) whose value at q is at most the cutoff, and when the prediction p holds every one
(residual >= 0) its answer is p itself, with no QP and no multiplier. On a small scene that is
most steps (a robot among ten people at dt = 0.1 s: four in five), and building the rows costs
tens of microseconds of array handling for a yes. :func:`clear_active` answers the same
question directly: it visits every pair of agents and every (agent, wall or obstacle) of a
geometry with nothing moving, forms each row that :func:`~sweep_core.numerics.constraints.
linearise` builds with the same arithmetic (:func:`~sweep_core.model.wall_kernels.pair_rows`,
:func:`~sweep_core.model.wall_kernels.near_rows`) and returns the number of rows that hold
with equality at p (``Projection.active``), or -1 as soon as one row fails at p (or a value is
NaN): then the rows are built and the QP solved as before.

The pairs: ``linearise`` takes the candidates of a neighbour search within 2 max r + cut and
keeps those with value |q_i - q_j| - r_i - r_j <= cut; here every pair is tested against the
second condition alone. The two sets can differ only by a pair whose value at q rounds to the
cutoff itself (the first condition follows from the second up to rounding), and such a row
holds at p with room: a row moves by at most 2 max_i |p_i - q_i| <= 2 (cut - 1e-3 max r) / 3,
so its residual at p is at least cut / 3, above ``ROW_TOLERANCE`` whenever cut > 3e-9 m (the
caller asks for at least :data:`MIN_CUT`). A pair row's residual
<e, p_i - p_j> - (r_i + r_j) is the same number for (i, j) and (j, i) (the products change
sign together), so the pairs' order does not matter; neither does it for a count.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from sweep_core.model.geometry import DENSE_SEGMENTS, Geometry
from sweep_core.model.wall_kernels import disk_gap, halfplane_value, segment_foot, unit
from sweep_core.numerics.projection.options import ROW_TOLERANCE

#: agents at most: every pair is visited (N (N - 1) / 2), where the neighbour search visits
#: only near ones; beyond this the rows are built as usual
MAX_AGENTS = 64
#: the smallest cutoff (m) the pass answers for (module docstring: cut / 3 > ROW_TOLERANCE)
MIN_CUT = 1e-6


def clear_active(geom: Geometry, q: np.ndarray, pred: np.ndarray, r1: np.ndarray,
                 cut: float) -> int:
    """The number of rows of C~(t1, q) within ``cut`` (m) that hold with equality at pred
    (residual <= ``ROW_TOLERANCE``) when pred (N, 2) holds all of them, else -1 (some row
    fails, a value is NaN, or the scene is not one this pass answers for: more than
    :data:`MAX_AGENTS` agents, user constraints, polygons, moving obstacles, more
    (agent, segment) pairs than the dense pass takes, a cutoff below :data:`MIN_CUT`).
    geom: the geometry at t1; q (N, 2) at t_n; r1 (N,) m at t1."""
    n = len(q)
    if (n > MAX_AGENTS or not cut >= MIN_CUT or geom.user or geom.is_moving
            or geom.has_polygons or n * len(geom.segment_a) > DENSE_SEGMENTS):
        return -1
    hn, hc, sa, sb, cc, cr = geom.packed
    if not geom.fixed_halfplanes:
        return -1
    return clear_count(np.ascontiguousarray(q, dtype=np.float64),
                       np.ascontiguousarray(pred, dtype=np.float64),
                       np.ascontiguousarray(r1, dtype=np.float64), float(cut), hn, hc, sa,
                       sb, cc, cr)


@numba.njit(cache=True, nogil=True)
def clear_count(q: np.ndarray, p: np.ndarray, r: np.ndarray, cut: float, hn: np.ndarray,
                hc: np.ndarray, sa: np.ndarray, sb: np.ndarray, cc: np.ndarray,
                cr: np.ndarray) -> int:  # pragma: no cover - compiled
    """:func:`clear_active`'s pass: the rows' values at q and residuals at p in the
    arithmetic of ``pair_rows``, ``near_rows`` and ``row_residuals`` (x then y); -1 at the
    first row failing at p or NaN."""
    n = q.shape[0]
    active = 0
    for a in range(n):
        if not (math.isfinite(p[a, 0]) and math.isfinite(p[a, 1])):
            return -1
    for a in range(n):
        for b in range(a + 1, n):
            val, dist, dx, dy = disk_gap(q[a, 0], q[a, 1], q[b, 0], q[b, 1], r[a], r[b])
            if val <= cut:
                ex, ey = unit(dx, dy, dist)
                res = (ex * (p[a, 0] - p[b, 0]) + ey * (p[a, 1] - p[b, 1])) - (r[a] + r[b])
                if not res >= 0.0:
                    return -1
                if res <= ROW_TOLERANCE:
                    active += 1
    for a in range(n):
        x, y, ra = q[a, 0], q[a, 1], r[a]
        for k in range(hn.shape[0]):
            if halfplane_value(x, y, hn[k, 0], hn[k, 1], hc[k], ra) <= cut:
                res = (hn[k, 0] * p[a, 0] + hn[k, 1] * p[a, 1]) - (hc[k] + ra)
                if not res >= 0.0:
                    return -1
                if res <= ROW_TOLERANCE:
                    active += 1
        for k in range(sa.shape[0]):
            dist, dx, dy, fx, fy = segment_foot(x, y, sa[k, 0], sa[k, 1], sb[k, 0], sb[k, 1])
            if dist - ra <= cut:
                ex, ey = unit(dx, dy, dist)
                res = (ex * p[a, 0] + ey * p[a, 1]) - ((ex * fx + ey * fy) + ra)
                if not res >= 0.0:
                    return -1
                if res <= ROW_TOLERANCE:
                    active += 1
        for k in range(cc.shape[0]):
            val, dist, dx, dy = disk_gap(x, y, cc[k, 0], cc[k, 1], cr[k], ra)
            if val <= cut:
                ex, ey = unit(dx, dy, dist)
                foot = (ex * cc[k, 0] + ey * cc[k, 1]) + cr[k]
                res = (ex * p[a, 0] + ey * p[a, 1]) - (foot + ra)
                if not res >= 0.0:
                    return -1
                if res <= ROW_TOLERANCE:
                    active += 1
    return active
