"""The backend QP solvers of one cluster, through qpsolvers: any solver it finds installed.

The cluster QP min 1/2 |x - t|^2 s.t. C x >= b + eps_abs is posed to qpsolvers as
P = I, q = -t, G = -C, h = -(b + eps_abs) (sparse); its multipliers z of G x <= h are the
cluster's lam (x = t + C^T z). Each solver gets the tight tolerances of ``SETTINGS`` (qpsolvers
passes them to the solver as they are): 1e-12 where the solver's own criterion allows it
(PIQP 1e-11, its answer then refined), so that the answer is certified by the duality gap
rather than taken on trust.

Clarabel and PIQP keep their own modules (:mod:`.interior`; :mod:`.pivot`, which loads PIQP's
baseline build so that the answer does not depend on the CPU); proxsuite is qpsolvers'
``proxqp``.
"""
from __future__ import annotations

import numpy as np
import qpsolvers
import scipy.sparse as sp

from sweep_core.numerics.projection.interior import solve_clarabel
from sweep_core.numerics.projection.options import ALIASES, SolverOptions, available_backends
from sweep_core.numerics.projection.pivot import SETTINGS as PIQP_SETTINGS
from sweep_core.numerics.projection.pivot import solve_piqp

#: tolerances given to each solver (qpsolvers forwards them to the solver's settings)
SETTINGS: dict[str, dict] = {
    "clarabel": {},  # :func:`.interior.solve_clarabel`
    "cvxopt": {"abstol": 1e-10, "reltol": 1e-10, "feastol": 1e-10},  # 1e-12: "unknown"
    "daqp": {"primal_tol": 1e-12, "dual_tol": 1e-12, "iter_limit": 100000},
    "highs": {"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10},
    "osqp": {"eps_abs": 1e-10, "eps_rel": 0.0, "max_iter": 100000, "polishing": True},
    "piqp": PIQP_SETTINGS,  # :func:`.pivot.solve_piqp`, its baseline build
    "proxqp": {"eps_abs": 1e-10, "eps_rel": 0.0, "max_iter": 1000},
}


#: the distance (m) to the exact projection each solver is held to with ``SETTINGS`` on a
#: small hexagonal jam (test_backends.py; measured there: clarabel 1.2e-8, cvxopt 1.2e-6, the
#: others about 6e-10, the rows' skin eps_abs). HiGHS 1.15 ends these QPs with a solve error
#: (the projection then hands them to Clarabel); a solver not listed is held to 1e-6 m
ACCURACY: dict[str, float] = {"clarabel": 1e-7, "cvxopt": 1e-5, "daqp": 1e-8, "osqp": 1e-8,
                              "piqp": 1e-8, "proxqp": 1e-8}


def available() -> list[str]:
    """The backends installed here, sorted (qpsolvers' names; clarabel always)."""
    return available_backends()


def solve_backend(target: np.ndarray, c: sp.spmatrix, b: np.ndarray, opts: SolverOptions
                  ) -> tuple[np.ndarray, np.ndarray, bool | None]:
    """One cluster QP by ``opts.backend``, rows tightened by eps_abs: x (n,), multipliers
    (m,) >= 0, and True (solved), None (Clarabel's reduced accuracy) or False."""
    name = ALIASES.get(opts.backend, opts.backend)
    if name == "clarabel":
        return solve_clarabel(target, sp.csr_matrix(c), b, opts)
    if name == "piqp":
        return solve_piqp(target, c, b, opts)
    n, m = c.shape[1], c.shape[0]
    if m == 0:
        return target.copy(), np.zeros(0), True
    problem = qpsolvers.Problem(sp.identity(n, format="csc"), -np.asarray(target, dtype=float),
                                sp.csc_matrix(-c), -(np.asarray(b, dtype=float) + opts.eps_abs))
    settings = dict(SETTINGS.get(name, {}))
    if name == "proxqp":
        settings["max_iter"] = opts.max_iter
    try:
        sol = qpsolvers.solve_problem(problem, solver=name, **settings)
    except Exception:  # noqa: BLE001 - a solver's failure means: no answer from it
        return target.copy(), np.zeros(m), False
    if not sol.found or sol.x is None or sol.z is None:
        return target.copy(), np.zeros(m), False
    return np.asarray(sol.x, dtype=float), np.maximum(np.asarray(sol.z, dtype=float), 0.0), True
