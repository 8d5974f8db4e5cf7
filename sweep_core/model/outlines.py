"""Outlines: the vertex lists of polylines, polygons and regions, checked, and point-in-polygon.
Coordinates in m, points (M, 2)."""
from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from fractions import Fraction
from typing import Any

import numpy as np

from sweep_core import checks
from sweep_core.errors import CostError, SceneError

#: pairs of edges the simple-outline tests of one scene's closed outlines (rooms, polygons,
#: regions) may examine, a closed outline of M points counting M^2 / 2; an edge pair whose
#: turns must be decided in exact arithmetic counts :data:`EXACT_PAIRS`. At about 0.3 us a
#: pair (the worst case, every pair's bounding boxes overlapping) this bounds the tests near
#: 3 s; one outline may have up to about 4 400 points
MAX_OUTLINE_PAIRS = 10_000_000
#: what one exact (rational) evaluation of a turn counts against MAX_OUTLINE_PAIRS
EXACT_PAIRS = 100
#: the scene's charge so far and the field being checked (None: nothing counted)
_CHARGED: ContextVar[list | None] = ContextVar("outline_pairs", default=None)


@contextmanager
def pair_budget() -> Iterator[None]:
    """Within it, the simple-outline tests count the pairs they examine against
    :data:`MAX_OUTLINE_PAIRS` (a scene's build: :mod:`sweep_core.model.scene`)."""
    token = _CHARGED.set([0, ""])
    try:
        yield
    finally:
        _CHARGED.reset(token)


def _charge(pairs: int, field: str | None = None) -> None:
    """Count ``pairs`` against the budget (``field``: the outline now checked); raise
    CostError naming it when the scene's outlines pass MAX_OUTLINE_PAIRS."""
    charged = _CHARGED.get()
    if charged is None:
        return
    if field is not None:
        charged[1] = field
    charged[0] += pairs
    if charged[0] > MAX_OUTLINE_PAIRS:
        raise CostError(charged[1], f"brings the pairs of edges the scene's closed outlines "
                        f"are checked for crossings to {charged[0]}, more than "
                        f"{MAX_OUTLINE_PAIRS} (the limit MAX_OUTLINE_PAIRS; an outline of M "
                        "points counts M^2 / 2)",
                        "give long outlines with fewer points, or as open polylines "
                        "(closed: false, which are not checked for crossings)")


