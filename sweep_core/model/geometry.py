"""What the walls and obstacles are, and the true constraint values g_k(t, q) (reference §2-3).

The feasible set Q(t) = {q : |q_i - q_j| >= r_i(t) + r_j(t), g_k(t, q_i) >= 0}: this module
evaluates those functions exactly (no linearisation; that is :mod:`sweep_core.numerics.constraints`).
Distances in m, positions (N, 2).

Two evaluations: every value (:func:`single_values`) and the rows within a reach
(:func:`single_rows`); the gaps' summary after a step is :mod:`sweep_core.model.gaps`, and the
compiled loops are in :mod:`sweep_core.model.wall_kernels`.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from functools import cached_property
from typing import Any

import numpy as np

from sweep_core.model import elementary
from sweep_core.model.neighbours import segments_within
from sweep_core.model.outlines import points_in_polygon
from sweep_core.model.user import constraint_name, evaluate
from sweep_core.model.wall_kernels import near_rows

# codes of single-row kinds, in the order of scene.geometry
HALFPLANE, SEGMENT, CIRCLE, USER = 0, 1, 2, 3
KIND_NAMES = ("walls(halfplane)", "walls(segment)", "obstacles(circle)", "constraints(user)")


@dataclass(frozen=True)
class Geometry:
    """Static description of walls and obstacles (arrays may be empty).

    halfplane_normal (W, 2) unit, halfplane_offset (W,) m, halfplane_velocity (W,) m/s:
        <n, q_i> - (c + v t) >= r_i(t).
    segment_a, segment_b (S, 2) m: dist(q_i, [a, b]) >= r_i(t).
    circle_center (O, 2) m, circle_radius (O,) m: |q_i - c| >= R + r_i(t).
    halfplane_index, segment_index, circle_index: position of each item in the scene's
        ``walls`` / ``obstacles`` lists, for messages.
    segment_polygon (S,): for a segment that is an edge of a solid polygon obstacle, the
        polygon's position in ``obstacles`` (-1: a wall segment or polyline piece). A polygon
        obstacle is its closed boundary: dist(q_i, P) >= r_i(t) holds exactly when every edge
        has dist(q_i, edge) >= r_i(t) and q_i lies outside P; each edge is a convex piece, so
        a polygon need not be convex and is not split further.
    segment_part (S,): the edge's or piece's position within its polyline or polygon (0 for a
        plain segment), for messages.
    """

    halfplane_normal: np.ndarray
    halfplane_offset: np.ndarray
    halfplane_velocity: np.ndarray
    segment_a: np.ndarray
    segment_b: np.ndarray
    circle_center: np.ndarray
    circle_radius: np.ndarray
    halfplane_index: np.ndarray
    segment_index: np.ndarray
    circle_index: np.ndarray
    segment_polygon: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.intp))
    segment_part: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.intp))
    segment_kind: tuple[str, ...] = ()
    #: rigid motions of moving obstacles: row m of motion_velocity (M, 2) m/s,
    #: motion_angular (M,) rad/s, motion_pivot (M, 2) m moves a point p0 to
    #: pivot + Rot(w t) (p0 - pivot) + v t; segment_motion (S,) and circle_motion (O,) give
    #: each segment's or circle's motion row (-1: static)
    motion_velocity: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))
    motion_angular: np.ndarray = field(default_factory=lambda: np.empty(0))
    motion_pivot: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))
    segment_motion: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.intp))
    circle_motion: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.intp))
    #: user constraints g(t, q_i) >= r_i(t) (:mod:`sweep_core.model.user`)
    user: tuple = ()

    def __post_init__(self) -> None:
        s = len(self.segment_a)
        if len(self.segment_polygon) != s:
            object.__setattr__(self, "segment_polygon", np.full(s, -1, dtype=np.intp))
        if len(self.segment_part) != s:
            object.__setattr__(self, "segment_part", np.zeros(s, dtype=np.intp))
        if len(self.segment_kind) != s:
            object.__setattr__(self, "segment_kind", ("segment",) * s)
        if len(self.segment_motion) != s:
            object.__setattr__(self, "segment_motion", np.full(s, -1, dtype=np.intp))
        if len(self.circle_motion) != len(self.circle_radius):
            object.__setattr__(self, "circle_motion",
                               np.full(len(self.circle_radius), -1, dtype=np.intp))

    @cached_property
    def packed(self) -> tuple[np.ndarray, ...]:
        """The arrays the compiled kernels take, C-contiguous float64, computed once: the
        half-planes' normals (W, 2) and offsets at t = 0 plus 0.0 (W,), the segments' ends
        (S, 2) each, the circles' centres (O, 2) and radii (O,)."""
        c = np.ascontiguousarray
        return (c(self.halfplane_normal, dtype=np.float64),
                c(self.halfplane_offset + self.halfplane_velocity * 0.0, dtype=np.float64),
                c(self.segment_a, dtype=np.float64), c(self.segment_b, dtype=np.float64),
                c(self.circle_center, dtype=np.float64), c(self.circle_radius, dtype=np.float64))

    @cached_property
    def fixed_halfplanes(self) -> bool:
        """No half-plane moves (their offsets at any t are those at t = 0)."""
        return not np.any(self.halfplane_velocity)

    @cached_property
    def static_segments(self) -> np.ndarray:
        """(S,) bool: the segments that do not move (the crossing check's), computed once
        (not to be written: a writeable array, the type the compiled check takes)."""
        return self.segment_motion < 0

    @cached_property
    def has_polygons(self) -> bool:
        """Some segment is the edge of a solid polygon."""
        return bool(np.any(self.segment_polygon >= 0))

    def with_circles(self, centres: np.ndarray, radii: np.ndarray) -> Geometry:
        """This geometry with static circle obstacles added (centres (M, 2), radii (M,) m,
        item indices after its own circles, scene index -1), its packed arrays carried over.

        Built without ``dataclasses.replace`` (a robot's step adds its disk every step): the
        fields copied, the circles' index and motion columns of M added disks kept per
        geometry, and ``__post_init__``, which only fills columns of the wrong length, not
        needed (every column has its length)."""
        m = len(radii)
        kept = self.__dict__.get("_added_circles")
        if kept is None or kept[0] != m:
            kept = (m, np.concatenate([self.circle_index,
                                       np.full(m, -1, dtype=self.circle_index.dtype)]),
                    np.concatenate([self.circle_motion, np.full(m, -1, dtype=np.intp)]))
            self.__dict__["_added_circles"] = kept
        out = object.__new__(Geometry)
        cache = out.__dict__
        own = self.__dict__
        cache.update({name: own[name] for name in _FIELDS})
        cache["circle_center"] = np.concatenate([self.circle_center, centres])
        cache["circle_radius"] = np.concatenate([self.circle_radius, radii])
        cache["circle_index"], cache["circle_motion"] = kept[1], kept[2]
        hn, off, sa, sb, _, _ = self.packed
        cache["packed"] = (hn, off, sa, sb, np.ascontiguousarray(out.circle_center,
                                                                 dtype=np.float64),
                           np.ascontiguousarray(out.circle_radius, dtype=np.float64))
        cache["fixed_halfplanes"], cache["has_polygons"] = self.fixed_halfplanes, \
            self.has_polygons
        return out

    def offsets(self, t: float) -> np.ndarray:
        """(W,) the half-planes' offsets c + v t at t (s), m, C-contiguous float64."""
        if self.fixed_halfplanes:
            return self.packed[1]
        return np.ascontiguousarray(self.halfplane_offset + self.halfplane_velocity * t,
                                    dtype=np.float64)

    @property
    def is_moving(self) -> bool:
        """Some obstacle moves (``at`` gives its pose at a time)."""
        return len(self.motion_angular) > 0

    def at(self, t: float) -> Geometry:
        """The geometry at time t (s): moving obstacles at their pose, with no motion left
        (the same object when nothing moves). Half-planes keep their own velocity."""
        if not self.is_moving:
            return self
        angle = self.motion_angular * t
        # a pose decides positions: cos and sin with the same bits on every CPU
        cos, sin = elementary.cos_of(angle), elementary.sin_of(angle)

        def move(p: np.ndarray, m: np.ndarray) -> np.ndarray:
            out = p.copy()
            on = m >= 0
            k = m[on]
            d = p[on] - self.motion_pivot[k]
            out[on, 0] = (self.motion_pivot[k, 0] + cos[k] * d[:, 0] - sin[k] * d[:, 1]
                          + self.motion_velocity[k, 0] * t)
            out[on, 1] = (self.motion_pivot[k, 1] + sin[k] * d[:, 0] + cos[k] * d[:, 1]
                          + self.motion_velocity[k, 1] * t)
            return out

        return replace(self, segment_a=move(self.segment_a, self.segment_motion),
                       segment_b=move(self.segment_b, self.segment_motion),
                       circle_center=move(self.circle_center, self.circle_motion),
                       motion_velocity=np.empty((0, 2)), motion_angular=np.empty(0),
                       motion_pivot=np.empty((0, 2)),
                       segment_motion=np.full(len(self.segment_a), -1, dtype=np.intp),
                       circle_motion=np.full(len(self.circle_radius), -1, dtype=np.intp))

    @property
    def is_empty(self) -> bool:
        return not (len(self.halfplane_offset) or len(self.segment_a) or len(self.circle_radius)
                    or self.user)

    def moves(self, kind: int, item: int) -> bool:
        """Whether item ``item`` of kind ``kind`` (HALFPLANE, SEGMENT, CIRCLE) moves: a moving
        obstacle, or a half-plane with a velocity."""
        if kind == HALFPLANE:
            return bool(self.halfplane_velocity[item] != 0.0)
        if kind == SEGMENT:
            return bool(self.segment_motion[item] >= 0)
        return kind == CIRCLE and bool(self.circle_motion[item] >= 0)

    def path(self, kind: int, item: int) -> str:
        """Scene path of a wall/obstacle, e.g. ``walls[2]``."""
        return self.describe(kind, item).split(" ")[0]

    def describe(self, kind: int, item: int) -> str:
        """Scene-facing name of a wall/obstacle, e.g. ``walls[2] (segment)``."""
        if kind == HALFPLANE:
            return f"walls[{int(self.halfplane_index[item])}] (halfplane)"
        if kind == USER:
            return f"constraints[{item}] ({constraint_name(self.user[item], item)})"
        if kind == SEGMENT:
            what, part = self.segment_kind[item], int(self.segment_part[item])
            if int(self.segment_polygon[item]) >= 0:
                return f"obstacles[{int(self.segment_polygon[item])}] (polygon edge {part})"
            if what == "map":
                return f"map (wall {part})"
            if what == "segment":
                return f"walls[{int(self.segment_index[item])}] (segment)"
            return f"walls[{int(self.segment_index[item])}] ({what} piece {part})"
        return f"obstacles[{int(self.circle_index[item])}] (circle)"


