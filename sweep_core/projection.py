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
import clarabel
import proxsuite
import scipy.sparse as sp
from scipy.optimize import nnls
from scipy.sparse.csgraph import connected_components

from . import checks
from .constraints import Geometry, Rows, linearise
from .errors import InfeasibleError, SceneError

#: largest row violation (m) accepted from the QP solver
ROW_TOLERANCE = 1e-9


@dataclass(frozen=True)
class SolverOptions:
    """Settings of the QP solve.

    eps_abs: proxsuite's absolute tolerance (m): bound on the row residuals and stationarity.
        Every row is tightened by eps_abs before the solve (a skin), so a solution within the
        tolerance still satisfies the untightened row: no overlap, not even of eps_abs.
    max_iter: proxsuite's iteration cap (backend "proxsuite").
    dense_fallback: clusters of up to this many variables (2 per agent) are retried with the
        active-set NNLS solver when the backend fails.
    backend: "clarabel" (default: interior point, robust in dense jams) or "proxsuite"
        (proxsuite 0.8.0 can stall inside its solve on degenerate jam QPs; see README).
    exact_vars: clusters of up to this many variables (2 per agent) are solved first by the
        exact active-set solver (:func:`_ldp`), the backend only if it fails. Up to about 64
        agents that solver is also the faster one; above, it costs O(n^3) but is exact where
        the interior-point backend stops about 1e-6 m short in degenerate jams (README).
    """

    eps_abs: float = 1e-10
    max_iter: int = 1000
    dense_fallback: int = 4000
    backend: str = "clarabel"
    exact_vars: int = 128

    @classmethod
    def from_values(cls, eps_abs: float = 1e-10, max_iter: int = 1000,
                    backend: str = "clarabel", exact_vars: int = 128) -> "SolverOptions":
        eps = checks.number(eps_abs, "solver.eps_abs", positive=True)
        if eps > 1e-9:
            raise SceneError("solver.eps_abs", f"{eps:g} m would allow overlaps above 1e-9 m",
                             "use eps_abs <= 1e-9")
        if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
            raise SceneError("solver.max_iter", f"must be a positive integer, got {max_iter!r}")
        if backend not in ("clarabel", "proxsuite"):
            raise SceneError("solver.backend", f"unknown backend {backend!r}",
                             "use 'clarabel' or 'proxsuite'")
        if (isinstance(exact_vars, bool) or not isinstance(exact_vars, (int, np.integer))
                or exact_vars < 0):
            raise SceneError("solver.exact_vars", f"must be an integer >= 0, got {exact_vars!r}",
                             "use 0 to send every cluster to the backend")
        return cls(eps, int(max_iter), backend=backend, exact_vars=int(exact_vars))


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


def _row_matrix(rows: Rows, loc: np.ndarray, m: int) -> tuple[sp.csc_matrix, np.ndarray]:
    """Sparse C (rows x 2m) and bounds b of ``C x >= b`` with x the stacked QP agents."""
    p, s = len(rows.pair_b), len(rows.single_b)
    ci, cj, ca = 2 * loc[rows.pair_i], 2 * loc[rows.pair_j], 2 * loc[rows.single_a]
    r_p = np.arange(p)
    r_s = p + np.arange(s)
    row = np.concatenate([r_p, r_p, r_p, r_p, r_s, r_s])
    col = np.concatenate([ci, ci + 1, cj, cj + 1, ca, ca + 1])
    val = np.concatenate([rows.pair_e[:, 0], rows.pair_e[:, 1], -rows.pair_e[:, 0],
                          -rows.pair_e[:, 1], rows.single_n[:, 0], rows.single_n[:, 1]])
    c = sp.csc_matrix((val, (row, col)), shape=(p + s, 2 * m))
    return c, np.concatenate([rows.pair_b, rows.single_b])


