"""The linearised QP as a sparse row matrix, split into independent clusters of agents, each
solved in closed form (one row), exactly (active set) or by a backend (interior point)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from sweep_core.numerics.constraints import Rows
from sweep_core.numerics.projection import active
from sweep_core.numerics.projection.backends import solve_backend
from sweep_core.numerics.projection.options import ROW_TOLERANCE, SolverOptions, check_backend


def row_matrix(rows: Rows, loc: np.ndarray, m: int) -> tuple[sp.csc_matrix, np.ndarray]:
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


def clusters(c: sp.csc_matrix) -> tuple[int, np.ndarray, np.ndarray]:
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


def solve_qp(target: np.ndarray, c: sp.csc_matrix, b: np.ndarray, opts: SolverOptions
              ) -> tuple[np.ndarray, np.ndarray, bool, int]:
    """min 1/2 |x - target|^2 s.t. c x >= b, cluster by cluster (clusters of agents linked by
    rows are independent QPs): single-row clusters in closed form, the others by
    :func:`solve_cluster`. Returns x, multipliers >= 0, whether every cluster was solved and
    the number of variables solved by the backend rather than exactly."""
    count, col_label, row_label = clusters(c)
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
        found = solve_cluster(target[cols], sub, b[rws], opts)
        if found is None:
            return x, lam, False, by_backend
        xk, lk, exact = found
        x[cols], lam[rws] = xk, lk
        by_backend += 0 if exact else len(cols)
    return x, lam, True, by_backend


#: clusters of more variables than this (and than exact_vars) are retried by the exact solver
#: only when the backend gave no usable answer (an "AlmostSolved" one whose rows hold is
#: kept): the dense active set costs the cube of the size (about 0.2 s at 512 variables, 1 to
#: 5 s at 2000)
CHEAP_EXACT = 512


def solve_active(target: np.ndarray, c: sp.csr_matrix, b: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, bool]:
    """One cluster by the compiled dual active-set solver (:mod:`.active`): x, multipliers and
    whether it solved the QP (False: no feasible point, or its step cap, 3 steps a row plus one
    per variable, was reached)."""
    csr = sp.csr_matrix(c)
    csr.sort_indices()
    x, lam, status, _ = active.solve(np.ascontiguousarray(target, dtype=float),
                                     csr.indptr.astype(np.int64), csr.indices.astype(np.int64),
                                     np.ascontiguousarray(csr.data, dtype=float),
                                     np.ascontiguousarray(b, dtype=float),
                                     3 * len(b) + len(target))
    return x, lam, status == active.SOLVED


#: the skins (m) a backend is tried with, thinnest first, up to ``SolverOptions.eps_abs``: the
#: skin costs skin x (sum of the multipliers) in the certificate's gap, so a thin one gives a
#: bound ten times smaller (2.9e-5 m against 2.9e-4 m on a 1000-agent jam at a door), but an
#: interior point holds its rows only to about 1e-13 m and then sometimes breaks one by that
#: much; the next skin is tried then
SKINS = (1e-12,)


def solve_tight(target: np.ndarray, c: sp.spmatrix, b: np.ndarray, opts: SolverOptions
                ) -> tuple[np.ndarray, np.ndarray, bool | None]:
    """One cluster by the backend with the thinnest skin of ``SKINS`` (then ``opts.eps_abs``)
    whose answer holds every row of c x >= b; the last answer if none does."""
    skins = [e for e in SKINS if e < opts.eps_abs] + [opts.eps_abs]
    for skin in skins:
        x, lam, ok = solve_backend(target, c, b, replace(opts, eps_abs=skin))
        if ok is not False and np.all(np.isfinite(x)) and (c @ x - b).min(initial=0.0) >= 0.0:
            break
    return x, lam, ok


def solve_cluster(target: np.ndarray, c: sp.csr_matrix, b: np.ndarray, opts: SolverOptions
                   ) -> tuple[np.ndarray, np.ndarray, bool] | None:
    """Solve one cluster: clusters of up to ``exact_vars`` variables by the exact active-set
    solver first, then the backend; larger ones by the backend first, then (up to
    ``dense_fallback`` variables) the exact solver; Clarabel last when the backend is another
    solver. An answer is taken only if every row holds to ROW_TOLERANCE. Returns x,
    multipliers and whether the exact solver produced them; None if no attempt gives an
    answer whose rows hold."""
    n = c.shape[1]
    exact = (True, lambda: solve_active(target, c, b))
    backend = (False, lambda: solve_tight(target, c, b, opts))
    attempts = ([exact, backend] if n <= opts.exact_vars
                else [backend] + ([exact] if n <= opts.dense_fallback else []))
    if check_backend(opts.backend) != "clarabel":
        # a solver that fails on a jam (HiGHS ends some with a solve error) hands it to
        # Clarabel rather than stopping the run
        attempts.append((False, lambda: solve_backend(target, c, b, replace(opts,
                                                                            backend="clarabel"))))
    last_resort = None
    for is_exact, attempt in attempts:
        if is_exact and n > max(opts.exact_vars, CHEAP_EXACT) and last_resort is not None:
            continue  # a feasible backend answer beats seconds of dense active set
        x, lam, ok = attempt()
        if not (np.all(np.isfinite(x)) and (c @ x - b).min() >= -ROW_TOLERANCE):
            continue
        if ok is True:
            return x, lam, is_exact
        if ok is None and last_resort is None:
            last_resort = (x, lam, False)
    # Clarabel's "AlmostSolved" with every row holding: feasible, though further from the
    # projection (the certificate says how far); better than stopping the run when nothing
    # else answered
    return last_resort


