"""The face step by a sparse factorisation: the Newton step of the dual on a face that has
stopped changing.

Once the Gauss-Seidel sweeps and the projected searches of :mod:`.dual` have found which rows
are active, what remains is the linear system of the face S (the rows with lam_k > 0),

    (A_S A_S^T) p = h_S - A_S x          (the dual's Newton step, reference §4),

whose matrix in a deep jam is badly conditioned: unpreconditioned conjugate gradients gain a
factor 2 to 3 per 50 iterations there, which made the certified solve take 25 to 40 rounds a
step at 1000 agents. One sparse factorisation of A_S A_S^T + eps I used as the preconditioner
of conjugate gradients on A_S A_S^T solves it in one to three iterations. The small shift eps
keeps the factorisation defined where the face's rows are linearly dependent (hexagonal
lattices): conjugate gradients on the unshifted, consistent system then still converge, the
factor only preconditions them.

The factorisation is CHOLMOD's simplicial LDL^T (through cvxopt) with its AMD ordering: about
0.7 ms at 1000 rows, and free of BLAS. Everything here decides positions, so nothing may depend
on the CPU: a BLAS kernel (SuperLU's supernodes, ``numpy.dot``) splits its sums by the vector
width the CPU offers, and its last bits differ between CPUs; the simplicial factorisation, the
sparse products and :func:`dual.dot` add in a fixed order.
"""
from __future__ import annotations

import cvxopt
import numpy as np
import scipy.sparse as sp
from cvxopt import cholmod

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


def factorise(m: sp.csr_matrix) -> object | None:
    """The LDL^T factor of m + SHIFT I (m symmetric positive semidefinite, (S, S)), or None
    when a pivot vanishes despite the shift."""
    shifted = (sp.tril(m) + SHIFT * sp.identity(m.shape[0])).tocoo()
    lower = cvxopt.spmatrix(shifted.data, shifted.row.astype(np.int64), shifted.col.astype(np.int64),
                            shifted.shape)
    # simplicial (no supernodes, hence no BLAS); the options are cvxopt's module-wide ones,
    # which its own QP solver reads too (left at simplicial, cvxopt's backend failed on a small
    # jam it otherwise solves): set for this factorisation only
    saved = dict(cholmod.options)
    cholmod.options["supernodal"] = 0
    try:
        factor = cholmod.symbolic(lower, uplo="L")
        cholmod.numeric(lower, factor)
    except ArithmeticError:
        return None
    finally:
        cholmod.options.clear()
        cholmod.options.update(saved)
    return factor


def solve(factor: object, r: np.ndarray) -> np.ndarray:
    """(m + SHIFT I)^-1 r (S,) through the factor of :func:`factorise`."""
    out = cvxopt.matrix(r.copy())
    cholmod.solve(factor, out)
    return np.array(out).ravel()


def newton_direction(n: int, rows: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray,
                     residual: np.ndarray) -> np.ndarray | None:
    """p (S,) m solving (A_S A_S^T) p = residual to about 1e-14 relative, or None when the
    factorisation fails or the residual does not fall below 1e-6 of its start (the system
    has no solution: the face is not the solution's)."""
    a = face_matrix(n, rows, ri, rj, re)
    m = (a @ a.T).tocsr()
    factor = factorise(m)
    if factor is None:
        return None
    r = residual.copy()
    p = np.zeros_like(r)
    z = solve(factor, r)
    dirn = z.copy()
    rz = dual.dot(r, z)
    start = dual.dot(r, r)
    for _ in range(PCG_ITERS):
        w = m @ dirn
        dw = dual.dot(dirn, w)
        if dw <= 0.0 or rz <= 0.0:
            break
        alpha = rz / dw
        p += alpha * dirn
        r -= alpha * w
        if dual.dot(r, r) <= 1e-28 * start:
            break
        z = solve(factor, r)
        rz_new = dual.dot(r, z)
        dirn = z + (rz_new / rz) * dirn
        rz = rz_new
    # an inconsistent face system (dependent rows, some of them not active at the solution:
    # degenerate lattices) has no solution; conjugate gradients then wander off
    if not np.all(np.isfinite(p)) or dual.dot(r, r) > CONSISTENT * start:
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