def chain_points(value: Any, field: str, closed: bool, least: int) -> np.ndarray:
    """The vertices (M, 2) of a polyline or polygon, checked: at least ``least`` points, no
    edge of zero length, and for a closed chain no two edges crossing (a closed chain given
    with its first point repeated at the end is accepted without the repeat); coordinates within
    +-checks.COORDINATE_BOUND."""
    points = checks.points(value, field)
    if closed and len(points) > 1 and np.array_equal(points[0], points[-1]):
        points = points[:-1]
    if len(points) < least:
        shape = "a closed outline" if closed else "a chain"
        raise SceneError(field, f"has {len(points)} points; {shape} needs at least {least}",
                         "list the vertices in order, e.g. [[0, 0], [4, 0], [4, 3]]")
    ends = np.roll(points, -1, axis=0) if closed else points[1:]
    length = np.hypot(*(ends - points[: len(ends)]).T)
    if length.min() < 1e-12:
        k = int(np.argmin(length))
        raise SceneError(field, f"points {k} and {(k + 1) % len(points)} coincide at "
                         f"[{points[k, 0]:g}, {points[k, 1]:g}] (an edge of zero length)",
                         "remove the repeated point")
    if closed:
        _charge(len(points) * len(points) // 2, field)
        crossing = first_crossing(points)
        if crossing is not None:
            i, j = crossing
            how = "fold back on each other" if (j - i) % len(points) in (1, len(points) - 1) \
                else "cross or touch"
            raise SceneError(field, f"edges {i} and {j} {how} (the outline is not simple)",
                             "give the vertices in order around the outline, or split it into "
                             "several polygons")
    return points


#: Shewchuk's bound on the relative error of the float orientation determinant: when
#: |det| > ORIENT_BOUND * (|t1| + |t2|) its sign is the exact sign (J. R. Shewchuk, Adaptive
#: precision floating-point arithmetic and fast robust geometric predicates, 1997, ccwerrboundA)
ORIENT_BOUND = (3.0 + 16.0 * 2.0 ** -53) * 2.0 ** -53


def orientation(p: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The exact sign (-1, 0, 1, int array) of the turn p -> q -> r for float points (..., 2)
    broadcast together: +1 counter-clockwise, 0 collinear. The float determinant decides when
    its error bound allows; the rare others are evaluated in exact rational arithmetic."""
    p, q, r = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (p, q, r)))
    shape = p.shape[:-1]
    p, q, r = (v.reshape(-1, 2) for v in (p, q, r))
    t1 = (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1])
    t2 = (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])
    det = t1 - t2
    sign = np.sign(det).astype(np.int64)
    unsure = np.flatnonzero(np.abs(det) <= ORIENT_BOUND * (np.abs(t1) + np.abs(t2)))
    _charge(EXACT_PAIRS * len(unsure))
    for at in unsure:
        (px, py), (qx, qy), (rx, ry) = (map(Fraction, v[at].tolist()) for v in (p, q, r))
        exact = (qx - px) * (ry - py) - (qy - py) * (rx - px)
        sign[at] = (exact > 0) - (exact < 0)
    return sign.reshape(shape)


def segments_meet(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """bool (...): the closed segments [a, b] and [c, d] (points (..., 2), broadcast) share
    a point, decided exactly (:func:`orientation`; a collinear pair meets when they overlap)."""
    a, b, c, d = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (a, b, c, d)))
    o1, o2 = orientation(a, b, c), orientation(a, b, d)
    o3, o4 = orientation(c, d, a), orientation(c, d, b)

    def within(p: np.ndarray, s: np.ndarray, e: np.ndarray) -> np.ndarray:
        # p collinear with [s, e]: inside its bounding box (exact comparisons)
        return np.all((np.minimum(s, e) <= p) & (p <= np.maximum(s, e)), axis=-1)

    return (((o1 * o2 < 0) & (o3 * o4 < 0))
            | ((o1 == 0) & within(c, a, b)) | ((o2 == 0) & within(d, a, b))
            | ((o3 == 0) & within(a, c, d)) | ((o4 == 0) & within(b, c, d)))


def first_crossing(points: np.ndarray) -> tuple[int, int] | None:
    """The first pair of edges of a closed chain that meet other than at their shared
    vertex (i, j), or None: two non-adjacent edges sharing a point, or two adjacent edges
    folding back on each other (collinear, opposite directions). Collinear vertices (an edge
    continuing in the same direction) are fine; decided exactly."""
    a, b = points, np.roll(points, -1, axis=0)
    m = len(points)
    nxt = np.roll(np.arange(m), -1)
    turn = orientation(a, b, b[nxt])
    u, v = b - a, b[nxt] - a[nxt]
    ahead = u[:, 0] * v[:, 0] + u[:, 1] * v[:, 1]  # exact sign for parallel u, v
    for k in np.flatnonzero((turn == 0) & (ahead < 0)):
        return (int(k), int(nxt[k])) if nxt[k] > k else (int(nxt[k]), int(k))
    # two closed segments can meet only where their bounding boxes overlap (exact
    # comparisons): the exact test runs on those pairs only, taken in blocks of rows and in
    # the order (i, then j) so that the first pair found is the first in that order
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    cols = np.arange(m)
    rows_per_block = max(1, (1 << 22) // m)
    for start in range(0, m - 2, rows_per_block):
        rows = np.arange(start, min(start + rows_per_block, m - 2))
        near = ((cols[None] >= rows[:, None] + 2)
                & (lo[None, :, 0] <= hi[rows, None, 0]) & (lo[rows, None, 0] <= hi[None, :, 0])
                & (lo[None, :, 1] <= hi[rows, None, 1]) & (lo[rows, None, 1] <= hi[None, :, 1]))
        if start == 0:
            near[0, m - 1] = False  # the last edge ends where the first begins
        ii, jj = np.nonzero(near)  # row-major: sorted by i, then j
        for at in range(0, len(ii), 1 << 16):
            i, j = rows[ii[at:at + (1 << 16)]], jj[at:at + (1 << 16)]
            hit = segments_meet(a[i], b[i], a[j], b[j])
            if np.any(hit):
                first = int(np.argmax(hit))
                return int(i[first]), int(j[first])
    return None


def points_in_polygon(q: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(N,) bool: q (N, 2) inside the closed outline ``points`` (M, 2), even-odd rule on a ray
    towards +x."""
    a, b = points, np.roll(points, -1, axis=0)
    y = q[:, 1:2]
    straddle = (a[:, 1][None] > y) != (b[:, 1][None] > y)
    dy = np.where(b[:, 1] != a[:, 1], b[:, 1] - a[:, 1], 1.0)
    x_cross = a[:, 0][None] + (y - a[:, 1][None]) * (b[:, 0] - a[:, 0])[None] / dy
    return (np.count_nonzero(straddle & (x_cross > q[:, 0:1]), axis=1) % 2) == 1


def signed_area(points: np.ndarray) -> float:
    """Signed area (m^2) of the closed polygon ``points`` (M, 2), positive anticlockwise (the
    shoelace formula)."""
    nxt = np.roll(points, -1, axis=0)
    return 0.5 * float(np.sum(points[:, 0] * nxt[:, 1] - nxt[:, 0] * points[:, 1]))


def perimeter(points: np.ndarray) -> float:
    """Length (m) of the closed polygon ``points`` (M, 2)."""
    edge = np.roll(points, -1, axis=0) - points
    return float(np.sum(np.hypot(edge[:, 0], edge[:, 1])))
