"""The projection with weights: min sum_i w_i |y_i - p_i|^2 over the linearised rows, for a
scene with a robot of finite weight other than 1.

With z_i = sqrt(w_i) (y_i - q_i) the objective is |z - sqrt(w) (p - q)|^2 again (identity
Hessian) and the rows <a, y - q> >= h become rows of A diag(1 / sqrt(w)) (column scaling): the
cluster solvers of :mod:`sweep_core.numerics.projection.clusters` (closed form for a single row,
the exact active set, the interior-point backend for large clusters) solve that, and y = q +
z / sqrt(w). The multipliers are those of the weighted problem: w_i (y_i - p_i) = sum_k lam_k
a_ki, so a person's (w = 1) reaction is lam e as in the unweighted case. The cutoff of the rows
is proven sufficient as in :func:`~sweep_core.numerics.projection.project` (the argument does
not depend on the metric).

``Projection.bound`` is proved as in the unweighted case, on the z problem: for any z with every
row held (C z >= h) and any lam >= 0, 1/2 |z - z*|^2 <= f(z) - D(lam) = 1/2 |z - d - C^T lam|^2 +
lam . (C z - h), the duality gap of the strongly convex objective (modulus 1); and
|y - y*| <= max_i (1 / sqrt(w_i)) |z - z*|. It is inf when a row is broken, even by rounding
(the answer then only holds the rows to the row tolerance, as checked).
"""
from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

from sweep_core.errors import InfeasibleError
from sweep_core.model.geometry import Geometry
from sweep_core.numerics.constraints import linearise
from sweep_core.numerics.projection import Projection, SolverOptions, first_cutoff
from sweep_core.numerics.projection.clusters import row_matrix, solve_qp
from sweep_core.numerics.projection.options import ROW_TOLERANCE


def project_weighted(geom: Geometry, t1: float, q: np.ndarray, pred: np.ndarray,
                     r1: np.ndarray, weights: np.ndarray, opts: SolverOptions) -> Projection:
    """Project pred (N, 2) onto C~(t1, q) in the metric of ``weights`` (N,) (> 0, finite);
    q (N, 2) at t_n, r1 (N,) at t1. Raises InfeasibleError when the QP has no solution."""
    n = len(q)
    cut = first_cutoff(q, pred, r1)
    solves = 0
    while True:
        rows = linearise(geom, t1, q, r1, cut)
        rp, rs = rows.residuals(pred)
        y = pred.copy()
        lam_p, lam_s = np.zeros(len(rp)), np.zeros(len(rs))
        qp_size = by_backend = 0
        bound = 0.0  # no row broken by the prediction: y = pred is the projection
        if (len(rp) and rp.min() < 0) or (len(rs) and rs.min() < 0):
            agents = rows.agents()
            qp_size = len(agents)
            loc = np.full(n, -1, dtype=np.intp)
            loc[agents] = np.arange(len(agents))
            c, b = row_matrix(rows, loc, len(agents))
            q_a = q[agents].ravel()
            h = b - c @ q_a
            scale = np.repeat(1.0 / np.sqrt(weights[agents]), 2)
            cs = sp.csc_matrix(c @ sp.diags(scale))
            dz = (pred[agents].ravel() - q_a) / scale
            z, lam, ok, by_backend = solve_qp(dz, cs, h, opts)
            solves += 1
            gap = _gap(cs, z, dz, h, lam)
            bound = float(scale.max() * math.sqrt(2.0 * gap)) if math.isfinite(gap) else math.inf
            y[agents] = (q_a + z * scale).reshape(-1, 2)
            lam_p, lam_s = lam[: len(rp)], lam[len(rp):]
            rp, rs = rows.residuals(y)
            worst = min(rp.min(initial=np.inf), rs.min(initial=np.inf))
            if not ok or not np.isfinite(worst) or worst < -ROW_TOLERANCE:
                raise InfeasibleError(t1, agents[:6].tolist(), "no feasible point (weighted), "
                                      f"worst row residual {worst:.3g} m")
        moved = float(np.sqrt(np.einsum("ij,ij->i", y - q, y - q)).max(initial=0.0))
        if 2.0 * moved <= cut:
            break
        cut = 3.0 * moved
    active = int(np.count_nonzero(rp <= ROW_TOLERANCE) + np.count_nonzero(rs <= ROW_TOLERANCE))
    return Projection(y, rows, lam_p, lam_s, active, qp_size, solves, by_backend // 2, bound)


def _gap(c: sp.csc_matrix, z: np.ndarray, d: np.ndarray, h: np.ndarray, lam: np.ndarray
         ) -> float:
    """Duality gap (m^2) of z (2M,) and lam (K,) for min 1/2 |z - d|^2 s.t. c z >= h: inf when
    a row is broken or lam is negative or not finite."""
    slack = c @ z - h
    if not (np.all(np.isfinite(lam)) and np.all(lam >= 0.0) and np.all(np.isfinite(slack))):
        return math.inf
    if len(slack) and float(slack.min()) < 0.0:
        return math.inf
    r = z - d - c.T @ lam
    # exact sums of correctly rounded products: the same bits on every CPU
    return 0.5 * math.fsum((r * r).tolist()) + math.fsum((lam * slack).tolist())
