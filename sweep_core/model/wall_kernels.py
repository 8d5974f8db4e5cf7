"""Compiled kernels of the wall and obstacle rows and of the exact crossing test (numba).

:func:`near_rows` is :func:`sweep_core.model.geometry.single_rows`' dense evaluation of the
half-planes, segments and circles in one pass over the agents, the same floating-point
operations in the same order as the vectorised numpy form (each two-term dot product
x0*y0 + x1*y1, no fused multiply-add: numba compiles without fastmath, so LLVM contracts
nothing), so the rows' bits are those of the numpy form on every CPU.

:func:`paths_meet` is :func:`sweep_core.model.outlines.segments_meet` for many pairs: the
bounding boxes compared exactly, the four orientation determinants in float with Shewchuk's
error filter; a pair whose sign the filter cannot vouch for is returned as unsure, for the
exact rational evaluation in Python (:func:`sweep_core.model.outlines.orientation`).

:func:`pair_gaps` and :func:`single_gaps` are :func:`sweep_core.model.gaps.gaps`' summary
(smallest value, its place, contacts, the segment pairs near the agents) in one pass each, the
values the bits of :func:`near_rows` and of the numpy form; :func:`crossing_pairs` gathers the
crossing test's candidate pairs (:func:`sweep_core.model.crossing.crossings`) and tests them.

Compiled with ``cache=True`` (see :mod:`sweep_core.model.neighbours`).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from sweep_core.model.outlines import segments_meet

#: Shewchuk's ccwerrboundA (as :data:`sweep_core.model.outlines.ORIENT_BOUND`)
_ORIENT_BOUND = (3.0 + 16.0 * 2.0 ** -53) * 2.0 ** -53


@numba.njit(cache=True, nogil=True, inline="always")
def segment_foot(x: float, y: float, ax: float, ay: float, bx: float, by: float
                 ) -> tuple[float, float, float, float, float]:  # pragma: no cover - compiled
    """The point of the segment [a, b] closest to (x, y) (m): (dist, dx, dy, fx, fy), the foot
    f = a + s (b - a) with s = <(x, y) - a, b - a> / |b - a|^2 clamped to [0, 1], the offset
    (dx, dy) = (x, y) - f and dist = sqrt(dx^2 + dy^2) (the bits of the numpy form)."""
    abx, aby = bx - ax, by - ay
    s = ((x - ax) * abx + (y - ay) * aby) / (abx * abx + aby * aby)
    s = min(max(s, 0.0), 1.0)
    fx, fy = ax + s * abx, ay + s * aby
    dx, dy = x - fx, y - fy
    return math.sqrt(dx * dx + dy * dy), dx, dy, fx, fy


@numba.njit(cache=True, nogil=True, inline="always")
def halfplane_value(x: float, y: float, nx: float, ny: float, c: float, ra: float
                    ) -> float:  # pragma: no cover - compiled
    """The value (m) of the half-plane <n, z> >= c (offset c at t) for the disk at (x, y) of
    radius ra: (x nx + y ny - c) - ra."""
    return (x * nx + y * ny - c) - ra


@numba.njit(cache=True, nogil=True, inline="always")
def disk_gap(x0: float, y0: float, x1: float, y1: float, r0: float, r1: float
             ) -> tuple[float, float, float, float]:  # pragma: no cover - compiled
    """The gap (m) of the disks at (x0, y0), radius r0 and (x1, y1), radius r1:
    ((dist - r0) - r1, dist, dx, dy) with (dx, dy) = (x0 - x1, y0 - y1), dist its length.
    Subtracted in this order, so a disk at (x, y), radius ra against a circle obstacle at c,
    radius rc is disk_gap(x, y, cx, cy, rc, ra) (the numpy form's (dist - rc) - ra)."""
    dx, dy = x0 - x1, y0 - y1
    dist = math.sqrt(dx * dx + dy * dy)
    return dist - r0 - r1, dist, dx, dy


@numba.njit(cache=True, nogil=True, inline="always")
def unit(dx: float, dy: float, dist: float) -> tuple[float, float]:  # pragma: no cover
    """(dx, dy) / dist, with dist floored at 1e-300 (a row's unit normal; dist its length)."""
    den = max(dist, 1e-300)
    return dx / den, dy / den


@numba.njit(cache=True, nogil=True)
def near_rows(q: np.ndarray, r: np.ndarray, reach: float, hn: np.ndarray, hc: np.ndarray,
              sa: np.ndarray, sb: np.ndarray, inside: np.ndarray, cc: np.ndarray,
              cr: np.ndarray, agent: np.ndarray, item: np.ndarray, g: np.ndarray,
              nrm: np.ndarray, foot: np.ndarray, counts: np.ndarray) -> int:
    """Every (agent, item) of the half-planes hn (W, 2), hc (W,) (offsets at t), segments
    [sa, sb] (S, 2) and circles cc (O, 2), cr (O,) whose value at q (N, 2), r (N,) is <= reach
    (m), written kind after kind into agent, item, g, nrm (M, 2), foot (M,) (room for
    N * (W + S + O) rows), agent-major within a kind; counts (3,) the rows of each kind;
    returns their total.
    inside (N, S) bool: the centre lies inside the solid polygon segment k bounds (value
    -dist - r), or shape (0, 0) when no segment bounds one."""
    n = q.shape[0]
    m = 0
    polygons = inside.shape[0] > 0
    start = m
    for a in range(n):
        x, y, ra = q[a, 0], q[a, 1], r[a]
        for k in range(hn.shape[0]):
            val = halfplane_value(x, y, hn[k, 0], hn[k, 1], hc[k], ra)
            if val <= reach:
                agent[m], item[m], g[m] = a, k, val
                nrm[m, 0], nrm[m, 1], foot[m] = hn[k, 0], hn[k, 1], hc[k]
                m += 1
    counts[0] = m - start
    start = m
    for a in range(n):
        x, y, ra = q[a, 0], q[a, 1], r[a]
        for k in range(sa.shape[0]):
            dist, dx, dy, fx, fy = segment_foot(x, y, sa[k, 0], sa[k, 1], sb[k, 0], sb[k, 1])
            val = dist - ra
            if polygons and inside[a, k]:
                val = -dist - ra
            if val <= reach:
                ex, ey = unit(dx, dy, dist)
                agent[m], item[m], g[m] = a, k, val
                nrm[m, 0], nrm[m, 1], foot[m] = ex, ey, ex * fx + ey * fy
                m += 1
    counts[1] = m - start
    start = m
    for a in range(n):
        x, y, ra = q[a, 0], q[a, 1], r[a]
        for k in range(cc.shape[0]):
            val, dist, dx, dy = disk_gap(x, y, cc[k, 0], cc[k, 1], cr[k], ra)
            if val <= reach:
                ex, ey = unit(dx, dy, dist)
                agent[m], item[m], g[m] = a, k, val
                nrm[m, 0], nrm[m, 1] = ex, ey
                foot[m] = (ex * cc[k, 0] + ey * cc[k, 1]) + cr[k]
                m += 1
    counts[2] = m - start
    return m


@numba.njit(cache=True, nogil=True)
def _orient(px: float, py: float, qx: float, qy: float, rx: float, ry: float
            ) -> tuple[int, bool]:
    """The float sign of the turn p -> q -> r and whether the error filter vouches for it."""
    t1 = (qx - px) * (ry - py)
    t2 = (qy - py) * (rx - px)
    det = t1 - t2
    sure = abs(det) > _ORIENT_BOUND * (abs(t1) + abs(t2))
    return (1 if det > 0 else (-1 if det < 0 else 0)), sure


@numba.njit(cache=True, nogil=True)
def _within(px: float, py: float, sx: float, sy: float, ex: float, ey: float) -> bool:
    return (min(sx, ex) <= px <= max(sx, ex)) and (min(sy, ey) <= py <= max(sy, ey))


@numba.njit(cache=True, nogil=True)
def paths_meet(p0: np.ndarray, p1: np.ndarray, a: np.ndarray, b: np.ndarray,
               hit: np.ndarray, unsure: np.ndarray) -> None:
    """For each pair m: the closed segments [p0_m, p1_m] and [a_m, b_m] ((M, 2) each) share
    a point (hit[m]), decided from float orientations the filter vouches for; unsure[m] when
    the boxes overlap and some orientation is not vouched for (hit[m] is then meaningless:
    decide it exactly)."""
    for m in range(p0.shape[0]):
        hit[m] = False
        unsure[m] = False
        ax, ay, bx, by = p0[m, 0], p0[m, 1], p1[m, 0], p1[m, 1]
        cx, cy, dx, dy = a[m, 0], a[m, 1], b[m, 0], b[m, 1]
        if not (min(ax, bx) <= max(cx, dx) and min(cx, dx) <= max(ax, bx)
                and min(ay, by) <= max(cy, dy) and min(cy, dy) <= max(ay, by)):
            continue
        o1, s1 = _orient(ax, ay, bx, by, cx, cy)
        o2, s2 = _orient(ax, ay, bx, by, dx, dy)
        o3, s3 = _orient(cx, cy, dx, dy, ax, ay)
        o4, s4 = _orient(cx, cy, dx, dy, bx, by)
        if not (s1 and s2 and s3 and s4):
            unsure[m] = True
            continue
        hit[m] = ((o1 * o2 < 0 and o3 * o4 < 0)
                  or (o1 == 0 and _within(cx, cy, ax, ay, bx, by))
                  or (o2 == 0 and _within(dx, dy, ax, ay, bx, by))
                  or (o3 == 0 and _within(ax, ay, cx, cy, dx, dy))
                  or (o4 == 0 and _within(bx, by, cx, cy, dx, dy)))


def paths_meet_exactly(p0: np.ndarray, p1: np.ndarray, a: np.ndarray, b: np.ndarray
                       ) -> np.ndarray:
    """bool (M,): [p0_m, p1_m] and [a_m, b_m] ((M, 2) float64 each) share a point, decided
    exactly: :func:`paths_meet`, and :func:`~sweep_core.model.outlines.segments_meet`'s
    rational arithmetic for the pairs it leaves unsure."""
    p0, p1, a, b = (np.ascontiguousarray(v, dtype=np.float64) for v in (p0, p1, a, b))
    hit, unsure = np.empty(len(p0), dtype=np.bool_), np.empty(len(p0), dtype=np.bool_)
    paths_meet(p0, p1, a, b, hit, unsure)
    if unsure.any():
        hit[unsure] = segments_meet(p0[unsure], p1[unsure], a[unsure], b[unsure])
    return hit


@numba.njit(cache=True, nogil=True)
def pair_gaps(q: np.ndarray, r: np.ndarray, i: np.ndarray, j: np.ndarray, contact_tol: float,
              pg: np.ndarray) -> tuple[int, int]:
    """pg[m] = |q_i - q_j| - r_i - r_j (m) for the pairs (i, j) (M,) each; returns the count
    of pg <= contact_tol and the first index of the smallest pg (-1 when M = 0)."""
    contacts, w = 0, -1
    for m in range(i.shape[0]):
        a, b = i[m], j[m]
        v = disk_gap(q[a, 0], q[a, 1], q[b, 0], q[b, 1], r[a], r[b])[0]
        pg[m] = v
        if v <= contact_tol:
            contacts += 1
        if w < 0 or v < pg[w]:
            w = m
    return contacts, w


@numba.njit(cache=True, nogil=True)
def single_gaps(q: np.ndarray, r: np.ndarray, hn: np.ndarray, hc: np.ndarray,
                sa: np.ndarray, sb: np.ndarray, inside: np.ndarray, cc: np.ndarray,
                cr: np.ndarray, contact_tol: float, reach: float, vals: np.ndarray,
                near_a: np.ndarray, near_k: np.ndarray, out: np.ndarray) -> int:
    """The summary of every half-plane, segment and circle value at q (N, 2), r (N,) (the
    arguments of :func:`near_rows`, whose values these are, bit for bit): vals (room for
    N * (W + S + O)) holds them kind after kind, agent-major. The search distance starts at
    ``reach`` and grows eightfold until some value lies within it (or it exceeds 1e12 m).
    out (6,) float64 receives: that distance, the count of values <= contact_tol, the
    smallest value within it, its kind (0, 1, 2), agent and item (-1: none); near_a, near_k
    (room for N * S) the (agent, segment) pairs within it, agent-major, whose count is
    returned. A NaN value makes out[3] = -2 (the caller then takes the numpy path)."""
    n = q.shape[0]
    polygons = inside.shape[0] > 0
    nh, ns, nc = hn.shape[0], sa.shape[0], cc.shape[0]
    low = math.inf
    m = 0
    for a in range(n):
        x, y, ra = q[a, 0], q[a, 1], r[a]
        for k in range(nh):
            vals[m] = halfplane_value(x, y, hn[k, 0], hn[k, 1], hc[k], ra)
            m += 1
    for a in range(n):
        x, y, ra = q[a, 0], q[a, 1], r[a]
        for k in range(ns):
            dist = segment_foot(x, y, sa[k, 0], sa[k, 1], sb[k, 0], sb[k, 1])[0]
            val = dist - ra
            if polygons and inside[a, k]:
                val = -dist - ra
            vals[m] = val
            m += 1
    for a in range(n):
        x, y, ra = q[a, 0], q[a, 1], r[a]
        for k in range(nc):
            vals[m] = disk_gap(x, y, cc[k, 0], cc[k, 1], cr[k], ra)[0]
            m += 1
    for u in range(m):
        if math.isnan(vals[u]):
            out[3] = -2.0
            return 0
        low = min(low, vals[u])
    while not (low <= reach or reach > 1e12):
        reach *= 8.0
    out[0] = reach
    contacts = 0
    best, kind, who, item = math.inf, -1, -1, -1
    found = 0
    start = 0
    for kd, width in enumerate((nh, ns, nc)):
        for u in range(n * width):
            v = vals[start + u]
            if v > reach:
                continue
            if v <= contact_tol:
                contacts += 1
            if v < best:
                best, kind, who, item = v, kd, u // width, u % width
            if kd == 1:
                near_a[found], near_k[found] = u // width, u % width
                found += 1
        start += n * width
    out[1], out[2], out[3], out[4], out[5] = contacts, best, kind, who, item
    return found


@numba.njit(cache=True, nogil=True)
def _path_meets(ax: float, ay: float, bx: float, by: float, cx: float, cy: float, dx: float,
                dy: float) -> tuple[bool, bool]:
    """(hit, unsure) of :func:`paths_meet` for one pair [a, b], [c, d]."""
    if not (min(ax, bx) <= max(cx, dx) and min(cx, dx) <= max(ax, bx)
            and min(ay, by) <= max(cy, dy) and min(cy, dy) <= max(ay, by)):
        return False, False
    o1, s1 = _orient(ax, ay, bx, by, cx, cy)
    o2, s2 = _orient(ax, ay, bx, by, dx, dy)
    o3, s3 = _orient(cx, cy, dx, dy, ax, ay)
    o4, s4 = _orient(cx, cy, dx, dy, bx, by)
    if not (s1 and s2 and s3 and s4):
        return False, True
    return ((o1 * o2 < 0 and o3 * o4 < 0)
            or (o1 == 0 and _within(cx, cy, ax, ay, bx, by))
            or (o2 == 0 and _within(dx, dy, ax, ay, bx, by))
            or (o3 == 0 and _within(ax, ay, cx, cy, dx, dy))
            or (o4 == 0 and _within(bx, by, cx, cy, dx, dy))), False


@numba.njit(cache=True, nogil=True)
def crossing_pairs(q0: np.ndarray, q1: np.ndarray, r1: np.ndarray, near_a: np.ndarray,
                   near_k: np.ndarray, reach: float, sa: np.ndarray, sb: np.ndarray,
                   static: np.ndarray, dense: int, out_i: np.ndarray, out_k: np.ndarray,
                   out_unsure: np.ndarray) -> int:
    """:func:`sweep_core.model.crossing.crossings`' candidates and their test in one pass:
    the near pairs (near_a, near_k) and, for every agent that moved farther than reach +
    r1 (every agent when reach < 0), each static segment; a candidate is kept when its
    segment is static and its agent moved. Writes the candidates whose path meets their
    segment, or which the error filter leaves unsure (out_unsure), in the candidates' order
    into out_i, out_k (room for len(near_a) + N * S); returns their count, or -1 when the far
    agents times the static segments exceed ``dense`` (the caller searches them instead)."""
    n, ns = q0.shape[0], sa.shape[0]
    n_static = 0
    for k in range(ns):
        if static[k]:
            n_static += 1
    far = 0
    for a in range(n):
        step = math.hypot(q1[a, 0] - q0[a, 0], q1[a, 1] - q0[a, 1])
        if step > (-1.0 if reach < 0 else reach + r1[a]):
            far += 1
    if far * n_static > dense:
        return -1
    m = 0
    for u in range(near_a.shape[0]):
        a, k = near_a[u], near_k[u]
        if not static[k] or (q1[a, 0] == q0[a, 0] and q1[a, 1] == q0[a, 1]):
            continue
        hit, unsure = _path_meets(q0[a, 0], q0[a, 1], q1[a, 0], q1[a, 1], sa[k, 0], sa[k, 1],
                                  sb[k, 0], sb[k, 1])
        if hit or unsure:
            out_i[m], out_k[m], out_unsure[m] = a, k, unsure
            m += 1
    for a in range(n):
        if q1[a, 0] == q0[a, 0] and q1[a, 1] == q0[a, 1]:
            continue
        step = math.hypot(q1[a, 0] - q0[a, 0], q1[a, 1] - q0[a, 1])
        if not step > (-1.0 if reach < 0 else reach + r1[a]):
            continue
        for k in range(ns):
            if not static[k]:
                continue
            hit, unsure = _path_meets(q0[a, 0], q0[a, 1], q1[a, 0], q1[a, 1], sa[k, 0],
                                      sa[k, 1], sb[k, 0], sb[k, 1])
            if hit or unsure:
                out_i[m], out_k[m], out_unsure[m] = a, k, unsure
                m += 1
    return m


@numba.njit(cache=True, nogil=True)
def pair_rows(q: np.ndarray, r: np.ndarray, i: np.ndarray, j: np.ndarray, cut: float,
              out_i: np.ndarray, out_j: np.ndarray, out_e: np.ndarray, out_b: np.ndarray
              ) -> int:
    """The linearised pair rows (:func:`sweep_core.numerics.constraints.linearise`) of the
    pairs (i, j) (M,) whose gap |q_i - q_j| - r_i - r_j is <= cut (m): their agents, unit
    vectors e = (q_i - q_j) / |q_i - q_j| (M, 2) and bounds r_i + r_j (m), in the pairs'
    order (the numpy form's bits); returns their count."""
    m = 0
    for u in range(i.shape[0]):
        a, b = i[u], j[u]
        val, dist, dx, dy = disk_gap(q[a, 0], q[a, 1], q[b, 0], q[b, 1], r[a], r[b])
        if val <= cut:
            out_i[m], out_j[m] = a, b
            out_e[m, 0], out_e[m, 1] = unit(dx, dy, dist)
            out_b[m] = r[a] + r[b]
            m += 1
    return m
