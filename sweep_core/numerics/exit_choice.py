"""The exit choice's assignment (``flows.exit_choice``; the rule is in
:mod:`sweep_core.model.exit_choice`): a compiled pass over the agents in order of their least
walking time, and the wished velocities towards the chosen exits."""
from __future__ import annotations

import numba
import numpy as np

from sweep_core.model.exit_choice import ExitChoice


@numba.njit(cache=True, nogil=True)
def assign(walk: np.ndarray, capacity: np.ndarray) -> np.ndarray:
    """(N,) int: the exit of each agent. walk (N, K): walking times T_k / v_i (s); capacity
    (K,): each exit's flow (1/s). Agents are taken in order of their least walking time
    (stable: ties by row), each to the exit of least walk + assigned / capacity (ties: the
    lower index)."""
    n, k = walk.shape
    best = np.empty(n)
    for i in range(n):
        best[i] = walk[i].min()
    order = np.argsort(best, kind="mergesort")
    count = np.zeros(k)
    out = np.zeros(n, dtype=np.int64)
    for i in order:
        choice, least = 0, np.inf
        for e in range(k):
            t = walk[i, e] + count[e] / capacity[e]
            if t < least:
                choice, least = e, t
        out[i] = choice
        count[choice] += 1.0
    return out


def choose(c: ExitChoice, t: float, q: np.ndarray, speed: np.ndarray) -> np.ndarray:
    """(M,) int: the exit of agents at q (M, 2) m with preferred speeds ``speed`` (M,) m/s."""
    walk = np.stack([f.travel_distance(q, t) for f in c.fields], axis=1)  # type: ignore[attr-defined]
    walk = walk / np.maximum(speed, 1e-12)[:, None]
    walk[~np.isfinite(walk)] = np.inf
    return assign(np.ascontiguousarray(walk), c.capacity)


def towards(c: ExitChoice, t: float, q: np.ndarray, speed: np.ndarray) -> np.ndarray:
    """(M, 2) m/s: each agent's drift towards its chosen exit (the exit's field at q)."""
    exit_of = choose(c, t, q, speed)
    u = np.zeros_like(q)
    for k, f in enumerate(c.fields):
        sel = np.flatnonzero(exit_of == k)
        if len(sel):
            u[sel] = f(t, q[sel])
    return u
