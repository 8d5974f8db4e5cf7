"""Warm starts across steps: the previous step's multipliers carried to this step's rows by
contact (the pair (i, j), or the agent and the wall or obstacle it touches)."""
from __future__ import annotations

import numpy as np

from sweep_core.numerics.constraints import Rows


def contact_keys(rows: Rows, n: int) -> np.ndarray:
    """One int64 key per row, pair rows first (as :meth:`Rows.displacement_rows`): i n + j >= 0
    for the pair (i < j), and a negative key from the agent, the kind and the index of the wall
    or obstacle for a single row. n: number of agents."""
    pairs = rows.pair_i.astype(np.int64) * n + rows.pair_j.astype(np.int64)
    singles = -1 - ((rows.single_a.astype(np.int64) << 26)
                    | (rows.single_kind.astype(np.int64) << 23)
                    | rows.single_item.astype(np.int64))
    return np.concatenate([pairs, singles])


def carry_multipliers(old: Rows, lam: np.ndarray, new: Rows, n: int) -> np.ndarray:
    """Multipliers (K,) for the rows ``new``: the previous step's (``old`` with ``lam``, in the
    same row order) where the same contact had a row, 0 elsewhere. n: number of agents."""
    new_keys = contact_keys(new, n)
    if len(lam) == 0 or len(new_keys) == 0:
        return np.zeros(len(new_keys))
    old_keys = contact_keys(old, n)
    order = np.argsort(old_keys, kind="stable")
    ko, lo = old_keys[order], lam[order]
    pos = np.minimum(np.searchsorted(ko, new_keys), len(ko) - 1)
    return np.where(ko[pos] == new_keys, lo[pos], 0.0)
