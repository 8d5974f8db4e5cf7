"""The exact solver of one cluster: a compiled dual active-set method (Goldfarb and Idnani).

    min 1/2 |x - d|^2   s.t.   <c_k, x> >= h_k   for every row k          (identity Hessian)

Goldfarb and Idnani's dual method (Math. Programming 27 (1983) 1-33) with G = I starts from the
unconstrained minimiser x = d and adds one violated row at a time; x always minimises the
objective on the active rows' equalities, with multipliers u >= 0 (x = d + N u, N the active
rows' gradients as columns). Adding row p moves x along z, the part of c_p orthogonal to the
active gradients, and u along -r, r = R^-1 Q^T c_p; a multiplier reaching 0 first drops its
row (partial step). A row whose gradient lies in the span of the active ones (z = 0: dependent
rows, as in jams of equal radii against walls) takes a pure dual step that drops a row, never
a singular solve; if no multiplier can decrease (r <= 0) the rows have no common point. Every
full step raises the dual objective, so no active set repeats and the method ends; the
iterations are capped all the same (``max_iter``) and the caller falls back when the cap is hit.

N = Q^T R is kept as Q (rows: an orthonormal basis of the active gradients, q x n) and R
(upper triangular, q x q): adding a row appends a basis vector (Gram-Schmidt, done twice);
dropping one re-triangularises R by Givens rotations, applied to Q too. A step costs O(n q).

Deterministic across CPUs: every operation is a sequential loop compiled by numba without
fastmath (no BLAS, no LAPACK, no numpy reductions), so the same data give the same bits
everywhere. The rows are given as CSR arrays (each row of a contact has 2 to 4 entries).
"""
from __future__ import annotations

import numba
import numpy as np

#: status of :func:`solve`: solved, no feasible point, iteration cap reached
SOLVED, INFEASIBLE, CAPPED = 0, 1, 2

#: a row is dependent on the active ones when its part orthogonal to them is below this
#: fraction of its norm (rounding leaves about 1e-15 on exactly dependent rows)
DEPENDENT = 1e-9


@numba.njit(cache=True, nogil=True)
def _row_dot(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, k: int,
             x: np.ndarray) -> float:
    total = 0.0
    for e in range(indptr[k], indptr[k + 1]):
        total += data[e] * x[indices[e]]
    return total


@numba.njit(cache=True, nogil=True)
def _drop(out: int, q: int, basis: np.ndarray, tri: np.ndarray, act: np.ndarray,
          u: np.ndarray) -> int:
    """Remove active position ``out`` of q: shift the columns of R, u and act left, then Givens
    rotations on rows (c, c + 1) of R and of the basis restore R's triangle. Returns q - 1."""
    n = basis.shape[1]
    for c in range(out, q - 1):
        act[c] = act[c + 1]
        u[c] = u[c + 1]
        for a in range(c + 2):  # column c + 1 of a triangle has rows 0..c + 1
            tri[a, c] = tri[a, c + 1]
    for a in range(q):
        tri[a, q - 1] = 0.0
    for c in range(out, q - 1):
        a_, b_ = tri[c, c], tri[c + 1, c]
        if b_ == 0.0:
            continue
        rho = np.sqrt(a_ * a_ + b_ * b_)
        cs, sn = a_ / rho, b_ / rho
        for col in range(c, q - 1):
            t1, t2 = tri[c, col], tri[c + 1, col]
            tri[c, col] = cs * t1 + sn * t2
            tri[c + 1, col] = -sn * t1 + cs * t2
        tri[c + 1, c] = 0.0
        for e in range(n):
            t1, t2 = basis[c, e], basis[c + 1, e]
            basis[c, e] = cs * t1 + sn * t2
            basis[c + 1, e] = -sn * t1 + cs * t2
    return q - 1


@numba.njit(cache=True, nogil=True)
def _direction(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, p: int, q: int,
               basis: np.ndarray, tri: np.ndarray, v: np.ndarray, z: np.ndarray,
               r: np.ndarray) -> float:
    """For row p: v = Q c_p (q,), z = c_p - Q^T v (n,) (orthogonalised again when the first pass
    cancelled more than half of |c_p|^2), r = R^-1 v (q,). Returns |z|^2."""
    n = basis.shape[1]
    for c in range(q):
        total = 0.0
        for e in range(indptr[p], indptr[p + 1]):
            total += data[e] * basis[c, indices[e]]
        v[c] = total
    for e in range(n):
        z[e] = 0.0
    for e in range(indptr[p], indptr[p + 1]):
        z[indices[e]] += data[e]
    for c in range(q):
        for e in range(n):
            z[e] -= v[c] * basis[c, e]
    zz = 0.0
    for e in range(n):
        zz += z[e] * z[e]
    cc = 0.0
    for e in range(indptr[p], indptr[p + 1]):
        cc += data[e] * data[e]
    if q > 0 and zz < 0.5 * cc:
        # cancellation: a second Gram-Schmidt pass ("twice is enough", Giraud et al.,
        # Numer. Math. 101 (2005) 87-100)
        for c in range(q):
            total = 0.0
            for e in range(n):
                total += basis[c, e] * z[e]
            v[c] += total
            for e in range(n):
                z[e] -= total * basis[c, e]
        zz = 0.0
        for e in range(n):
            zz += z[e] * z[e]
    for c in range(q - 1, -1, -1):
        total = v[c]
        for a in range(c + 1, q):
            total -= tri[c, a] * r[a]
        r[c] = total / tri[c, c]
    return zz


