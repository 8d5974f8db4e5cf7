"""numpy's order of summation, compiled: a compiled caller that replaces ``a.sum()`` keeps
numpy's bits (numpy sums a contiguous float64 vector pairwise, not in index order; the tests
compare the two on every length to 600 and on longer vectors)."""
from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def numpy_sum(a: np.ndarray) -> float:  # pragma: no cover - compiled
    """sum_k a_k of a (K,) vector in numpy's own order (``a.sum()``), so that a compiled
    caller keeps numpy's bits: pairwise, a block of more than 128 split in two halves (the
    first a multiple of 8 long) and the halves' sums added; a block of at most 128 summed by
    :func:`block_sum`. The recursion is walked with an explicit stack (numba's cache does not
    load recursive functions)."""
    n = a.shape[0]
    if n <= 128:
        return block_sum(a, 0, n)
    start = np.zeros(64, dtype=np.int64)  # 2^64 elements at most: 64 levels
    size = np.zeros(64, dtype=np.int64)
    left = np.zeros(64)
    has_left = np.zeros(64, dtype=np.bool_)
    depth = 0
    size[0] = n
    while True:
        while size[depth] > 128:  # down the left halves
            half = size[depth] // 2
            half -= half % 8
            start[depth + 1], size[depth + 1], has_left[depth + 1] = start[depth], half, False
            depth += 1
        v = block_sum(a, start[depth], size[depth])
        while True:  # up, adding each finished right half to its left half
            if depth == 0:
                return v
            up = depth - 1
            if not has_left[up]:
                left[up], has_left[up] = v, True
                half = size[up] // 2
                half -= half % 8
                start[depth], size[depth] = start[up] + half, size[up] - half
                has_left[depth] = False
                break  # then down the right half
            v = left[up] + v
            depth = up


@numba.njit(cache=True, nogil=True)
def block_sum(a: np.ndarray, lo: int, n: int) -> float:  # pragma: no cover - compiled
    """numpy's sum of a[lo: lo + n], n <= 128: in order when n < 8, else eight running sums
    of every eighth element (the last n % 8 left out) added as ((0 + 1) + (2 + 3)) + ((4 + 5)
    + (6 + 7)), then the rest in order."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r = a[lo: lo + 8].copy()
    i = 8
    while i < n - n % 8:
        for j in range(8):
            r[j] += a[lo + i + j]
        i += 8
    res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    for k in range(lo + i, lo + n):
        res += a[k]
    return res
