"""Projection onto the linearised feasible set: one convex QP per step (reference §4).

    y = argmin |y - p|^2  subject to the rows of C~(t1, q)   (identity Hessian)

Only agents that appear in a built row enter the QP; all others keep y_i = p_i. Rows are
built inside a cutoff (``constraints.linearise``) and the cutoff is proven sufficient after
the solve: an unbuilt row had value > cut at q, and moves by at most |y_i - q_i| + |y_j - q_j|
<= 2 max_i |y_i - q_i|, so if that is <= cut every unbuilt row holds at y; otherwise the
cutoff grows and the QP is solved again. Projecting onto a superset and landing inside the
set gives the projection onto the set, so the result is exact, not approximate.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sweep_core.errors import InfeasibleError
from sweep_core.model.geometry import Geometry
from sweep_core.numerics.constraints import Rows, linearise
from sweep_core.numerics.projection.clusters import row_matrix, solve_qp
from sweep_core.numerics.projection.options import ROW_TOLERANCE, SolverOptions


@dataclass(frozen=True)
class Projection:
    """Result of one projection.

    y: (N, 2) projected positions (m); rows: the rows built; lam_pair (P,), lam_single (M,):
    multipliers (>= 0) of the rows, the reaction of each contact is lam * gradient;
    active: number of rows that hold with equality (residual <= ROW_TOLERANCE); qp_size: number of
    agents in the QP (0 when the prediction was already feasible); solves: QP solves done;
    backend_agents: agents whose cluster was solved by the interior-point backend rather than
    exactly (closed form or active set), i.e. to the backend's tolerance (about 1e-6 m in
    degenerate jams) instead of to rounding.
    """

    y: np.ndarray
    rows: Rows
    lam_pair: np.ndarray
    lam_single: np.ndarray
    active: int
    qp_size: int
    solves: int
    backend_agents: int = 0


def first_cutoff(q: np.ndarray, pred: np.ndarray, r1: np.ndarray) -> float:
    """The cutoff (m) rows are first built with: 3 max_i |p_i - q_i| + 1e-3 max r.

    A margin beyond the provable 2 max|p - q|: a projection usually moves agents a little
    further than their prediction, and a second build costs more than a few extra rows."""
    step = np.sqrt(np.einsum("ij,ij->i", pred - q, pred - q))
    return 3.0 * float(step.max()) + 1e-3 * float(r1.max())


def project(geom: Geometry, t1: float, q: np.ndarray, pred: np.ndarray, r1: np.ndarray,
            opts: SolverOptions) -> Projection:
    """Project the prediction pred (N, 2) onto C~(t1, q); q (N, 2) at t_n, r1 (N,) at t1.

    Raises InfeasibleError (naming t1 and the agents) if the QP has no solution.
    """
    n = len(q)
    if n == 0:
        empty = linearise(geom, t1, q, r1, 0.0)
        return Projection(pred.copy(), empty, np.empty(0), np.empty(0), 0, 0, 0)
    cut = first_cutoff(q, pred, r1)
    solves = 0
    while True:
        rows = linearise(geom, t1, q, r1, cut)
        rp, rs = rows.residuals(pred)
        lam_p, lam_s = np.zeros(len(rp)), np.zeros(len(rs))
        y = pred.copy()
        qp_size = by_backend = 0
        if (len(rp) and rp.min() < 0) or (len(rs) and rs.min() < 0):
            agents = rows.agents()
            qp_size = len(agents)
            loc = np.full(n, -1, dtype=np.intp)
            loc[agents] = np.arange(qp_size)
            c, b = row_matrix(rows, loc, qp_size)
            x, lam, ok, by_backend = solve_qp(pred[agents].ravel(), c, b, opts)
            solves += 1
            y[agents] = x.reshape(-1, 2)
            rp, rs = rows.residuals(y)
            worst = min(rp.min(initial=np.inf), rs.min(initial=np.inf))
            if not ok or not np.isfinite(worst) or worst < -ROW_TOLERANCE:
                why = "no feasible point" if not ok else "solver residual"
                raise InfeasibleError(t1, _culprits(rows, rp, rs),
                                      f"{why}, worst row residual {worst:.3g} m")
            lam_p, lam_s = lam[: len(rp)], lam[len(rp):]
        moved = float(np.sqrt(np.einsum("ij,ij->i", y - q, y - q)).max())
        if 2.0 * moved <= cut:
            break
        cut = 3.0 * moved
    # a row is active when it holds with equality (to the solver tolerance); an interior-point
    # solver leaves tiny positive multipliers on slack rows, so multipliers are not counted
    active = int(np.count_nonzero(rp <= ROW_TOLERANCE) + np.count_nonzero(rs <= ROW_TOLERANCE))
    return Projection(y, rows, lam_p, lam_s, active, qp_size, solves, by_backend // 2)


def _culprits(rows: Rows, rp: np.ndarray, rs: np.ndarray, count: int = 6) -> list[int]:
    """Agents of the most violated rows, most violated first."""
    rp = np.nan_to_num(rp, nan=-np.inf)
    rs = np.nan_to_num(rs, nan=-np.inf)
    order = np.argsort(np.concatenate([rp, rs]))[:count]
    agents: list[int] = []
    for k in order:
        found = ([rows.pair_i[k], rows.pair_j[k]] if k < len(rp)
                 else [rows.single_a[k - len(rp)]])
        for a in found:
            if int(a) not in agents:
                agents.append(int(a))
    return agents
