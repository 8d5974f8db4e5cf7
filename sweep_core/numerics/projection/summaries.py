"""Two summaries a projection takes of its arrays, compiled with numpy's bits: the largest
step and the rows' residuals (shared by :mod:`.project`, :mod:`.small` and the robots' clear
step)."""
from __future__ import annotations

import numba
import numpy as np

from sweep_core.numerics.projection import dual
from sweep_core.numerics.projection.options import ROW_TOLERANCE


@numba.njit(cache=True, nogil=True)
def largest_step(q: np.ndarray, pred: np.ndarray, r: np.ndarray
                 ) -> tuple[float, float]:  # pragma: no cover - compiled
    """The largest |p_i - q_i|^2 (m^2; the sum x then y, as ``einsum("ij,ij->i")``) and the
    largest r_i (m), each NaN as soon as one value is (as numpy's max)."""
    square = 0.0 if len(q) else np.nan
    for i in range(len(q)):
        dx, dy = pred[i, 0] - q[i, 0], pred[i, 1] - q[i, 1]
        square = dual.maximum(square, dx * dx + dy * dy)
    r_max = r[0] if len(r) else np.nan
    for i in range(1, len(r)):
        r_max = dual.maximum(r_max, r[i])
    return square, r_max


@numba.njit(cache=True, nogil=True)
def row_summary(rp: np.ndarray, rs: np.ndarray) -> tuple[float, int, bool]:  # pragma: no cover
    """Of the residuals rp (P,) and rs (M,) (m): the worst, Python's ``min`` of numpy's
    ``rp.min(initial=inf)`` and ``rs.min(initial=inf)`` (each NaN from a NaN on; the second
    only when it is below the first); the rows holding with equality (residual <=
    ROW_TOLERANCE); and whether a row is broken as numpy's ``rp.min() < 0 or rs.min() < 0``
    says it (a NaN in an array hides its negative values: its min is NaN)."""
    low_p, low_s = np.inf, np.inf
    active = 0
    for k in range(rp.shape[0]):
        low_p = dual.minimum(low_p, rp[k])
        active += rp[k] <= ROW_TOLERANCE
    for k in range(rs.shape[0]):
        low_s = dual.minimum(low_s, rs[k])
        active += rs[k] <= ROW_TOLERANCE
    return (low_s if low_s < low_p else low_p), active, low_p < 0.0 or low_s < 0.0
