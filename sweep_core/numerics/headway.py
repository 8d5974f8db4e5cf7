"""The headway speed law (optional, ``flows.headway``), after Tordeux, Chraibi and Seyfried's
collision-free speed model (2016): an agent's wished speed falls with the free distance ahead,

    |U_i| -> min(|U_i|, max(0, s_i / T)),

T the time gap (s) and s_i the free distance (m): how far agent i can move along its wished
direction e_i = U_i / |U_i| before its disk touches another agent's. For an agent j with
d = q_j - q_i, a = <d, e_i> > 0 (ahead) and lateral offset b = |d - a e_i| < l = r_i + r_j (in
i's path), that distance is a - sqrt(l^2 - b^2): for a person straight ahead (b = 0) it is the
model's s - l, centre distance minus the sum of the radii. A person beside the path, within a
lateral margin w (l <= b < l + w), counts with s = a (continuous at b = l): people keep a
lateral distance, and without it agents in lanes would not feel the crowd beside them.
s_i is the minimum over such j (infinite if none). Walls do not enter s_i; the projection
keeps every contact exact as always, so the law only lowers the prediction's speed. Agents
with U_i = 0 are left alone.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from sweep_core.model.neighbours import SizedSearch


@numba.njit(cache=True, nogil=True)
def free_distances(q: np.ndarray, r: np.ndarray, u: np.ndarray, pi: np.ndarray,
                   pj: np.ndarray, margin: float) -> np.ndarray:
    """Free distance s_i (N,) m ahead of each agent along u_i (N, 2) with lateral margin w
    (m) (module docstring), over the candidate pairs (pi, pj); inf where nobody is ahead."""
    n = q.shape[0]
    out = np.full(n, np.inf)
    for k in range(pi.shape[0]):
        for side in range(2):
            i = pi[k] if side == 0 else pj[k]
            j = pj[k] if side == 0 else pi[k]
            ux, uy = u[i, 0], u[i, 1]
            speed = math.sqrt(ux * ux + uy * uy)
            if speed == 0.0:
                continue
            dx, dy = q[j, 0] - q[i, 0], q[j, 1] - q[i, 1]
            a = (dx * ux + dy * uy) / speed
            if a <= 0.0:
                continue
            ll = r[i] + r[j]
            b2 = max(dx * dx + dy * dy - a * a, 0.0)
            if b2 >= (ll + margin) * (ll + margin):
                continue
            s = max(a - math.sqrt(ll * ll - b2), 0.0) if b2 < ll * ll else a
            if s < out[i]:
                out[i] = s
    return out


@numba.njit(cache=True, nogil=True)
def slow_down(u: np.ndarray, s: np.ndarray, time_gap: float) -> np.ndarray:
    """U_i scaled to the speed min(|U_i|, max(0, s_i / T)) (N, 2) m/s."""
    out = u.copy()
    for i in range(u.shape[0]):
        speed = math.sqrt(u[i, 0] * u[i, 0] + u[i, 1] * u[i, 1])
        if speed == 0.0:
            continue
        v = min(speed, max(0.0, s[i] / time_gap))
        if v < speed:
            f = v / speed
            out[i, 0] = u[i, 0] * f
            out[i, 1] = u[i, 1] * f
    return out


#: the headway law's pair search (its reach holds many more pairs than 4 per agent)
_SEARCH = SizedSearch()


def headway(q: np.ndarray, r: np.ndarray, u: np.ndarray, time_gap: float,
            margin: float = 0.0) -> np.ndarray:
    """The wished velocities u (N, 2) m/s under the headway law with time gap T (s) and
    lateral margin w (m), for centres q (N, 2) m and radii r (N,) m. Only agents closer than
    max|u| T + 2 max r + w can slow one another, so the pairs are searched within that reach
    (compiled cell lists)."""
    n = len(q)
    if n < 2:
        return u.copy()
    top = float(np.sqrt(np.max(np.einsum("ij,ij->i", u, u))))
    if top == 0.0:
        return u.copy()
    reach = top * time_gap + 2.0 * float(r.max()) + margin
    pi, pj = _SEARCH(q, reach)
    s = free_distances(np.ascontiguousarray(q), np.ascontiguousarray(r, dtype=np.float64),
                       np.ascontiguousarray(u), pi, pj, float(margin))
    return slow_down(np.ascontiguousarray(u), s, float(time_gap))
