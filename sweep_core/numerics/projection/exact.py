"""An independent exact reference: the cluster QP as a least-distance program through scipy's
NNLS (Lawson-Hanson). The tests compare the solvers with it; the projection uses
:mod:`.active` (compiled, bounded, deterministic) instead."""
from __future__ import annotations

import numpy as np
from scipy.optimize import nnls


def ldp(target: np.ndarray, c: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
    """The same QP as a least-distance program solved exactly through NNLS.

    With x = y - target, min |x| s.t. c x >= h (h = b - c target) is solved by
    u = argmin_{u >= 0} |E u - f|, E = [c^T; h^T], f = (0, ..., 0, 1), residual r = E u - f:
    x = -r[:n] / r[n] and the multipliers are u / -r[n]; r = 0 means no feasible point
    (Lawson and Hanson, Solving Least Squares Problems, 1974, ch. 23). Active-set, so
    degenerate (non-unique) multipliers of dense jams do not slow it down.
    """
    n, m = c.shape[1], c.shape[0]
    h = b - c @ target
    # the problem is positively homogeneous in h: solve it for h / scale, whose largest entry
    # is 1, so NNLS's tolerances (relative to |f| = 1) are relative to the data
    scale = float(np.abs(h).max())
    if scale == 0.0:
        return target.copy(), np.zeros(m), True
    e = np.vstack([c.T, h[None, :] / scale])
    f = np.zeros(n + 1)
    f[-1] = 1.0
    u, _ = nnls(e, f, maxiter=max(50 * m, 1000))
    r = e @ u - f
    if not -r[n] > 1e-12:
        return target.copy(), np.zeros(m), False
    return target - scale * r[:n] / r[n], scale * u / -r[n], True


