"""Iterative refinement of a cluster solver's answer: the same QP solved again in coordinates
centred on that answer and magnified, so that the rows come out exact to a few ulp.

Why. An interior point holds the rows of a jam only to about 1e-13 m: its tolerances are
relative to the data, displacements of a few centimetres. The certificate's gap is at least
sum_k lam_k s_k(x), and in a 1000-agent jam at a door the multipliers sum to about 420 m, so
the bound of such an answer is 2.9e-5 m however close x is. Near-active rows of a jam of equal
disks are dependent (more loaded rows than coordinates) and their bounds slightly
inconsistent, so no linear solve brings all their slacks to zero: which of them the exact
projection leaves slack is a question for the QP itself (docs/jam_solvers.md).

How (the iterative refinement of Gleixner, Steffy and Wolter for linear programs, INFORMS J.
Computing 28(3), 2016, applied to this QP). With x^ the answer, s^ = C x^ - h its slacks and
W the rows of slack below ``NEAR``, substitute x = x^ + v / D (D in ``SCALES``): up to a
constant and the factor D,

    min  (x^ - t) . v + 1/(2 D) |v|^2   s.t.   C_W v >= -D (s^_W - skin)

is the QP restricted to W, exactly, with right-hand sides D times those of the original (whose
near-active slacks are about 1e-12 m): a second interior-point solve is accurate relative to
them, so the rows of x^ + v / D hold to about its tolerance over D, far below rounding. Its
multipliers are the QP's (the objective keeps its scale). The skin, a few ulp of the displacements, keeps the
rounding of x^ + v / D from breaking a row. Rows left out of W had a slack of at least
``NEAR`` and v / D is far smaller; nothing here is trusted anyway: the caller certifies the
result and keeps it per cluster only where its proved bound is smaller.

Measured on 1000-agent jams of equal disks at a door (2400 loaded rows): the bound of PIQP's
answer, 2.9e-5 m (5.6e-6 to 6.7e-6 m after :mod:`.polish`), becomes about 2e-7 m, for a
solve of 13 to 18 iterations (25 to 40 ms, about half the first solve).
"""
from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

from sweep_core.numerics.projection import pivot

#: rows with a slack below this (m) enter the refined QP. An interior point leaves small
#: multipliers on rows of slack up to about 1e-9 m; left out, their agents' correction is
#: free and the refined QP wanders (rows broken by 1e-8 m on 5 of 62 jammed steps with 1e-9)
NEAR = 1e-6
#: magnifications of the correction, tried in turn until PIQP reports the refined QP solved:
#: its right-hand sides are at most NEAR x D (at 1e6 PIQP reached its iteration cap on
#: some jams; at 1e4 it wandered off on one QP in about 200 and solved it at 1e3). The larger
#: D, the more exact the rows: on 1000-agent jams of equal disks at a door the bound was
#: 1.5-2.3e-7 m at 1e10, 1.9-4.3e-7 m at 1e9, 3.6e-7-1.3e-6 m at 1e8. On two steps of the
#: polydisperse jam PIQP reached its cap at 1e10 and 1e9 (bounds 1.1e-6 and 2.4e-6 m) and
#: solved the QP at 1e8 in 8 to 10 iterations (1.4e-7 and 1.8e-7 m)
SCALES = (1e10, 1e9, 1e8)
#: the skin (m) in ulp of the largest displacement: it keeps the rounding of x^ + v / D (about
#: half an ulp a coordinate; the refined rows of 1000-agent jams came out within 0.3 ulp of
#: their skin) from breaking a row, and costs skin x sum(lam) in the gap: 1.8e-14 m^2 on a
#: 1000-agent jam at a door, a bound of 1.9e-7 m (16 ulp: 3.3e-7 m)
SKIN_ULPS = 4.0
#: PIQP's settings for the refined QP, in its scaled units: rows to 1e-8 / D m, the
#: stationarity to 1e-8 m, the duality gap to 1e-4 / D m^2 (far below the skin's cost); a
#: solve takes 10 to 25 iterations; the regularisation's floor is :data:`.pivot.SETTINGS`'s
SETTINGS: dict[str, float | bool | int] = {
    "eps_abs": 1e-8, "eps_rel": 0.0, "eps_duality_gap_abs": 1e-4,
    "eps_duality_gap_rel": 0.0, "check_duality_gap": True, "max_iter": 40,
    "reg_lower_limit": pivot.SETTINGS["reg_lower_limit"]}


