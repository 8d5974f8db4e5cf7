"""Compiled kernels of the certified projection: the QP's dual, solved by projected Gauss-Seidel
sweeps and Newton steps on the face of active rows (conjugate gradients), the slacks the
certificate needs, and contact clusters by union-find.

The QP of one step is written in *displacement* coordinates x = y - q (m), small numbers (a
step's motion), so that a row's slack is computed to about 1e-18 m instead of the 1e-15 m of
absolute positions. One row k has agents ``ri[k]`` and ``rj[k]`` (``-1`` for a wall or obstacle
row), a unit vector ``re[k]`` and a bound ``rh[k]`` (m); its gradient a_k is +re at ri and -re at
rj (|a_k|^2 = 2), or +re at ri alone (|a_k|^2 = 1):

    primal   min 1/2 |x - d|^2            s.t.  <a_k, x> >= h_k   for every row k
    dual     min phi(lam) = 1/2 |d + A^T lam|^2 - h^T lam   over lam >= 0,   x = d + A^T lam

(d = p - q the predicted displacement; reference §4 with y - q_n as the unknown). The dual is a
bound-constrained QP with Hessian A A^T and gradient grad phi = A x - h, the rows' slacks. Two
kinds of iteration decrease phi:

* a projected Gauss-Seidel sweep (one row at a time, lam_k <- max(0, lam_k - s_k / |a_k|^2),
  x moved with it): cheap, finds which rows are active, slow to converge in deep jams;
* a face step (Moré and Toraldo's GPCG, SIAM J. Optim. 1 (1991) 93-113, applied to the dual):
  conjugate gradients on phi restricted to the rows with lam_k > 0, then a projected line search
  along that direction: Newton-fast once the active rows are found.

Every kernel writes out the row's value <a_k, x> and the update x += v a_k (pair row or single
row) in its own loop. Calling two shared jitted helpers instead (also with inline="always")
gave bit-identical answers but made a step of the 1000-agent deep jam 1.5 to 2 times slower
(11-15 ms against 5-8 ms), so the repetition is deliberate.
"""
from __future__ import annotations

import numba
import numpy as np

#: Dekker's splitter 2^27 + 1: it splits a double into two halves whose products are exact
SPLIT = 134217729.0


@numba.njit(cache=True, nogil=True, inline="always")
def maximum(a: float, b: float) -> float:  # pragma: no cover - compiled
    """numpy's ``maximum`` of two numbers: the larger, a on a tie, NaN when either is (a
    running max m = maximum(m, v) is numpy's ``max``, NaN from the first NaN on)."""
    return a if (a >= b or a != a) else b


@numba.njit(cache=True, nogil=True, inline="always")
def minimum(a: float, b: float) -> float:  # pragma: no cover - compiled
    """numpy's ``minimum`` of two numbers: the smaller, a on a tie, NaN when either is (a
    running min m = minimum(m, v) is numpy's ``min``, NaN from the first NaN on)."""
    return a if (a <= b or a != a) else b


@numba.njit(cache=True, nogil=True)
def apply_multipliers(d: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray,
                      lam: np.ndarray) -> np.ndarray:
    """x = d + A^T lam, (N, 2) m, exact up to the rounding of x itself (1 ulp).

    In a deep jam an agent's multipliers add up to several metres while x is a few
    centimetres; summed plainly, x would carry an error of about eps times that sum (1e-15 m
    and more), and the certificate's skin would have to cover it. Here each product
    lam_k re_k is split exactly into p + e (Dekker's product, no fused multiply-add) and added
    by Knuth's two-sum, its rounding error kept in a second accumulator: a compensated sum in a
    fixed order, the same bits on every CPU."""
    n = d.shape[0]
    x = d.copy()
    c = np.zeros((n, 2))
    for k in range(ri.shape[0]):
        lk = lam[k]
        if lk != 0.0:
            i, j = ri[k], rj[k]
            t = SPLIT * lk
            lh = t - (t - lk)
            ll = lk - lh
            for a in range(2):
                v = re[k, a]
                p = lk * v
                t = SPLIT * v
                vh = t - (t - v)
                vl = v - vh
                e = ((lh * vh - p) + lh * vl + ll * vh) + ll * vl  # lk v = p + e exactly
                s = x[i, a]
                u = s + p
                w = u - s
                c[i, a] += (s - (u - w)) + (p - w) + e  # s + p = u + that, exactly
                x[i, a] = u
                if j >= 0:
                    s = x[j, a]
                    u = s - p
                    w = u - s
                    c[j, a] += (s - (u - w)) + (-p - w) - e
                    x[j, a] = u
    for i in range(n):
        x[i, 0] += c[i, 0]
        x[i, 1] += c[i, 1]
    return x


