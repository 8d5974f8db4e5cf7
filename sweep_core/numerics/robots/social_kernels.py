"""The robots' per-step compiled arithmetic: the social-force planner's people and wall terms
(:class:`.planners.SocialForce`), the tracker's matching, the walls within sensor range, and
the clearance and time to collision of a robot's episode record (``nearest_pass``, for
:func:`sweep_core.analysis.social.nearest`). Each operation is the one, in the order, the
numpy form took (numpy's ``hypot`` is the C library's, as numba's is; the exponentials and
the heading's product are taken outside, by :mod:`sweep_core.model.elementary` and written-out
products), so the commands and records keep their bits (test_guard and test_social_metrics
compare them)."""
from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def _maximum(x: float, y: float) -> float:  # pragma: no cover - compiled
    """numpy's maximum of two floats: a NaN propagates."""
    if x != x or x >= y:
        return x
    return y


@numba.njit(cache=True)
def people_terms(d: np.ndarray, y: np.ndarray, b: np.ndarray, grad: np.ndarray,
                 unit: np.ndarray) -> None:  # pragma: no cover - compiled
    """For each person j: d (M, 2) m from j to the robot, y (M, 2) m j's step relative to
    the robot; b (M,) m the elliptical distance sqrt((|d| + |d - y|)^2 - |y|^2) / 2 (its
    square at least 1e-18 m^2), grad (M, 2) its gradient in d, unit (M, 2) d / |d| (|d| and
    |d - y| at least 1e-9 m)."""
    for j in range(d.shape[0]):
        d0, d1 = d[j, 0], d[j, 1]
        dn = _maximum(np.hypot(d0, d1), 1e-9)
        e0, e1 = d0 - y[j, 0], d1 - y[j, 1]
        dyn = _maximum(np.hypot(e0, e1), 1e-9)
        yn = np.hypot(y[j, 0], y[j, 1])
        s = dn + dyn
        bj = 0.5 * math.sqrt(_maximum(s * s - yn * yn, 1e-18))
        b[j] = bj
        coef = s / (4.0 * _maximum(bj, 1e-9))
        grad[j, 0] = coef * (d0 / dn + e0 / dyn)
        grad[j, 1] = coef * (d1 / dn + e1 / dyn)
        unit[j, 0] = d0 / dn
        unit[j, 1] = d1 / dn


@numba.njit(cache=True)
def pushes(grad: np.ndarray, mag: np.ndarray, side: np.ndarray, out: np.ndarray
           ) -> None:  # pragma: no cover - compiled
    """out (2,) = sum_j mag_j (grad_j + side_j turn_j), turn_j = grad_j turned by +90
    degrees, summed over j in order (numpy's sum along the first axis)."""
    for j in range(grad.shape[0]):
        g0, g1 = grad[j, 0], grad[j, 1]
        p0 = mag[j] * (g0 + side[j] * -g1)
        p1 = mag[j] * (g1 + side[j] * g0)
        if j == 0:
            out[0], out[1] = p0, p1
        else:
            out[0] += p0
            out[1] += p1


@numba.njit(cache=True)
def _first_min(values: np.ndarray) -> int:  # pragma: no cover - compiled
    """numpy's argmin of a 1-D array: the first NaN, else the first smallest."""
    best = 0
    for k in range(len(values)):
        if values[best] != values[best]:
            return best
        if values[k] != values[k] or values[k] < values[best]:
            best = k
    return best


@numba.njit(cache=True)
def track(xy: np.ndarray, old: np.ndarray, old_v: np.ndarray, dt: float, a: float,
          gate2: float, v: np.ndarray) -> None:  # pragma: no cover - compiled
    """The tracker's update (:class:`.planners.Tracker`): person i of ``xy`` (M, 2) m takes
    the track j of ``old`` (M', 2) m nearest it when i is j's nearest too and the squared
    distance is at most gate2 m^2; then v[i] = old_v[j] + a ((xy_i - old_j) / dt - old_v[j])
    (m/s, dt s); v (M, 2) is left as given (zeros) elsewhere. Nearest by squared distance,
    the first of equals (numpy's argmin)."""
    m, n = xy.shape[0], old.shape[0]
    d2 = np.empty((m, n))
    for i in range(m):
        for j in range(n):
            dx = xy[i, 0] - old[j, 0]
            dy = xy[i, 1] - old[j, 1]
            d2[i, j] = dx * dx + dy * dy
    column = np.empty(m)
    for i in range(m):
        j = _first_min(d2[i])
        for k in range(m):
            column[k] = d2[k, j]
        if _first_min(column) != i or not d2[i, j] <= gate2:
            continue
        for c in range(2):
            step = (xy[i, c] - old[j, c]) / dt
            v[i, c] = old_v[j, c] + a * (step - old_v[j, c])