def skin(x: np.ndarray) -> float:
    """The refined rows' skin (m) for an answer x (n,) of displacements (m)."""
    return SKIN_ULPS * float(np.finfo(float).eps) * max(float(np.abs(x).max(initial=0.0)), 1e-3)


def refine(target: np.ndarray, x: np.ndarray, c: sp.spmatrix, h: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray] | None:
    """One refinement of x (n,), an approximate solution of min 1/2 |x - target|^2 s.t.
    c x >= h (c: (m, n) rows, h: (m,) bounds, m): the refined x (n,) and multipliers (m,),
    zero off the near-active rows; None when no row is near-active or the solves gave nothing
    finite. The magnifications of ``SCALES`` are tried until PIQP reports one solved; of the
    answers so far, the one of the smallest duality gap (:func:`gap`) is returned (an answer
    cut short by PIQP's iteration cap can be closer than a solved one at a smaller D; the
    caller's certificate judges it). By PIQP's baseline build (the same bits on every x86-64
    CPU)."""
    cr = sp.csr_matrix(c)
    s = cr @ x - h
    near = np.flatnonzero(s < NEAR)
    if len(near) == 0:
        return None
    n = len(x)
    piqp = pivot.baseline()
    answers: list[tuple[np.ndarray, np.ndarray]] = []
    for scale in SCALES:
        solver = piqp.SparseSolver()
        for key, value in SETTINGS.items():
            setattr(solver.settings, key, value)
        solver.settings.verbose = False
        # PIQP's form: min 1/2 v' P v + g' v  s.t.  G v <= b
        solver.setup((1.0 / scale) * sp.identity(n, format="csc"),
                     np.asarray(x - target, dtype=float), sp.csc_matrix((0, n)), np.zeros(0),
                     sp.csc_matrix(-cr[near]), None, scale * (s[near] - skin(x)), None, None)
        status = solver.solve()
        v = np.array(solver.result.x, dtype=float)
        lam_near = np.maximum(np.array(solver.result.z_u, dtype=float), 0.0)
        if np.all(np.isfinite(v)) and np.all(np.isfinite(lam_near)):
            lam = np.zeros(len(h))
            lam[near] = lam_near
            answers.append((x + v / scale, lam))
            if status == piqp.PIQP_SOLVED:
                break
    if len(answers) <= 1:  # the usual case, solved at the first magnification: no choice
        return answers[0] if answers else None
    return min(answers, key=lambda a: gap(target, cr, h, *a))


def gap(target: np.ndarray, c: sp.csr_matrix, h: np.ndarray, x: np.ndarray, lam: np.ndarray
        ) -> float:
    """The duality gap (m^2) of a point x (n,) and multipliers lam (m,) >= 0 for min 1/2
    |x - target|^2 s.t. c x >= h: 1/2 |x - target - c^T lam|^2 + lam . (c x - h), or inf
    when x breaks a row. In floating point: it ranks candidate answers, it proves nothing (the
    projection's certificate does)."""
    s = c @ x - h
    if not np.all(s >= 0.0):
        return math.inf
    r = x - target - c.T @ lam
    # correctly rounded sums (not BLAS's dot, whose order depends on the CPU), so that the
    # same candidate is chosen on every CPU
    return 0.5 * math.fsum(r * r) + math.fsum(lam * s)
