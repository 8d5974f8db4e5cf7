"""The Clarabel backend (interior point, qdldl) for one cluster QP."""
from __future__ import annotations

import clarabel
import numpy as np
import scipy.sparse as sp

from sweep_core.numerics.projection.options import SolverOptions


def solve_clarabel(target: np.ndarray, c: sp.csr_matrix, b: np.ndarray, opts: SolverOptions
              ) -> tuple[np.ndarray, np.ndarray, bool | None]:
    """The cluster QP by Clarabel's interior-point method, rows tightened by eps_abs.

    Interior-point iterations do not depend on the multipliers being unique, so dense jams
    (reference §6) cost no more than loose crowds. Returns x, multipliers and True (solved),
    None ("AlmostSolved": reduced accuracy) or False."""
    n, m = c.shape[1], c.shape[0]
    if m == 0:
        return target.copy(), np.zeros(0), True
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = 1e-12
    settings.max_iter = 200
    # the supernodal 'faer' factorisation (the default in Clarabel 0.11) is several times
    # slower than qdldl on these mesh-like KKT systems (374 ms against 2.7 s at 4000 jammed)
    settings.direct_solve_method = "qdldl"
    solver = clarabel.DefaultSolver(sp.identity(n, format="csc"), -target, sp.csc_matrix(-c),
                                    -(b + opts.eps_abs), [clarabel.NonnegativeConeT(m)], settings)
    sol = solver.solve()
    # "AlmostSolved" means Clarabel's reduced tolerances (about 1e-5 here), possibly far from
    # the projection although the rows hold: None, taken only when no other solver answers
    status = str(sol.status)
    ok = True if status == "Solved" else (None if status == "AlmostSolved" else False)
    return np.array(sol.x), np.maximum(np.array(sol.z), 0.0), ok