def _proxsuite(target: np.ndarray, c: sp.csc_matrix, b: np.ndarray, opts: SolverOptions
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


def _ldp(target: np.ndarray, c: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
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


def _clusters(c: sp.csc_matrix) -> tuple[int, np.ndarray, np.ndarray]:
    """Connected clusters of agents linked by rows: count, label of each column, of each row."""
    n = c.shape[1] // 2
    agent_of_col = np.arange(2 * n) // 2
    coo = c.tocoo()
    row_agent = np.zeros(c.shape[0], dtype=np.intp)
    row_agent[coo.row] = agent_of_col[coo.col]
    link = sp.csr_matrix((np.ones(len(coo.row)), (row_agent[coo.row], agent_of_col[coo.col])),
                         shape=(n, n))
    count, label = connected_components(link, directed=False)
    return count, label[agent_of_col], label[row_agent]


def _solve_qp(target: np.ndarray, c: sp.csc_matrix, b: np.ndarray, opts: SolverOptions
              ) -> tuple[np.ndarray, np.ndarray, bool, int]:
    """min 1/2 |x - target|^2 s.t. c x >= b, cluster by cluster (clusters of agents linked by
    rows are independent QPs): single-row clusters in closed form, the others by
    :func:`_solve_cluster`. Returns x, multipliers >= 0, whether every cluster was solved and
    the number of variables solved by the backend rather than exactly."""
    count, col_label, row_label = _clusters(c)
    x, lam = target.copy(), np.zeros(c.shape[0])
    cr = c.tocsr()
    order_c, order_r = np.argsort(col_label, kind="stable"), np.argsort(row_label, kind="stable")
    starts_c = np.searchsorted(col_label[order_c], np.arange(count + 1))
    starts_r = np.searchsorted(row_label[order_r], np.arange(count + 1))
    n_rows = np.diff(starts_r)
    # a cluster with a single row is a projection onto a half-space: closed form, vectorised
    one = np.nonzero(n_rows == 1)[0]
    if len(one):
        r1 = order_r[starts_r[one]]
        row = cr[r1]
        lam1 = np.maximum(0.0, (b[r1] - row @ target) / np.asarray(row.multiply(row).sum(axis=1)).ravel())
        lam[r1] = lam1
        x += np.asarray(row.T @ lam1).ravel()
    by_backend = 0
    for k in np.nonzero(n_rows > 1)[0]:
        cols = order_c[starts_c[k]:starts_c[k + 1]]
        rws = order_r[starts_r[k]:starts_r[k + 1]]
        sub = cr[rws][:, cols]
        found = _solve_cluster(target[cols], sub, b[rws], opts)
        if found is None:
            return x, lam, False, by_backend
        xk, lk, exact = found
        x[cols], lam[rws] = xk, lk
        by_backend += 0 if exact else len(cols)
    return x, lam, True, by_backend


def _solve_cluster(target: np.ndarray, c: sp.csr_matrix, b: np.ndarray, opts: SolverOptions
                   ) -> tuple[np.ndarray, np.ndarray, bool] | None:
    """Solve one cluster: clusters of up to ``exact_vars`` variables by the exact active-set
    solver first, then the backend; larger ones by the backend first, then (up to
    ``dense_fallback`` variables) the exact solver. An answer is taken only if every row holds
    to ROW_TOLERANCE. Returns x, multipliers and whether the exact solver produced them; None
    if no attempt gives an answer whose rows hold."""
    n = c.shape[1]
    exact = (True, lambda: _ldp(target, c.toarray(), b))
    backend = (False, lambda: (_proxsuite(target, c.tocsc(), b, opts)
                               if opts.backend == "proxsuite" else _clarabel(target, c, b, opts)))
    attempts = ([exact, backend] if n <= opts.exact_vars
                else [backend] + ([exact] if n <= opts.dense_fallback else []))
    last_resort = None
    for is_exact, attempt in attempts:
        x, lam, ok = attempt()
        if not (np.all(np.isfinite(x)) and (c @ x - b).min() >= -ROW_TOLERANCE):
            continue
        if ok is True:
            return x, lam, is_exact
        if ok is None and last_resort is None:
            last_resort = (x, lam, False)
    # Clarabel's "AlmostSolved" with every row holding: feasible, though further from the
    # projection; better than stopping the run when nothing else answered
    return last_resort


def _clarabel(target: np.ndarray, c: sp.csr_matrix, b: np.ndarray, opts: SolverOptions
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
            c, b = _row_matrix(rows, loc, qp_size)
            x, lam, ok, by_backend = _solve_qp(pred[agents].ravel(), c, b, opts)
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
