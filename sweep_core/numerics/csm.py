"""The collision-free speed model's speed law (``flows.headway`` with ``law: csm``, the
default), after Tordeux, Chraibi and Seyfried (2016), on top of the projection.

Direction rule. Agent i's wished direction e0_i = U_i / |U_i| is turned away from its
neighbours,

    e_i = (e0_i + sum_j a exp((l_ij - d_ij) / D) n_ji) / |...|,

with d_ij the distance between the centres (m), l_ij = r_i + r_j, n_ji = (q_i - q_j) / d_ij
the unit vector from j to i, a the repulsion strength (dimensionless, relative to the unit
e0_i) and D its range (m). Terms below a e^(-CUT) are left out (``CUT``; the result does not
depend on how far the pair search reaches).

Speed rule. s_i = min over the agents j ahead (<q_j - q_i, e_i> >= 0) whose centre is within
k l_ij of i's line of motion (|<q_j - q_i, e_i^perp>| <= k l_ij) of d_ij - l_ij, the gap to
the nearest one in the direction of motion (infinite if none);

    U_i -> min(|U_i|, max(0, s_i / T)) e_i,

T the time gap (s), k in (0, 1] the lateral fraction (``lateral``; k = 1 is the published
law: every neighbour whose disk overlaps i's path is ahead). With k < 1 a neighbour offset
sideways by more than k l_ij does not slow i: the two pass each other staggered, as people
do in the overlapping lanes of a bottleneck (the zipper effect, Hoogendoorn and Daamen 2005:
lanes about 0.45 m apart for a body about 0.55 m wide), and the projection keeps their
contact exact if they touch. Walls enter the direction rule only with the option
``wall_repulsion`` a_w > 0 (below) and never the speed rule: the projection keeps every
contact (agents and walls) exact, so the law only changes the prediction. Agents with U_i = 0 are
left alone. With a = 0 the direction is e0_i and only the speed falls.

Options (docs/flows.md), each neutral at its default: ``follow`` beta in [0, 1) adds beta
times the speed the rule gives i's leader j (the agent setting s_i), along e_i when positive,
to s_i / T (min(|U_i|, max(0, s_i / T + beta p_i)); a uniform single file then moves as with
the time gap T / (1 + beta)); ``length`` f in (0, 1] takes d_ij - f l_ij as the gap;
``fade`` k2 in [k, 1] lets a neighbour between k l_ij and k2 l_ij count with its gap divided
by a cosine weight falling from 1 to 0; ``wall_repulsion`` a_w >= 0 with ``wall_range``
D_w (m) adds the published model's wall term to the direction rule's sum,
sum_w a_w exp(-g_iw / D_w) n_iw over the walls and obstacles w (g_iw the gap from i's disk
to w, n_iw the unit normal pointing away from w; :func:`wall_terms`).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from sweep_core.model import elementary
from sweep_core.model.elementary import cos, exp
from sweep_core.model.neighbours import SizedSearch, pairs_into

#: repulsion terms with exponent (l - d) / D below -CUT are left out (a e^-CUT, a 1e-4 of a)
CUT = 9.2
@numba.njit(cache=True, nogil=True)
def directions(q: np.ndarray, r: np.ndarray, u: np.ndarray, pi: np.ndarray, pj: np.ndarray,
               strength: float, reach: float, walls: np.ndarray) -> np.ndarray:
    """Unit directions e_i (N, 2) of the direction rule (module docstring) for centres q
    (N, 2) m, radii r (N,) m, wished velocities u (N, 2) m/s over the candidate pairs
    (pi, pj), with the walls' terms ``walls`` (N, 2) added to the sum of each moving agent
    (:func:`wall_terms`; an empty (0, 2) array: none); rows of zeros where u_i = 0 or the sum
    vanishes."""
    n = q.shape[0]
    out = np.zeros((n, 2))
    moving = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        speed = math.sqrt(u[i, 0] * u[i, 0] + u[i, 1] * u[i, 1])
        if speed > 0.0:
            moving[i] = True
            out[i, 0] = u[i, 0] / speed
            out[i, 1] = u[i, 1] / speed
    if strength > 0.0 or walls.shape[0] > 0:
        for k in range(pi.shape[0] if strength > 0.0 else 0):
            i, j = pi[k], pj[k]
            dx, dy = q[i, 0] - q[j, 0], q[i, 1] - q[j, 1]
            d = math.sqrt(dx * dx + dy * dy)
            x = (r[i] + r[j] - d) / reach
            if d == 0.0 or x < -CUT:
                continue
            f = strength * exp(x) / d
            if moving[i]:
                out[i, 0] += f * dx
                out[i, 1] += f * dy
            if moving[j]:
                out[j, 0] -= f * dx
                out[j, 1] -= f * dy
        for i in range(walls.shape[0]):
            if moving[i]:
                out[i, 0] += walls[i, 0]
                out[i, 1] += walls[i, 1]
        for i in range(n):
            m = math.sqrt(out[i, 0] * out[i, 0] + out[i, 1] * out[i, 1])
            if m > 0.0:
                out[i, 0] /= m
                out[i, 1] /= m
    return out


def wall_terms(rows: list, n: int, strength: float, reach: float) -> np.ndarray:
    """The walls' terms of the direction rule, sum_w a_w exp(-g_iw / D_w) n_iw (N, 2), over
    the (agent, item, g, n, foot) rows of :func:`sweep_core.model.geometry.single_rows`
    (g_iw the gap m from agent i's disk to wall or obstacle w, n_iw the unit normal pointing
    away from it) with strength a_w and range D_w (m); rows with g_iw > CUT D_w add less
    than a_w e^-CUT and are left out (ask single_rows for the reach CUT D_w)."""
    out = np.zeros((n, 2))
    for a, _, g, nrm, _ in rows:
        if len(a):
            w = strength * elementary.exp_of(-np.asarray(g) / reach)
            np.add.at(out, a, w[:, None] * nrm)
    return out


def gaps_ahead(q: np.ndarray, r: np.ndarray, e: np.ndarray, pi: np.ndarray,
               pj: np.ndarray, lateral: float = 1.0, fade: float = -1.0,
               length: float = 1.0) -> np.ndarray:
    """s_i (N,) m: the gap d_ij - f l_ij to the nearest agent ahead of i in its corridor of
    half-width k l_ij along e_i (N, 2), k = ``lateral`` in (0, 1], f = ``length`` in (0, 1]
    (module docstring); with a ``fade`` k2 > k a neighbour at a lateral offset b between
    k l_ij and k2 l_ij counts with its positive gap divided by the weight
    (1 + cos(pi (b - k l_ij) / ((k2 - k) l_ij))) / 2 (1 at k l_ij, 0 at k2 l_ij); inf where
    there is none. fade <= k (the default -1) is the sharp corridor of half-width k l_ij."""
    return nearest_ahead(q, r, e, pi, pj, lateral, fade, length)[0]


@numba.njit(cache=True, nogil=True)
def nearest_ahead(q: np.ndarray, r: np.ndarray, e: np.ndarray, pi: np.ndarray,
                  pj: np.ndarray, lateral: float, fade: float,
                  length: float) -> tuple[np.ndarray, np.ndarray]:
    """The gaps s_i (N,) m of :func:`gaps_ahead` and the index (N,) of the agent giving each
    (-1 where there is none)."""
    n = q.shape[0]
    out = np.full(n, np.inf)
    lead = np.full(n, -1, dtype=np.int64)
    outer = max(fade, lateral)
    for k in range(pi.shape[0]):
        for side in range(2):
            i = pi[k] if side == 0 else pj[k]
            j = pj[k] if side == 0 else pi[k]
            ex, ey = e[i, 0], e[i, 1]
            if ex == 0.0 and ey == 0.0:
                continue
            dx, dy = q[j, 0] - q[i, 0], q[j, 1] - q[i, 1]
            if dx * ex + dy * ey < 0.0:
                continue
            ll = r[i] + r[j]
            b = abs(dy * ex - dx * ey)
            if b > outer * ll:
                continue
            s = math.sqrt(dx * dx + dy * dy) - (ll if length == 1.0 else length * ll)
            if b > lateral * ll:  # only with a fade: the partial band
                if b >= outer * ll:
                    continue
                w = 0.5 * (1.0 + cos(math.pi * (b - lateral * ll) /
                                     ((outer - lateral) * ll)))
                if w <= 0.0:  # at k2 l_ij up to rounding: does not count
                    continue
                if s > 0.0:
                    s = s / w
            if s < out[i]:
                out[i] = s
                lead[i] = j
    return out, lead


@numba.njit(cache=True, nogil=True)
def speeds(u: np.ndarray, e: np.ndarray, s: np.ndarray, time_gap: float, push: np.ndarray
           ) -> np.ndarray:
    """min(|u_i|, max(0, s_i / T + push_i)) e_i (N, 2) m/s; push (N,) m/s is 0 for the speed
    rule alone, the leader's share for ``follow`` (:func:`leader_push`)."""
    out = np.zeros_like(u)
    for i in range(u.shape[0]):
        speed = math.sqrt(u[i, 0] * u[i, 0] + u[i, 1] * u[i, 1])
        if speed == 0.0:
            continue
        v = min(speed, max(0.0, s[i] / time_gap + push[i]))
        out[i, 0] = v * e[i, 0]
        out[i, 1] = v * e[i, 1]
    return out