@numba.njit(cache=True, nogil=True)
def slacks(x: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray, rh: np.ndarray
           ) -> np.ndarray:
    """s_k = <a_k, x> - h_k (K,) m: >= 0 where row k holds."""
    s = np.empty(ri.shape[0])
    for k in range(ri.shape[0]):
        i, j = ri[k], rj[k]
        ux, uy = x[i, 0], x[i, 1]
        if j >= 0:
            ux -= x[j, 0]
            uy -= x[j, 1]
        s[k] = re[k, 0] * ux + re[k, 1] * uy - rh[k]
    return s


@numba.njit(cache=True, nogil=True)
def pgs(x: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray, rh: np.ndarray,
        lam: np.ndarray, sweeps: int) -> float:
    """``sweeps`` symmetric Gauss-Seidel sweeps on the dual (forward, then backward), in place
    on lam (>= 0) and x (kept equal to d + A^T lam). Returns the largest violation
    max_k (h_k - <a_k, x>) seen during the last sweep (m)."""
    n_rows = ri.shape[0]
    worst = 0.0
    for sweep in range(sweeps):
        worst = 0.0
        for t in range(n_rows):
            k = t if sweep % 2 == 0 else n_rows - 1 - t
            i, j = ri[k], rj[k]
            ex, ey = re[k, 0], re[k, 1]
            ux, uy = x[i, 0], x[i, 1]
            if j >= 0:
                ux -= x[j, 0]
                uy -= x[j, 1]
            viol = rh[k] - (ex * ux + ey * uy)
            if viol > worst:
                worst = viol
            new = lam[k] + (0.5 * viol if j >= 0 else viol)
            if new < 0.0:
                new = 0.0
            step = new - lam[k]
            if step != 0.0:
                lam[k] = new
                x[i, 0] += step * ex
                x[i, 1] += step * ey
                if j >= 0:
                    x[j, 0] -= step * ex
                    x[j, 1] -= step * ey
    return worst


@numba.njit(cache=True, nogil=True)
def _scatter(n: int, rows: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray,
             v: np.ndarray) -> np.ndarray:
    """A_S^T v for the rows ``rows`` (S,) with values v (S,): (n, 2)."""
    z = np.zeros((n, 2))
    for u in range(rows.shape[0]):
        k = rows[u]
        i, j = ri[k], rj[k]
        z[i, 0] += v[u] * re[k, 0]
        z[i, 1] += v[u] * re[k, 1]
        if j >= 0:
            z[j, 0] -= v[u] * re[k, 0]
            z[j, 1] -= v[u] * re[k, 1]
    return z


@numba.njit(cache=True, nogil=True)
def _gather(z: np.ndarray, rows: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray
            ) -> np.ndarray:
    """A_S z for the rows ``rows`` (S,): (S,)."""
    w = np.empty(rows.shape[0])
    for u in range(rows.shape[0]):
        k = rows[u]
        i, j = ri[k], rj[k]
        ux, uy = z[i, 0], z[i, 1]
        if j >= 0:
            ux -= z[j, 0]
            uy -= z[j, 1]
        w[u] = re[k, 0] * ux + re[k, 1] * uy
    return w


@numba.njit(cache=True, nogil=True)
def _phi(x: np.ndarray, rh: np.ndarray, lam: np.ndarray) -> float:
    """The dual objective 1/2 |x|^2 - h^T lam at x = d + A^T lam."""
    total = 0.0
    for a in range(x.shape[0]):
        total += 0.5 * (x[a, 0] * x[a, 0] + x[a, 1] * x[a, 1])
    for k in range(lam.shape[0]):
        total -= rh[k] * lam[k]
    return total


