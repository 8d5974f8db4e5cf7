"""The proxsuite backend (sparse proxqp) for one cluster QP."""
from __future__ import annotations

import numpy as np
import proxsuite
import scipy.sparse as sp

from sweep_core.numerics.projection.options import SolverOptions


def solve_proxsuite(target: np.ndarray, c: sp.csc_matrix, b: np.ndarray, opts: SolverOptions
               ) -> tuple[np.ndarray, np.ndarray, bool]:
    """min 1/2 |x - target|^2 s.t. c x >= b + eps_abs (the skin) with proxsuite's sparse
    backend; returns x, multipliers >= 0 and whether it converged."""
    n, m = len(target), len(b)
    qp = proxsuite.proxqp.sparse.QP(n, 0, m)
    qp.settings.eps_abs = opts.eps_abs
    qp.settings.eps_rel = 0.0
    qp.settings.max_iter = opts.max_iter
    qp.settings.max_iter_in = 100  # bounds the inner loop too, which can otherwise stall
    qp.settings.verbose = False
    qp.init(sp.identity(n, format="csc"), -target, None, None, c, b + opts.eps_abs,
            np.full(m, 1e30))
    qp.solve()
    status = qp.results.info.status
    ok = (status.name if hasattr(status, "name") else str(status)) == "PROXQP_SOLVED"
    return np.array(qp.results.x), np.maximum(-np.array(qp.results.z), 0.0), ok