@numba.njit(cache=True, nogil=True)
def leader_push(v: np.ndarray, e: np.ndarray, lead: np.ndarray, beta: float) -> np.ndarray:
    """The follow rule's push beta p_i (N,) m/s, p_i = max(0, <v_j, e_i>) the speed v (N, 2)
    m/s of the speed rule alone gives the agent j that sets i's gap (``lead``), along i's
    direction: a leader walking away lets i close up by beta of its speed; one coming towards
    i or standing adds nothing."""
    out = np.zeros(v.shape[0])
    for i in range(v.shape[0]):
        j = lead[i]
        if j >= 0:
            out[i] = beta * max(0.0, v[j, 0] * e[i, 0] + v[j, 1] * e[i, 1])
    return out


#: the room the speed law's pair search makes first (its reach holds many more pairs than 4
#: per agent): the last search's count and a quarter more, a hint only (the compiled search
#: runs again when more are found)
_SEARCH = SizedSearch()


def csm(q: np.ndarray, r: np.ndarray, u: np.ndarray, time_gap: float, strength: float,
        reach: float, lateral: float = 1.0, fade: float = -1.0,
        length: float = 1.0, beta: float = 0.0, walls: np.ndarray | None = None
        ) -> np.ndarray:
    """The wished velocities u (N, 2) m/s under the collision-free speed model's law with time
    gap T (s), repulsion strength a and range D (m), lateral fraction k, its fade k2 and the
    body length's fraction f (``gaps_ahead``) and the follow weight beta (0: the
    speed rule alone: :func:`leader_push`), for centres q
    (N, 2) m and radii r (N,) m; ``walls`` (N, 2) the walls' terms of the direction rule
    (:func:`wall_terms`; None: none). The pairs are searched (compiled cell lists) within
    max|u| T + 2 max r, and within 2 max r + CUT D when a > 0: no pair farther apart enters
    either rule."""
    n = len(q)
    if n == 0 or (n < 2 and walls is None):
        return u.copy()
    q = np.ascontiguousarray(q, dtype=np.float64)
    r = np.ascontiguousarray(r, dtype=np.float64)
    u = np.ascontiguousarray(u, dtype=np.float64)
    w = _NO_WALLS if walls is None else np.ascontiguousarray(walls, dtype=np.float64)
    v, found = searched_law(q, r, u, float(time_gap), float(strength), float(reach), w,
                            float(lateral), float(fade), float(length), float(beta),
                            max(4 * n, _SEARCH.expect))
    _SEARCH.expect = found + found // 4
    return v