@numba.njit(cache=True)
def clip01(x: float) -> float:  # pragma: no cover - compiled
    """numpy's clip of x to [0, 1]: NaN kept, max then min by strict comparisons (so -0.0
    becomes 0.0, as numpy gives)."""
    if x == x:
        x = x if x > 0.0 else 0.0
        x = x if x < 1.0 else 1.0
    return x


@numba.njit(cache=True)
def near_segments(px: float, py: float, a: np.ndarray, b: np.ndarray, reach: float,
                  near: np.ndarray) -> None:  # pragma: no cover - compiled
    """near (S,) bool: segments [a, b] ((S, 2) m each) whose closest point to (px, py) lies
    within reach m (its parameter clip((p - a).e / max(|e|^2, 1e-300), 0, 1), e = b - a)."""
    for k in range(a.shape[0]):
        e0, e1 = b[k, 0] - a[k, 0], b[k, 1] - a[k, 1]
        ee = _maximum(e0 * e0 + e1 * e1, 1e-300)
        s = clip01(((px - a[k, 0]) * e0 + (py - a[k, 1]) * e1) / ee)
        near[k] = np.hypot((a[k, 0] + s * e0) - px, (a[k, 1] + s * e1) - py) <= reach


@numba.njit(cache=True)
def wall_offsets(ox: float, oy: float, a: np.ndarray, b: np.ndarray, rel: np.ndarray,
                 d: np.ndarray) -> None:  # pragma: no cover - compiled
    """rel (S, 2) m: from the nearest point of each segment [a, b] ((S, 2) m each) to (ox, oy);
    d (S,) m its length, at least 1e-9 m."""
    for k in range(a.shape[0]):
        e0, e1 = b[k, 0] - a[k, 0], b[k, 1] - a[k, 1]
        ee = _maximum(e0 * e0 + e1 * e1, 1e-300)
        s = clip01(((ox - a[k, 0]) * e0 + (oy - a[k, 1]) * e1) / ee)
        r0, r1 = ox - (a[k, 0] + s * e0), oy - (a[k, 1] + s * e1)
        rel[k, 0], rel[k, 1] = r0, r1
        d[k] = _maximum(np.hypot(r0, r1), 1e-9)


@numba.njit(cache=True)
def scaled_sum(mag: np.ndarray, rel: np.ndarray, d: np.ndarray
               ) -> np.ndarray:  # pragma: no cover - compiled
    """(2,) sum over k, in order, of mag_k rel_k / d_k (mag (S,), rel (S, 2), d (S,))."""
    out = np.zeros(2)
    for k in range(len(mag)):
        p0, p1 = mag[k] * rel[k, 0] / d[k], mag[k] * rel[k, 1] / d[k]
        if k == 0:
            out[0], out[1] = p0, p1
        else:
            out[0] += p0
            out[1] += p1
    return out


@numba.njit(cache=True)
def nearest_pass(x: float, y: float, vx: float, vy: float, radius: float,
                 people: np.ndarray, radii: np.ndarray, velocities: np.ndarray, out: np.ndarray
                 ) -> None:  # pragma: no cover - compiled
    """``analysis.social.nearest`` in one pass: out = (smallest clearance, smallest time to
    collision over the people of finite velocity, how many they are), m, s; each value
    computed as ``analysis.social``'s ``clearance`` and ``time_to_collision`` compute it
    (same operations, same order: the same bits), a NaN propagating to the minimum as
    numpy's does. (x, y) m and (vx, vy) m/s the robot's, people (N, 2) m, radii (N,) m,
    velocities (N, 2) m/s."""
    low_c, low_t, known = math.inf, math.inf, 0
    for j in range(people.shape[0]):
        c = np.hypot(x - people[j, 0], y - people[j, 1]) - radius - radii[j]
        if c != c or low_c != low_c:
            low_c = math.nan
        elif c < low_c:
            low_c = c
        wx, wy = velocities[j, 0], velocities[j, 1]
        if not (math.isfinite(wx) and math.isfinite(wy)):
            continue
        known += 1
        px, py = people[j, 0] - x, people[j, 1] - y
        ux, uy = wx - vx, wy - vy
        reach = radius + radii[j]
        pw = px * ux + py * uy
        ww = ux * ux + uy * uy
        cc = (px * px + py * py) - reach * reach
        disc = pw * pw - ww * cc
        tau = math.inf
        if pw < 0 and disc >= 0 and ww > 0:
            tau = cc / (-pw + math.sqrt(disc))
        if cc <= 0:
            tau = 0.0
        if tau != tau or low_t != low_t:
            low_t = math.nan
        elif tau < low_t:
            low_t = tau
    out[0], out[1], out[2] = low_c, low_t, known
