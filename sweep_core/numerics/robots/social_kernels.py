"""Compiled parts of the social-force planner's people term (:class:`.planners.SocialForce`):
the elliptical distances and their gradients, and the weighted sum of the pushes. Each
operation is the one, in the order, the numpy form took (numpy's ``hypot`` is the C
library's, as numba's is; the exponentials and the heading's product stay numpy's), so the
planner's commands keep their bits (test_guard compares them)."""
from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def people_terms(d: np.ndarray, y: np.ndarray, b: np.ndarray, grad: np.ndarray,
                 unit: np.ndarray) -> None:  # pragma: no cover - compiled
    """For each person j: d (M, 2) m from j to the robot, y (M, 2) m j's step relative to
    the robot; b (M,) m the elliptical distance sqrt((|d| + |d - y|)^2 - |y|^2) / 2 (its
    square at least 1e-18 m^2), grad (M, 2) its gradient in d, unit (M, 2) d / |d| (|d| and
    |d - y| at least 1e-9 m)."""
    for j in range(d.shape[0]):
        d0, d1 = d[j, 0], d[j, 1]
        dn = max(np.hypot(d0, d1), 1e-9)
        e0, e1 = d0 - y[j, 0], d1 - y[j, 1]
        dyn = max(np.hypot(e0, e1), 1e-9)
        yn = np.hypot(y[j, 0], y[j, 1])
        s = dn + dyn
        bj = 0.5 * math.sqrt(max(s * s - yn * yn, 1e-18))
        b[j] = bj
        coef = s / (4.0 * max(bj, 1e-9))
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