@numba.njit(cache=True, nogil=True)
def face_step(x: np.ndarray, d: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray,
              rh: np.ndarray, lam: np.ndarray, cg_iters: int, passes: int) -> int:
    """Up to ``passes`` face passes (:func:`face_pass`), in place on lam and x: a pass whose
    full step would make multipliers negative drops the rows whose multipliers its projected
    search brings to 0 (an active-set move, phi decreasing), and the next pass works on the
    smaller face. Returns the CG iterations run."""
    total = 0
    for _ in range(passes):
        its, reach = face_pass(x, d, ri, rj, re, rh, lam, cg_iters)
        total += its
        if its == 0 or reach >= 1.0:
            break
    return total


@numba.njit(cache=True, nogil=True)
def face_pass(x: np.ndarray, d: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray,
              rh: np.ndarray, lam: np.ndarray, cg_iters: int) -> tuple[int, float]:
    """One GPCG face step, in place on lam and x (= d + A^T lam on return).

    S = rows with lam_k > 0. Conjugate gradients minimise phi over lam_S (the other
    multipliers held at 0): (A_S A_S^T) p = -(A_S x - h_S), at most ``cg_iters`` iterations.
    Then the projected search along p (:func:`search`). Returns the CG iterations run (0 when
    S is empty or no step decreased phi) and the longest step keeping lam >= 0 (>= 1: the
    full step)."""
    n = x.shape[0]
    rows = face_rows(lam)
    count = rows.shape[0]
    if count == 0:
        return 0, 1.0
    r = face_residual(x, ri, rj, re, rh, rows)  # -(A_S x - h_S)
    p = np.zeros(count)
    dirn = r.copy()
    rr = 0.0
    for u in range(count):
        rr += r[u] * r[u]
    rr0 = rr
    its = 0
    while its < cg_iters and rr > 1e-32 * max(rr0, 1e-300) and rr > 0.0:
        w = _gather(_scatter(n, rows, ri, rj, re, dirn), rows, ri, rj, re)
        dw = 0.0
        for u in range(count):
            dw += dirn[u] * w[u]
        if dw <= 0.0:
            break
        alpha = rr / dw
        rr_new = 0.0
        for u in range(count):
            p[u] += alpha * dirn[u]
            r[u] -= alpha * w[u]
            rr_new += r[u] * r[u]
        beta = rr_new / rr
        rr = rr_new
        for u in range(count):
            dirn[u] = r[u] + beta * dirn[u]
        its += 1
    if its == 0:
        return 0, 1.0
    moved, reach = search(x, d, ri, rj, re, rh, lam, rows, p)
    return (its if moved else 0), reach


@numba.njit(cache=True, nogil=True)
def search(x: np.ndarray, d: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray,
           rh: np.ndarray, lam: np.ndarray, rows: np.ndarray, p: np.ndarray
           ) -> tuple[bool, float]:
    """Projected search along a face direction p (S,) on the rows ``rows`` (S,), in place on
    lam and x (= d + A^T lam on return): lam <- max(0, lam + alpha p) for the first alpha that
    does not increase phi, tried in the order 1, 1/2, 1/4, ... down to the longest step
    keeping every multiplier >= 0 (the reach), then the reach, then halvings of the reach.
    Steps longer than the reach drop every row whose multiplier crosses 0 at once (Moré and
    Toraldo's projected search; stopping at the reach drops one row a pass, which in a deep
    jam takes tens of rounds). Up to the reach phi is convex along p and decreasing to the
    face minimiser, so the reach is always accepted when p is a descent direction. Returns
    whether lam moved and the reach (>= 1: the full step keeps lam >= 0)."""
    count = rows.shape[0]
    phi0 = _phi(x, rh, lam)
    old = lam.copy()
    reach = 1.0
    for u in range(count):
        if p[u] < 0.0 and -old[rows[u]] / p[u] < reach:
            reach = -old[rows[u]] / p[u]
    trials = np.empty(24)
    nt = 0
    step = 1.0
    while step > reach and nt < 12:  # projected steps beyond the reach
        trials[nt] = step
        nt += 1
        step *= 0.5
    trials[nt] = reach
    nt += 1
    while nt < 24:
        trials[nt] = 0.5 * trials[nt - 1]
        nt += 1
    for t in range(nt):
        step = trials[t]
        if step <= 0.0:
            continue
        for u in range(count):
            k = rows[u]
            v = old[k] + step * p[u]
            lam[k] = v if v > 0.0 else 0.0
        trial = apply_multipliers(d, ri, rj, re, lam)
        if _phi(trial, rh, lam) <= phi0 + 1e-15 * abs(phi0):
            x[:, :] = trial
            return True, reach
    lam[:] = old
    return False, reach


