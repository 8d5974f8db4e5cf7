"""Warm starts across steps: the previous step's multipliers carried to this step's rows by
contact (the pair (i, j), or the agent and the wall or obstacle it touches)."""
from __future__ import annotations

import numba
import numpy as np

from sweep_core.numerics.constraints import Rows


def contact_keys(rows: Rows, n: int) -> np.ndarray:
    """One int64 key per row, pair rows first (as :meth:`Rows.displacement_rows`): i n + j >= 0
    for the pair (i < j), and a negative key from the agent, the kind and the index of the wall
    or obstacle for a single row (compiled: :func:`row_keys`). n: number of agents."""
    out = np.empty(rows.count, dtype=np.int64)
    row_keys(rows.pair_i, rows.pair_j, rows.single_a, rows.single_kind, rows.single_item, n,
             out)
    return out


def carry_multipliers(old: Rows, lam: np.ndarray, new: Rows, n: int) -> np.ndarray:
    """Multipliers (K,) for the rows ``new``: the previous step's (``old`` with ``lam``, in the
    same row order) where the same contact had a row, 0 elsewhere. n: number of agents."""
    if len(lam) == 0 or new.count == 0:
        return np.zeros(new.count)
    return carried(contact_keys(old, n), np.ascontiguousarray(lam, dtype=np.float64),
                   contact_keys(new, n))


@numba.njit(cache=True, nogil=True)
def row_keys(pi: np.ndarray, pj: np.ndarray, sa: np.ndarray, kind: np.ndarray,
             item: np.ndarray, n: int, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """:func:`contact_keys` into out (K,) int64."""
    m = len(pi)
    for k in range(m):
        out[k] = np.int64(pi[k]) * n + np.int64(pj[k])
    for k in range(len(sa)):
        out[m + k] = -1 - ((np.int64(sa[k]) << 26) | (np.int64(kind[k]) << 23)
                           | np.int64(item[k]))


@numba.njit(cache=True, nogil=True)
def carried(old_keys: np.ndarray, lam: np.ndarray, new_keys: np.ndarray
            ) -> np.ndarray:  # pragma: no cover - compiled
    """For each new key the multiplier of the first old row (in row order) with that key,
    else 0: the old keys sorted stably, each new one found by bisection."""
    order = np.argsort(old_keys, kind="mergesort")
    ko = old_keys[order]
    out = np.zeros(len(new_keys))
    for k in range(len(new_keys)):
        pos = min(np.searchsorted(ko, new_keys[k]), len(ko) - 1)
        if ko[pos] == new_keys[k]:
            out[k] = lam[order[pos]]
    return out