@numba.njit(cache=True, nogil=True)
def _refine(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, h: np.ndarray,
            d: np.ndarray, q: int, act: np.ndarray, tri: np.ndarray, u: np.ndarray) -> None:
    """One step of iterative refinement of the active multipliers: with x = d + N u, solve
    R^T R du = h_A - N^T x (the active rows' residuals) and add du, so that the recomputed x
    holds the active rows to rounding."""
    x = d.copy()
    for c in range(q):
        k = act[c]
        for e in range(indptr[k], indptr[k + 1]):
            x[indices[e]] += u[c] * data[e]
    w = np.empty(q)
    for c in range(q):
        w[c] = h[act[c]] - _row_dot(indptr, indices, data, act[c], x)
    for c in range(q):  # R^T y = w (forward)
        total = w[c]
        for a in range(c):
            total -= tri[a, c] * w[a]
        w[c] = total / tri[c, c]
    for c in range(q - 1, -1, -1):  # R du = y (backward)
        total = w[c]
        for a in range(c + 1, q):
            total -= tri[c, a] * w[a]
        w[c] = total / tri[c, c]
    for c in range(q):
        u[c] += w[c]


@numba.njit(cache=True, nogil=True)
def solve(d: np.ndarray, indptr: np.ndarray, indices: np.ndarray, data: np.ndarray,
          h: np.ndarray, max_iter: int) -> tuple[np.ndarray, np.ndarray, int, int]:
    """min 1/2 |x - d|^2 s.t. C x >= h by the dual active-set method of the module docstring.

    d: (n,) target (m); C: (m, n) as CSR arrays indptr (m + 1,), indices, data; h: (m,) bounds
    (m); max_iter: cap on the steps (adds, drops and dual steps). A row counts as holding when
    its slack is above -16 ulp of the data's scale (the caller's skin is larger). Returns
    x = d + C^T lam (n,), the multipliers lam >= 0 (m,), the status (SOLVED, INFEASIBLE,
    CAPPED) and the steps taken."""
    n, m = d.shape[0], h.shape[0]
    scale = 1e-3
    for e in range(n):
        scale = max(scale, abs(d[e]))
    for k in range(m):
        scale = max(scale, abs(h[k]))
    slack_tol = 16.0 * 2.220446049250313e-16 * scale
    norm2 = np.empty(m)
    for k in range(m):
        total = 0.0
        for e in range(indptr[k], indptr[k + 1]):
            total += data[e] * data[e]
        norm2[k] = total
    qmax = min(n, m)
    basis = np.zeros((qmax, n))
    tri = np.zeros((qmax, qmax))
    act = np.empty(qmax, dtype=np.int64)
    active = np.zeros(m, dtype=np.bool_)
    u = np.zeros(qmax + 1)
    v = np.empty(qmax)
    r = np.empty(qmax)
    z = np.empty(n)
    x = d.copy()
    q = 0
    steps = 0
    status = SOLVED
    while status == SOLVED:
        # the most violated row, by distance (slack / |c_k|), the first on ties
        p = -1
        worst = 0.0
        for k in range(m):
            if active[k] or norm2[k] == 0.0:
                continue
            s = _row_dot(indptr, indices, data, k, x) - h[k]
            if s < -slack_tol and s / np.sqrt(norm2[k]) < worst:
                worst = s / np.sqrt(norm2[k])
                p = k
        if p < 0:
            break
        up = 0.0
        while True:
            steps += 1
            if steps > max_iter:
                status = CAPPED
                break
            zz = _direction(indptr, indices, data, p, q, basis, tri, v, z, r)
            t1 = np.inf
            out = -1
            for c in range(q):
                if r[c] > 0.0 and u[c] / r[c] < t1:
                    t1 = u[c] / r[c]
                    out = c
            if q == qmax or zz <= DEPENDENT * DEPENDENT * norm2[p]:
                # c_p in the span of the active gradients: x cannot move, only a row can go
                if out < 0:
                    status = INFEASIBLE
                    break
                for c in range(q):
                    u[c] -= t1 * r[c]
                up += t1
                u[out] = 0.0
                active[act[out]] = False
                q = _drop(out, q, basis, tri, act, u)
                continue
            s_p = _row_dot(indptr, indices, data, p, x) - h[p]
            t2 = -s_p / zz if s_p < 0.0 else 0.0
            t = min(t1, t2)
            for e in range(n):
                x[e] += t * z[e]
            for c in range(q):
                u[c] -= t * r[c]
            up += t
            if t2 <= t1:  # full step: row p joins the active set
                znorm = np.sqrt(zz)
                for e in range(n):
                    basis[q, e] = z[e] / znorm
                for c in range(q):
                    tri[c, q] = v[c]
                tri[q, q] = znorm
                act[q] = p
                u[q] = up
                active[p] = True
                q += 1
                break
            u[out] = 0.0  # partial step: the row whose multiplier reached 0 leaves
            active[act[out]] = False
            q = _drop(out, q, basis, tri, act, u)
    lam = np.zeros(m)
    if status == SOLVED:
        for _ in range(2):
            _refine(indptr, indices, data, h, d, q, act, tri, u)
        for c in range(q):
            lam[act[c]] = u[c] if u[c] > 0.0 else 0.0
    else:
        for c in range(q):
            lam[act[c]] = u[c]
    x = d.copy()
    for k in range(m):
        if lam[k] != 0.0:
            for e in range(indptr[k], indptr[k + 1]):
                x[indices[e]] += lam[k] * data[e]
    return x, lam, status, steps
