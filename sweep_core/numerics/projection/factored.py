"""The face step by a sparse factorisation: the Newton step of the dual on a face that has
stopped changing.

Once the Gauss-Seidel sweeps and the projected searches of :mod:`.dual` have found which rows
are active, what remains is the linear system of the face S (the rows with lam_k > 0),

    (A_S A_S^T) p = h_S - A_S x          (the dual's Newton step, reference §4),

whose matrix in a deep jam is badly conditioned: unpreconditioned conjugate gradients gain a
factor 2 to 3 per 50 iterations there, which made the certified solve take 25 to 40 rounds a
step at 1000 agents. One sparse LU factorisation of A_S A_S^T + eps I (SuperLU through
:func:`scipy.sparse.linalg.splu`, symmetric mode, minimum-degree ordering of A + A^T; about
2 ms at 1000 rows) used as the preconditioner of conjugate gradients on A_S A_S^T solves it in
one to three iterations. The small shift eps keeps the factorisation defined where the face's
rows are linearly dependent (hexagonal lattices): conjugate gradients on the unshifted,
consistent system then still converge, the factor only preconditions them.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from sweep_core.numerics.projection import dual

#: shift of the factored matrix (its diagonal is 2 for a pair row, 1 for a wall row)
SHIFT = 1e-10
#: preconditioned conjugate-gradient iterations at most
PCG_ITERS = 10
#: largest squared residual, relative to the start, of a direction that is taken
CONSISTENT = 1e-12


def face_matrix(n: int, rows: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray
                ) -> sp.csr_matrix:
    """A_S (S, 2 n): row u is the gradient of row ``rows[u]`` in the unknowns (x_0, y_0, x_1,
    ...)."""
    m = len(rows)
    e = re[rows]
    i, j = ri[rows], rj[rows]
    pair = j >= 0
    u = np.arange(m)
    r = np.concatenate([u, u, u[pair], u[pair]])
    c = np.concatenate([2 * i, 2 * i + 1, 2 * j[pair], 2 * j[pair] + 1])
    v = np.concatenate([e[:, 0], e[:, 1], -e[pair, 0], -e[pair, 1]])
    return sp.csr_matrix((v, (r, c)), shape=(m, 2 * n))


def newton_direction(n: int, rows: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray,
                     residual: np.ndarray) -> np.ndarray | None:
    """p (S,) m solving (A_S A_S^T) p = residual to about 1e-14 relative, or None when the
    factorisation fails or the residual does not fall below 1e-6 of its start (the system
    has no solution: the face is not the solution's)."""
    a = face_matrix(n, rows, ri, rj, re)
    m = (a @ a.T).tocsc()
    try:
        lu = splu(m + SHIFT * sp.identity(len(rows), format="csc"),
                  permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                  options={"SymmetricMode": True})
    except RuntimeError:  # a zero pivot despite the shift
        return None
    r = residual.copy()
    p = np.zeros_like(r)
    z = lu.solve(r)
    dirn = z.copy()
    rz = float(r @ z)
    start = float(r @ r)
    for _ in range(PCG_ITERS):
        w = m @ dirn
        dw = float(dirn @ w)
        if dw <= 0.0 or rz <= 0.0:
            break
        alpha = rz / dw
        p += alpha * dirn
        r -= alpha * w
        if float(r @ r) <= 1e-28 * start:
            break
        z = lu.solve(r)
        rz_new = float(r @ z)
        dirn = z + (rz_new / rz) * dirn
        rz = rz_new
    # an inconsistent face system (dependent rows, some of them not active at the solution:
    # degenerate lattices) has no solution; conjugate gradients then wander off
    if not np.all(np.isfinite(p)) or float(r @ r) > CONSISTENT * start:
        return None
    return p


def face_step(x: np.ndarray, d: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray,
              rh: np.ndarray, lam: np.ndarray) -> bool:
    """One factored face step, in place on lam and x (= d + A^T lam on return): the Newton
    direction on the face lam > 0, then :func:`dual.search`. Returns whether lam moved."""
    rows = dual.face_rows(lam)
    if len(rows) == 0:
        return False
    p = newton_direction(len(d), rows, ri, rj, re, dual.face_residual(x, ri, rj, re, rh, rows))
    if p is None:
        return False
    moved, _ = dual.search(x, d, ri, rj, re, rh, lam, rows, p)
    return bool(moved)