_NO_WALLS = np.zeros((0, 2))


@numba.njit(cache=True, nogil=True)
def searched_law(q: np.ndarray, r: np.ndarray, u: np.ndarray, time_gap: float,
                 strength: float, reach: float, walls: np.ndarray, lateral: float, fade: float,
                 length: float, beta: float, room: int
                 ) -> tuple[np.ndarray, int]:  # pragma: no cover - compiled
    """:func:`csm`'s search and rules for N >= 1 agents in one call: the search's reach from
    the largest wished speed, the pairs (``pairs_into``, with room for ``room`` pairs first,
    searched again with room for all when more are found: the pairs do not depend on it), then
    :func:`law`. The velocities (N, 2) m/s and the pairs found (0 when no one wishes to move:
    then u itself, copied)."""
    # the largest |u_i| is the square root of the largest square (sqrt is monotone and
    # correctly rounded); 2 max r
    square, rmax = largest_square(u, r)
    top = math.sqrt(square)
    if top == 0.0:
        return u.copy(), 0
    far = max(top * time_gap, CUT * reach if strength > 0.0 else 0.0)
    i, j, found = _pairs(q, rmax + far, room)
    return law(q, r, u, i, j, strength, reach, walls, lateral, fade, length, time_gap,
               beta), found


@numba.njit(cache=True, nogil=True)
def _pairs(q: np.ndarray, reach: float, room: int
           ) -> tuple[np.ndarray, np.ndarray, int]:  # pragma: no cover - compiled
    """``pairs_within``'s pairs (i, j) of q (N, 2) at most ``reach`` m apart, searched with
    room for ``room`` pairs first; and how many were found."""
    if q.shape[0] < 2:
        none = np.empty(0, dtype=np.intp)
        return none, none, 0
    while True:
        i = np.empty(room, dtype=np.intp)
        j = np.empty(room, dtype=np.intp)
        found = pairs_into(q, reach, i, j)
        if found <= room:
            return i[:found], j[:found], found
        room = found