#: the dataclass fields of a Geometry (what ``with_circles`` copies)
_FIELDS = tuple(f.name for f in fields(Geometry))


def single_values(geom: Geometry, t: float, q: np.ndarray, r: np.ndarray
                  ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """For each kind: (g, n, foot) with g (N, K) = constraint values at (t, q) in m,
    n (N, K, 2) the unit gradient, foot (N, K) the bound offset <n, point on the wall>."""
    geom = geom.at(t)
    out = []
    # half-planes: g = <n, q> - (c + v t) - r
    c = geom.halfplane_offset + geom.halfplane_velocity * t
    n = np.broadcast_to(geom.halfplane_normal, (len(q),) + geom.halfplane_normal.shape)
    # <n, q> written out (a matrix product goes through BLAS, whose kernels round differently
    # on different CPUs)
    hn = geom.halfplane_normal
    nq = q[:, 0:1] * hn[None, :, 0] + q[:, 1:2] * hn[None, :, 1]
    out.append((nq - c - r[:, None], n,
                np.broadcast_to(c, (len(q), len(c)))))
    # segments: g = |q - p| - r with p the closest point of [a, b]
    ab = geom.segment_b - geom.segment_a
    rel = q[:, None, :] - geom.segment_a[None, :, :]
    s = np.clip(np.einsum("nkc,kc->nk", rel, ab) / np.einsum("kc,kc->k", ab, ab), 0.0, 1.0)
    foot = geom.segment_a[None] + s[..., None] * ab[None]
    d = q[:, None, :] - foot
    dist = np.sqrt(np.einsum("nkc,nkc->nk", d, d))
    e = d / np.maximum(dist, 1e-300)[..., None]
    g = dist - r[:, None]
    if np.any(geom.segment_polygon >= 0):
        # inside a solid polygon: the true value is -dist - r (never feasible)
        inside = inside_polygons(q, geom)
        g = np.where(inside, -dist - r[:, None], g)
    out.append((g, e, np.einsum("nkc,nkc->nk", e, foot)))
    # circles: g = |q - c| - R - r
    d = q[:, None, :] - geom.circle_center[None]
    dist = np.sqrt(np.einsum("nkc,nkc->nk", d, d))
    e = d / np.maximum(dist, 1e-300)[..., None]
    out.append((dist - geom.circle_radius[None] - r[:, None], e,
                np.einsum("nkc,kc->nk", e, geom.circle_center) + geom.circle_radius[None]))
    # user constraints: value g - r, unit normal n = grad g / |grad g|, and the bound
    # <n, q> + (r - g) / |grad g| of the normalised row written as foot + r
    users = len(geom.user)
    gu = np.empty((len(q), users))
    nu, fu = np.empty((len(q), users, 2)), np.empty((len(q), users))
    for u in range(users):
        val, grad = evaluate(geom.user[u], u, t, q)
        size = np.maximum(np.hypot(grad[:, 0], grad[:, 1]), 1e-300)
        gu[:, u] = val - r
        nu[:, u] = grad / size[:, None]
        fu[:, u] = np.einsum("nc,nc->n", nu[:, u], q) + (r - val) / size - r
    out.append((gu, nu, fu))
    return out


def inside_polygons(q: np.ndarray, geom: Geometry) -> np.ndarray:
    """(N, S) bool: agent n's centre lies inside the solid polygon that segment k bounds
    (False for segments that bound none). Even-odd rule (:func:`points_in_polygon`) on each
    polygon's vertices, its edges' start points in order: a centre on an edge counts as
    outside (its distance, 0, already makes the row infeasible)."""
    poly = geom.segment_polygon
    out = np.zeros((len(q), len(poly)), dtype=bool)
    for p in np.unique(poly[poly >= 0]):
        edges = poly == p
        out[:, edges] = points_in_polygon(q, geom.segment_a[edges])[:, None]
    return out


#: agent x segment products up to which segments are evaluated densely, without the index
DENSE_SEGMENTS = 8192


def single_rows(geom: Geometry, t: float, q: np.ndarray, r: np.ndarray, reach: float
                ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """For each kind, every (agent, item) whose constraint value at (t, q) is <= reach (m), as
    1-D arrays (agent, item, g, n (M, 2), foot): what :func:`single_values` gives, without
    evaluating far pairs. Many segments (a map) are searched with a spatial index
    (:func:`segments_within`) instead of against every agent."""
    geom = geom.at(t)
    n_seg = len(geom.segment_a)
    if n_seg == 0 or len(q) * n_seg <= DENSE_SEGMENTS:
        return _dense_rows(geom, t, q, r, reach)
    empty = np.empty(0, dtype=np.intp)
    plain = replace(geom, segment_a=np.empty((0, 2)), segment_b=np.empty((0, 2)),
                    segment_index=empty, segment_polygon=empty, segment_part=empty,
                    segment_kind=(), segment_motion=empty)
    out = single_rows(plain, t, q, r, reach)
    a, k = segments_within(q, geom.segment_a, geom.segment_b, reach + float(r.max()))
    inside = None
    if np.any(geom.segment_polygon >= 0):
        # an agent inside a polygon may be near none of its edges, but is never feasible:
        # its pairs with every edge of that polygon are added (once) from the inside test
        inside = inside_polygons(q, geom)
        who, item = np.nonzero(inside)
        extra = ~np.isin(who * n_seg + item, a * n_seg + k)
        a, k = np.concatenate([a, who[extra]]), np.concatenate([k, item[extra]])
    dist, e, foot = _segment_values(geom, q, a, k)
    g = dist - r[a]
    if inside is not None:
        g = np.where(inside[a, k], -dist - r[a], g)  # as single_values has it
    keep = g <= reach
    out[SEGMENT] = (a[keep], k[keep], g[keep], e[keep], np.einsum("mc,mc->m", e, foot)[keep])
    return out


def dense_rows(geom: Geometry, t: float, q: np.ndarray, r: np.ndarray, reach: float
               ) -> tuple[np.ndarray, ...]:
    """The half-plane, segment and circle rows of a geometry with nothing moving within
    ``reach`` (m) at (t, q) (q (N, 2), r (N,) C-contiguous float64) in one compiled pass
    (:func:`~sweep_core.model.wall_kernels.near_rows`, the bits of :func:`single_values`):
    agent (M,), item (M,), value (M,), unit normal (M, 2), foot (M,), kind after kind, and
    the count of each kind (3,)."""
    hc = geom.offsets(t)
    inside = inside_polygons(q, geom) if geom.has_polygons else _NO_POLYGON
    hn, _, sa, sb, cc, cr = geom.packed
    room = len(q) * (len(hc) + len(sa) + len(cr))
    agent, item = np.empty(room, dtype=np.intp), np.empty(room, dtype=np.intp)
    g, nrm, foot = np.empty(room), np.empty((room, 2)), np.empty(room)
    counts = np.zeros(3, dtype=np.intp)
    m = near_rows(q, r, float(reach), hn, hc, sa, sb, inside, cc, cr, agent, item, g, nrm, foot,
                  counts)
    return agent[:m], item[:m], g[:m], nrm[:m], foot[:m], counts


def _dense_rows(geom: Geometry, t: float, q: np.ndarray, r: np.ndarray, reach: float
                ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """:func:`single_rows` evaluated against every item: half-planes, segments and circles in
    one compiled pass (:func:`dense_rows`), user constraints through :func:`single_values`'
    own code."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    r = np.ascontiguousarray(r, dtype=np.float64)
    agent, item, g, nrm, foot, counts = dense_rows(geom, t, q, r, reach)
    out = []
    start = 0
    for c in counts.tolist():
        part = slice(start, start + c)
        out.append((agent[part], item[part], g[part], nrm[part], foot[part]))
        start += c
    if geom.user:
        gu, nu, fu = single_values(replace(geom, **_NO_ITEMS), t, q, r)[USER]
        a, k = np.nonzero(gu <= reach)
        out.append((a, k, gu[a, k], nu[a, k], fu[a, k]))
    else:
        none = np.empty(0, dtype=np.intp)
        out.append((none, none, np.empty(0), np.empty((0, 2)), np.empty(0)))
    return out


_NO_POLYGON = np.zeros((0, 0), dtype=np.bool_)
_EMPTY = np.empty(0, dtype=np.intp)
#: a geometry's fields that leave only its user constraints
_NO_ITEMS: dict[str, Any] = {"halfplane_normal": np.empty((0, 2)), "halfplane_offset": np.empty(0),
             "halfplane_velocity": np.empty(0), "halfplane_index": _EMPTY,
             "segment_a": np.empty((0, 2)), "segment_b": np.empty((0, 2)),
             "segment_index": _EMPTY, "segment_polygon": _EMPTY, "segment_part": _EMPTY,
             "segment_kind": (), "segment_motion": _EMPTY,
             "circle_center": np.empty((0, 2)), "circle_radius": np.empty(0),
             "circle_index": _EMPTY, "circle_motion": _EMPTY}


def _segment_values(geom: Geometry, q: np.ndarray, a: np.ndarray, k: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distance (m) from centre a to segment k, the unit vector from the segment's nearest
    point to the centre, and that point, for each pair (a, k)."""
    ab = geom.segment_b[k] - geom.segment_a[k]
    rel = q[a] - geom.segment_a[k]
    s = np.clip(np.einsum("mc,mc->m", rel, ab) / np.einsum("mc,mc->m", ab, ab), 0.0, 1.0)
    foot = geom.segment_a[k] + s[:, None] * ab
    d = q[a] - foot
    dist = np.sqrt(np.einsum("mc,mc->m", d, d))
    return dist, d / np.maximum(dist, 1e-300)[:, None], foot
