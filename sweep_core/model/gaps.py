"""The true constraint values' summary at (t, q) after a step (:func:`gaps`, :class:`Gaps`): the
smallest pair and wall/obstacle gaps, the contacts, the worst constraints and the (agent,
segment) pairs near each other for the crossing check (:mod:`sweep_core.model.crossing`).
Exact values (no linearisation), m; positions (N, 2). The compiled passes are
:func:`~sweep_core.model.wall_kernels.pair_gaps` and
:func:`~sweep_core.model.wall_kernels.single_gaps`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numba
import numpy as np
from scipy.spatial import cKDTree

from sweep_core.model.geometry import (
    DENSE_SEGMENTS,
    SEGMENT,
    Geometry,
    inside_polygons,
    single_rows,
)
from sweep_core.model.maps import map_from_spec
from sweep_core.model.neighbours import pairs_into, pairs_within
from sweep_core.model.wall_kernels import pair_gaps, single_gaps

if TYPE_CHECKING:  # the scene module reads this one
    from sweep_core.model.scene import Scene

#: largest true-constraint violation (m) ever accepted after a step
FEASIBILITY_TOLERANCE = 1e-9

_NO_POLYGON = np.zeros((0, 0), dtype=np.bool_)
_EMPTY = np.empty(0, dtype=np.intp)


@dataclass(frozen=True)
class Gaps:
    """True (non-linearised) constraint values at (t, q), m.

    min_pair, min_single: smallest gap (inf if none); contacts: number of constraints with
    gap <= contact_tol; worst_pair: (i, j, gap) or None; worst_single: (agent, kind, item, gap)
    or None. near_agent, near_segment: the (agent, segment) pairs whose value is within
    ``reach`` (m), the distance searched (for the crossing check of
    :mod:`sweep_core.model.crossing`).
    """

    min_pair: float
    min_single: float
    contacts: int
    worst_pair: tuple[int, int, float] | None
    worst_single: tuple[int, int, int, float] | None
    pair_i: np.ndarray
    pair_j: np.ndarray
    pair_gap: np.ndarray
    near_agent: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.intp))
    near_segment: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.intp))
    reach: float = 0.0

    @property
    def min_gap(self) -> float:
        """The smallest of the gaps searched: every gap at most ``contact_tol`` is (all that a
        step's check needs), so this is the smallest gap whenever it is at most that; above
        it, a pair farther apart than 2 max(r) + contact_tol may be smaller
        (:func:`smallest_gap` searches them)."""
        return min(self.min_pair, self.min_single)


def gaps(geom: Geometry, t: float, q: np.ndarray, r: np.ndarray,
         contact_tol: float = 1e-6) -> Gaps:
    """Evaluate every constraint that can be violated or touching at (t, q)."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    r = np.ascontiguousarray(r, dtype=np.float64)
    r_max = max(float(r.max()), 0.0) if len(r) else 0.0  # r.max(initial=0.0), NaN kept
    if 1 < len(q) <= SMALL:
        done = _small(geom, t, q, r, r_max, contact_tol)
        if done is not None:
            return done
    if len(q) > 1:
        i, j = pairs_within(q, 2.0 * r_max + contact_tol)
        pg = np.empty(len(i))
        contacts, w = pair_gaps(q, r, i, j, float(contact_tol), pg)
    else:  # one disk (a robot's target, say): no pair
        i, j, pg, contacts, w = _EMPTY, _EMPTY, np.empty(0), 0, -1
    worst_pair = None
    min_pair = np.inf
    if w >= 0:
        min_pair = float(pg[w])
        worst_pair = (int(i[w]), int(j[w]), min_pair)
    min_single, worst_single = np.inf, None
    reach, near = 0.0, (_EMPTY, _EMPTY)
    if not geom.is_empty and len(q):
        # the smallest value over all (agent, item): searched within a reach that grows
        # eightfold until something is found (what is not found is larger than what is)
        reach = max(contact_tol, 2.0 * r_max, 1e-3)
        here = geom.at(t)
        summary = None
        if not here.user and (len(here.segment_a) == 0
                              or len(q) * len(here.segment_a) <= DENSE_SEGMENTS):
            summary = _dense_gaps(here, t, q, r, contact_tol, reach)
        if summary is not None:
            reach, count, min_single, worst_single, near = summary
            contacts += count
        else:
            found = _found_rows(here, t, q, r, reach)
            reach = found[-1]
            near = found[SEGMENT][0], found[SEGMENT][1]
            for kind, (a, k, g) in enumerate(found[:-1]):
                if len(g) == 0:
                    continue
                contacts += int(np.count_nonzero(g <= contact_tol))
                w = int(np.argmin(g))
                if g[w] < min_single:
                    min_single = float(g[w])
                    worst_single = (int(a[w]), kind, int(k[w]), min_single)
    return Gaps(min_pair, min_single, contacts, worst_pair, worst_single, i, j, pg, near[0],
                near[1], reach)


def smallest_gap(g: Gaps, q: np.ndarray, r: np.ndarray, contact_tol: float = 1e-6
                 ) -> tuple[float, tuple[int, int] | None]:
    """The smallest true gap (m) at centres q (N, 2) with radii r (N,), whose :func:`gaps` (with
    the same ``contact_tol``) is ``g``, and the pair (i, j) that gives it (None: a wall or
    obstacle gives it, ``g.worst_single``, or nothing does). :func:`gaps` searches the pairs
    at most 2 max(r) + contact_tol apart, so a pair it left out has a gap above contact_tol:
    when ``g.min_gap`` is above that, the pairs that could be smaller are searched here
    (those closer than 2 max(r) plus it; with no gap found at all, plus the nearest centres'
    distance less 2 min(r), which bounds the smallest pair gap)."""
    best = g.min_gap
    pair = (g.worst_pair[0], g.worst_pair[1]) if (g.worst_pair is not None
                                                  and g.min_pair <= g.min_single) else None
    if not best > contact_tol or len(q) < 2:  # NaN kept
        return best, pair
    q = np.ascontiguousarray(q, dtype=np.float64)
    r = np.ascontiguousarray(r, dtype=np.float64)
    bound = best
    if not np.isfinite(bound):
        d = cKDTree(q).query(q, k=2)[0][:, 1]
        bound = float(d.min()) - 2.0 * float(r.min())
    i, j = pairs_within(q, 2.0 * float(r.max()) + max(bound, contact_tol))
    if len(i):
        pg = np.empty(len(i))
        _, w = pair_gaps(q, r, i, j, float(contact_tol), pg)
        if w >= 0 and pg[w] < best:
            return float(pg[w]), (int(i[w]), int(j[w]))
    return best, pair


class SmallestGap:
    """The smallest true gap (m) at centres q (N, 2) with radii r (N,): :func:`smallest_gap`
    of their :func:`gaps` g (inf without g), found when first asked (a simulator's step never
    needs it; its diagnostics and summaries do)."""

    def __init__(self, g: Gaps | None, q: np.ndarray, r: np.ndarray) -> None:
        self.g, self.q, self.r = g, q, r
        self.found: float | None = None if g is not None else math.inf

    def value(self) -> float:
        """The smallest gap (m), searched at the first call."""
        if self.found is None:
            assert self.g is not None
            self.found = smallest_gap(self.g, self.q, self.r)[0]
        return self.found


#: crowds of at most this many agents take :func:`_small`'s single compiled call
SMALL = 64


def _small(geom: Geometry, t: float, q: np.ndarray, r: np.ndarray, r_max: float,
           contact_tol: float) -> Gaps | None:
    """:func:`gaps` in one compiled call (:func:`small_gaps`: the neighbour search, the pairs'
    and the walls' passes, the same kernels in the same order, so the same values and the
    same summary) for a geometry without user constraints; None when that does not apply
    (user constraints, a NaN wall value, more pairs than 4 N) and the caller's path runs."""
    here = geom.at(t)
    n = len(q)
    if here.user or n * len(here.segment_a) > DENSE_SEGMENTS:
        return None
    hc = here.offsets(t)
    inside = inside_polygons(q, here) if here.has_polygons else _NO_POLYGON
    hn, _, sa, sb, cc, cr = here.packed
    walls = not geom.is_empty
    i, j, pg, vals, near_a, near_k, out = small_room(n, len(hc), len(sa), len(cr), walls)
    small_gaps(q, r, 2.0 * r_max + contact_tol, walls, hn, hc, sa, sb, inside, cc, cr,
               float(contact_tol), max(contact_tol, 2.0 * r_max, 1e-3), i, j, pg, vals,
               near_a, near_k, out)
    if out[6] > len(i) or out[3] == -2.0:
        return None
    return small_summary(i, j, pg, near_a, near_k, out, walls)


def small_room(n: int, halfplanes: int, segments: int, circles: int, walls: bool
               ) -> tuple[np.ndarray, ...]:
    """The arrays :func:`small_gaps` fills for n agents among that many half-planes,
    segments and circles (``walls``: the geometry is not empty): i, j, pg (room for 4 n
    pairs, as :func:`~sweep_core.model.neighbours.pairs_within` first makes), vals, near_a,
    near_k and out (12,)."""
    cap = 4 * n
    vals = np.empty(n * (halfplanes + segments + circles) if walls else 0)
    near_a = np.empty(n * segments if walls else 0, dtype=np.intp)
    return (np.empty(cap, dtype=np.intp), np.empty(cap, dtype=np.intp), np.empty(cap), vals,
            near_a, np.empty(len(near_a), dtype=np.intp), np.empty(12))


def small_summary(i: np.ndarray, j: np.ndarray, pg: np.ndarray, near_a: np.ndarray,
                  near_k: np.ndarray, out: np.ndarray, walls: bool) -> Gaps:
    """The :class:`Gaps` of what :func:`small_gaps` wrote into :func:`small_room`'s arrays
    (when it found no more pairs than i has room for and no NaN wall value)."""
    o = out.tolist()  # Python floats, each read once
    found, w, near = int(o[6]), int(o[8]), int(o[9])
    smallest = np.inf if w < 0 else float(pg[w])
    worst_pair = None if w < 0 else (int(i[w]), int(j[w]), smallest)
    worst_single = None
    if walls and o[3] >= 0:
        worst_single = (int(o[4]), int(o[3]), int(o[5]), o[2])
    return Gaps(smallest, o[2] if walls else np.inf,
                int(o[7]) + (int(o[1]) if walls else 0), worst_pair, worst_single,
                i[:found], j[:found], pg[:found], near_a[:near], near_k[:near],
                o[0] if walls else 0.0)


@numba.njit(cache=True, nogil=True)
def small_gaps(q: np.ndarray, r: np.ndarray, pair_reach: float, walls: bool, hn: np.ndarray,
               hc: np.ndarray, sa: np.ndarray, sb: np.ndarray, inside: np.ndarray,
               cc: np.ndarray, cr: np.ndarray, contact_tol: float, reach: float,
               i: np.ndarray, j: np.ndarray, pg: np.ndarray, vals: np.ndarray,
               near_a: np.ndarray, near_k: np.ndarray, out: np.ndarray
               ) -> None:  # pragma: no cover - compiled
    """:func:`gaps`' passes in one call for q (N, 2), r (N,), N >= 2: the pairs within
    ``pair_reach`` into i, j (room for their length), their gaps into pg
    (:func:`~sweep_core.model.wall_kernels.pair_gaps`), then, when ``walls``,
    :func:`~sweep_core.model.wall_kernels.single_gaps` with the wall arguments, vals,
    near_a, near_k and out[0:6]. out[6] the pairs found (more than len(i): nothing else
    done), out[7] the pairs' contacts, out[8] the first smallest pair (-1: none), out[9]
    single_gaps' count of near segment pairs (0 without walls)."""
    out[9] = 0.0
    out[3] = -1.0
    found = pairs_into(q, pair_reach, i, j)
    out[6] = found
    if found > i.shape[0]:
        return
    contacts, w = pair_gaps(q, r, i[:found], j[:found], contact_tol, pg[:found])
    out[7], out[8] = contacts, w
    if walls:
        out[9] = single_gaps(q, r, hn, hc, sa, sb, inside, cc, cr, contact_tol, reach, vals,
                             near_a, near_k, out)


def _dense_gaps(geom: Geometry, t: float, q: np.ndarray, r: np.ndarray, contact_tol: float,
                reach: float) -> tuple | None:
    """:func:`gaps`' wall and obstacle part, every value at once (compiled,
    :func:`~sweep_core.model.wall_kernels.single_gaps`): (reach, contacts, smallest value,
    worst_single, near segment pairs), or None when some value is NaN."""
    hc = geom.offsets(t)
    inside = inside_polygons(q, geom) if geom.has_polygons else _NO_POLYGON
    hn, _, sa, sb, cc, cr = geom.packed
    vals = np.empty(len(q) * (len(hc) + len(sa) + len(cr)))
    near_a = np.empty(len(q) * len(sa), dtype=np.intp)
    near_k = np.empty(len(q) * len(sa), dtype=np.intp)
    out = np.empty(6)
    found = single_gaps(q, r, hn, hc, sa, sb, inside, cc, cr, float(contact_tol), float(reach),
                        vals, near_a, near_k, out)
    if out[3] == -2.0:
        return None
    worst = None
    if out[3] >= 0:
        worst = (int(out[4]), int(out[3]), int(out[5]), float(out[2]))
    return (float(out[0]), int(out[1]), float(out[2]), worst,
            (near_a[:found], near_k[:found]))


def _found_rows(geom: Geometry, t: float, q: np.ndarray, r: np.ndarray, reach: float
                ) -> list:
    """For each kind the rows (agent, item, value) within the reach at which the eightfold
    growth from ``reach`` first finds one (the largest tried past 1e12 m), that reach last."""
    while True:
        rows = single_rows(geom, t, q, r, reach)
        if any(len(a) for a, _, _, _, _ in rows) or reach > 1e12:
            break
        reach *= 8.0
    return [(a, k, g) for a, k, g, _, _ in rows] + [reach]


def violating_agents(scene: Scene, t: float, q: np.ndarray) -> list[int]:
    """The agents (sorted indices) whose centres q (N, 2) violate a wall, obstacle or user
    constraint of ``scene`` at time t by more than FEASIBILITY_TOLERANCE (m), or lie in a
    blocked cell of its map (or outside the map's grid)."""
    q = np.asarray(q, dtype=np.float64)
    bad: set[int] = set()
    if len(q) and not scene.geometry.is_empty:
        for a, _, g, _, _ in single_rows(scene.geometry, t, q, scene.radii(t), 0.0):
            bad.update(int(i) for i in a[g < -FEASIBILITY_TOLERANCE])
    if len(q) and scene.spec.get("map") is not None:
        grid = map_from_spec(scene.spec["map"], "map", None)
        bad.update(int(i) for i in np.flatnonzero(grid.is_blocked(q)))
    return sorted(bad)