@numba.njit(cache=True, nogil=True)
def face_rows(lam: np.ndarray) -> np.ndarray:
    """Indices of the rows with lam_k > 0 (the face), ascending."""
    return np.flatnonzero(lam > 0.0)


@numba.njit(cache=True, nogil=True)
def face_residual(x: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray,
                  rh: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """h_S - A_S x (S,) m: minus the face rows' slacks."""
    w = _gather(x, rows, ri, rj, re)
    for u in range(rows.shape[0]):
        w[u] = rh[rows[u]] - w[u]
    return w


@numba.njit(cache=True, nogil=True)
def _root(parent: np.ndarray, a: int) -> int:
    while parent[a] != a:
        parent[a] = parent[parent[a]]
        a = parent[a]
    return a


@numba.njit(cache=True, nogil=True)
def cluster_labels(n: int, ri: np.ndarray, rj: np.ndarray) -> tuple[np.ndarray, int]:
    """Clusters of agents linked by rows (union-find): a label per agent in 0..count-1, numbered
    in order of each cluster's smallest agent, -1 for agents in no row; and the count."""
    parent = np.arange(n)
    used = np.zeros(n, dtype=np.bool_)
    for k in range(ri.shape[0]):
        used[ri[k]] = True
        if rj[k] >= 0:
            used[rj[k]] = True
            a, b = _root(parent, ri[k]), _root(parent, rj[k])
            if a != b:
                if a < b:
                    parent[b] = a
                else:
                    parent[a] = b
    label = np.full(n, -1, dtype=np.int64)
    count = 0
    for a in range(n):
        if used[a]:
            root = _root(parent, a)
            if label[root] < 0:
                label[root] = count
                count += 1
            label[a] = label[root]
    return label, count


@numba.njit(cache=True, nogil=True)
def cluster_certificates(x: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray,
                         rh: np.ndarray, lam: np.ndarray, label: np.ndarray, clusters: int
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per cluster of agents: sum_k lam_k s_k over its rows (m^2), its smallest slack s_k (m)
    and the sum of its multipliers (m), at x = d + A^T lam (so that r = x - d - A^T lam = 0
    and the duality gap of a cluster whose rows all hold is sum_k lam_k s_k)."""
    comp = np.zeros(clusters)
    low = np.full(clusters, np.inf)
    total = np.zeros(clusters)
    for k in range(ri.shape[0]):
        i, j = ri[k], rj[k]
        ux, uy = x[i, 0], x[i, 1]
        if j >= 0:
            ux -= x[j, 0]
            uy -= x[j, 1]
        s = re[k, 0] * ux + re[k, 1] * uy - rh[k]
        c = label[i]
        comp[c] += lam[k] * s
        total[c] += lam[k]
        if s < low[c]:
            low[c] = s
    return comp, low, total


@numba.njit(cache=True, nogil=True)
def dot(a: np.ndarray, b: np.ndarray) -> float:
    """sum_k a_k b_k of two (K,) vectors, added in index order: the same bits on every CPU
    (BLAS's ddot splits the sum by the vector width the CPU offers)."""
    s = 0.0
    for k in range(a.shape[0]):
        s += a[k] * b[k]
    return s