@numba.njit(cache=True, nogil=True)
def largest_square(u: np.ndarray, r: np.ndarray) -> tuple[float, float]:  # pragma: no cover
    """The largest |u_i|^2 (the sum x then y, as ``einsum("ij,ij->i")``; NaN as soon as one
    is, as numpy's max) and 2 max r_i (m) of (N,) >= 1 values."""
    square = u[0, 0] * u[0, 0] + u[0, 1] * u[0, 1]
    for i in range(1, u.shape[0]):
        v = u[i, 0] * u[i, 0] + u[i, 1] * u[i, 1]
        if v > square or v != v:
            square = v if square == square else square
    top = r[0]
    for i in range(1, r.shape[0]):
        if r[i] > top or r[i] != r[i]:
            top = r[i] if top == top else top
    return square, 2.0 * top


@numba.njit(cache=True, nogil=True)
def law(q: np.ndarray, r: np.ndarray, u: np.ndarray, pi: np.ndarray, pj: np.ndarray,
        strength: float, reach: float, walls: np.ndarray, lateral: float, fade: float,
        length: float, time_gap: float, beta: float) -> np.ndarray:  # pragma: no cover
    """:func:`csm`'s rules over the candidate pairs (pi, pj): :func:`directions`,
    :func:`nearest_ahead`, :func:`speeds` and, when beta > 0, :func:`leader_push`, in one
    call."""
    e = directions(q, r, u, pi, pj, strength, reach, walls)
    s, lead = nearest_ahead(q, r, e, pi, pj, lateral, fade, length)
    v = speeds(u, e, s, time_gap, np.zeros(q.shape[0]))
    if beta == 0.0:
        return v
    return speeds(u, e, s, time_gap, leader_push(v, e, lead, beta))
