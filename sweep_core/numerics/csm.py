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
contact exact if they touch. Walls do not enter either rule: the projection keeps every contact
(agents and walls) exact, so the law only changes the prediction. Agents with U_i = 0 are
left alone. With a = 0 the direction is e0_i and only the speed falls.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from sweep_core.model.neighbours import pairs_within

#: repulsion terms with exponent (l - d) / D below -CUT are left out (a e^-CUT, a 1e-4 of a)
CUT = 9.2


@numba.njit(cache=True, nogil=True)
def directions(q: np.ndarray, r: np.ndarray, u: np.ndarray, pi: np.ndarray, pj: np.ndarray,
               strength: float, reach: float) -> np.ndarray:
    """Unit directions e_i (N, 2) of the direction rule (module docstring) for centres q
    (N, 2) m, radii r (N,) m, wished velocities u (N, 2) m/s over the candidate pairs
    (pi, pj); rows of zeros where u_i = 0 or the sum vanishes."""
    n = q.shape[0]
    out = np.zeros((n, 2))
    moving = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        speed = math.sqrt(u[i, 0] * u[i, 0] + u[i, 1] * u[i, 1])
        if speed > 0.0:
            moving[i] = True
            out[i, 0] = u[i, 0] / speed
            out[i, 1] = u[i, 1] / speed
    if strength > 0.0:
        for k in range(pi.shape[0]):
            i, j = pi[k], pj[k]
            dx, dy = q[i, 0] - q[j, 0], q[i, 1] - q[j, 1]
            d = math.sqrt(dx * dx + dy * dy)
            x = (r[i] + r[j] - d) / reach
            if d == 0.0 or x < -CUT:
                continue
            f = strength * math.exp(x) / d
            if moving[i]:
                out[i, 0] += f * dx
                out[i, 1] += f * dy
            if moving[j]:
                out[j, 0] -= f * dx
                out[j, 1] -= f * dy
        for i in range(n):
            m = math.sqrt(out[i, 0] * out[i, 0] + out[i, 1] * out[i, 1])
            if m > 0.0:
                out[i, 0] /= m
                out[i, 1] /= m
    return out


@numba.njit(cache=True, nogil=True)
def gaps_ahead(q: np.ndarray, r: np.ndarray, e: np.ndarray, pi: np.ndarray,
               pj: np.ndarray, lateral: float = 1.0) -> np.ndarray:
    """s_i (N,) m: the gap d_ij - l_ij to the nearest agent ahead of i in its corridor of
    half-width k l_ij along e_i (N, 2), k = ``lateral`` in (0, 1] (module docstring); inf
    where there is none."""
    n = q.shape[0]
    out = np.full(n, np.inf)
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
            if abs(dy * ex - dx * ey) > lateral * ll:
                continue
            s = math.sqrt(dx * dx + dy * dy) - ll
            if s < out[i]:
                out[i] = s
    return out


@numba.njit(cache=True, nogil=True)
def speeds(u: np.ndarray, e: np.ndarray, s: np.ndarray, time_gap: float) -> np.ndarray:
    """min(|u_i|, max(0, s_i / T)) e_i (N, 2) m/s."""
    out = np.zeros_like(u)
    for i in range(u.shape[0]):
        speed = math.sqrt(u[i, 0] * u[i, 0] + u[i, 1] * u[i, 1])
        if speed == 0.0:
            continue
        v = min(speed, max(0.0, s[i] / time_gap))
        out[i, 0] = v * e[i, 0]
        out[i, 1] = v * e[i, 1]
    return out


def csm(q: np.ndarray, r: np.ndarray, u: np.ndarray, time_gap: float, strength: float,
        reach: float, lateral: float = 1.0) -> np.ndarray:
    """The wished velocities u (N, 2) m/s under the collision-free speed model's law with time
    gap T (s), repulsion strength a and range D (m) and lateral fraction k, for centres q
    (N, 2) m and radii r (N,) m. The pairs are searched (compiled cell lists) within
    max|u| T + 2 max r, and within 2 max r + CUT D when a > 0: no pair farther apart enters
    either rule."""
    n = len(q)
    if n < 2:
        return u.copy()
    top = float(np.sqrt(np.max(np.einsum("ij,ij->i", u, u))))
    if top == 0.0:
        return u.copy()
    rmax = 2.0 * float(r.max())
    far = max(top * time_gap, CUT * reach if strength > 0.0 else 0.0)
    pi, pj = pairs_within(q, rmax + far)
    q = np.ascontiguousarray(q)
    r = np.ascontiguousarray(r, dtype=np.float64)
    u = np.ascontiguousarray(u)
    e = directions(q, r, u, pi, pj, float(strength), float(reach))
    return speeds(u, e, gaps_ahead(q, r, e, pi, pj, float(lateral)), float(time_gap))
