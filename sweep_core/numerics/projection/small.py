"""A small scene's projection in one compiled call, when the certified rounds settle it.

On a small scene (a robot among ten people) the projection of a step with a contact builds a
few rows and certifies their QP in a few rounds: microseconds of arithmetic, spread over a
dozen compiled calls (the neighbour search, the pair and wall rows, the residuals, the warm
start's keys, the displacement rows, the rounds, the cutoff test) with Python between them,
which costs ten times more. :func:`small_projection` asks the same kernels the same questions
in the same order in one call: the rows of :func:`~sweep_core.numerics.constraints.linearise`
(its dense branch: ``pairs_into``, ``pair_rows``, ``near_rows``), the residuals and their
summary, the previous step's multipliers carried by contact (:mod:`.warm`), the rounds of
:func:`~sweep_core.numerics.projection.certified.first_rounds`, the residuals at the answer
and the cutoff test of :func:`~sweep_core.numerics.projection.project.project`. Each value is
computed by the same kernel from the same arguments, so the answer has the bits ``project``
gives it.

It answers only the common case; otherwise it returns None and ``project`` runs as before,
from the start (nothing has changed): the rounds stop for a factored face step or leave a
cluster uncertified (the cluster solvers), a row is broken at the answer (``project`` raises,
naming the agents), or the answer moves too far for the cutoff (a wider cutoff). It applies
(:func:`applies`) to at most ``clear.MAX_AGENTS`` agents in a geometry without user
constraints, polygons, moving obstacles or moving half-planes, with the certified method and
no cluster held back from the rounds by the last step.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from sweep_core.model.geometry import DENSE_SEGMENTS, Geometry
from sweep_core.model.neighbours import pairs_into
from sweep_core.model.wall_kernels import near_rows, pair_rows
from sweep_core.numerics.constraints import Rows, displacement_rows, row_agents, row_residuals
from sweep_core.numerics.projection import certified, dual, pairwise
from sweep_core.numerics.projection.clear import MAX_AGENTS
from sweep_core.numerics.projection.options import ROW_TOLERANCE, SolverOptions
from sweep_core.numerics.projection.summaries import largest_step, row_summary
from sweep_core.numerics.projection.warm import carried, row_keys

#: no polygon bounds a segment (``near_rows``' inside argument)
_NO_POLYGON = np.zeros((0, 0), dtype=np.bool_)
#: the previous step's rows when there are none to carry multipliers from
_NO_INDEX = np.empty(0, dtype=np.intp)
_NO_KIND = np.empty(0, dtype=np.int8)
_NO_LAM = np.empty(0)


def applies(geom: Geometry, n: int, opts: SolverOptions, held: bool) -> bool:
    """Whether :func:`small_projection` may answer for ``n`` agents in ``geom`` (the
    geometry at the step's end) with ``opts``; ``held``: the last step held clusters back
    from the rounds (its ``stuck``)."""
    return (2 <= n <= MAX_AGENTS and opts.method == "certified" and not held
            and not geom.user and not geom.is_moving and not geom.has_polygons
            and geom.fixed_halfplanes and n * len(geom.segment_a) <= DENSE_SEGMENTS)


def small_projection(geom: Geometry, q: np.ndarray, pred: np.ndarray, r1: np.ndarray,
                     cut: float, opts: SolverOptions, warm: tuple | None
                     ) -> tuple[np.ndarray, Rows, np.ndarray, np.ndarray, int, int, int,
                                float, int] | None:
    """``project``'s answer for the prediction pred (N, 2) from q (N, 2), radii r1 (N,) m at
    the step's end, rows first built within ``cut`` (m), when the module docstring's common
    case holds: y (N, 2), the rows, their multipliers (pairs, singles), the active rows, the
    QP's agents, the solves (0 or 1), the certified bound (m) and the sweeps; else None.
    warm: the previous step's (rows, pair multipliers, single multipliers) to carry, or None.
    ``geom`` must satisfy :func:`applies`."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    pred = np.ascontiguousarray(pred, dtype=np.float64)
    r1 = np.ascontiguousarray(r1, dtype=np.float64)
    hn, hc, sa, sb, cc, cr = geom.packed
    if warm is None:
        old = (_NO_INDEX, _NO_INDEX, _NO_INDEX, _NO_KIND, _NO_INDEX, _NO_LAM, _NO_LAM, False)
    else:
        rows, lam_p, lam_s = warm
        old = (rows.pair_i, rows.pair_j, rows.single_a, rows.single_kind, rows.single_item,
               np.ascontiguousarray(lam_p, dtype=np.float64),
               np.ascontiguousarray(lam_s, dtype=np.float64), True)
    out = first_pass(q, pred, r1, float(cut), hn, hc, sa, sb, cc, cr, not geom.is_empty,
                   *old, float(opts.tol), int(opts.max_rounds))
    (ok, y, pi, pj, pe, pb, s_a, s_n, s_b, s_kind, s_item, lam, active, qp_size, solves,
     bound, rounds) = out
    if not ok:
        return None
    m = len(pb)
    return (y, Rows(pi, pj, pe, pb, s_a, s_n, s_b, s_kind, s_item), lam[:m], lam[m:], active,
            qp_size, solves, bound, rounds * certified.SWEEPS)


@numba.njit(cache=True, nogil=True)
def first_pass(q: np.ndarray, pred: np.ndarray, r1: np.ndarray, cut: float, hn: np.ndarray,
             hc: np.ndarray, sa: np.ndarray, sb: np.ndarray, cc: np.ndarray, cr: np.ndarray,
             walls: bool, old_i: np.ndarray, old_j: np.ndarray, old_a: np.ndarray,
             old_kind: np.ndarray, old_item: np.ndarray, old_lam_p: np.ndarray,
             old_lam_s: np.ndarray, has_warm: bool, tol: float, max_rounds: int
             ) -> tuple:  # pragma: no cover - compiled
    """:func:`small_projection`'s arithmetic: ``linearise``'s dense rows, then ``project``'s
    first pass (its steps, in its order); the first value False where ``project`` would do
    anything else."""
    n = q.shape[0]
    # linearise: the pairs within 2 max r + cut (r1.max(initial=0.0)), their rows
    r_max = 0.0
    for a in range(n):
        r_max = dual.maximum(r_max, r1[a])
    reach = 2.0 * r_max + cut
    cap = 4 * n
    i = np.empty(cap, dtype=np.intp)
    j = np.empty(cap, dtype=np.intp)
    found = pairs_into(q, reach, i, j)
    if found > cap:
        i = np.empty(found, dtype=np.intp)
        j = np.empty(found, dtype=np.intp)
        found = pairs_into(q, reach, i, j)
    pi, pj = np.empty(found, dtype=np.intp), np.empty(found, dtype=np.intp)
    pe, pb = np.empty((found, 2)), np.empty(found)
    m = pair_rows(q, r1, i[:found], j[:found], cut, pi, pj, pe, pb)
    pi, pj, pe, pb = pi[:m], pj[:m], pe[:m], pb[:m]
    # ... and the walls' and obstacles' rows, kind after kind
    room = n * (hn.shape[0] + sa.shape[0] + cc.shape[0]) if walls else 0
    s_a, s_item = np.empty(room, dtype=np.intp), np.empty(room, dtype=np.intp)
    g, s_n, foot = np.empty(room), np.empty((room, 2)), np.empty(room)
    counts = np.zeros(3, dtype=np.intp)
    ms = 0
    if walls:
        ms = near_rows(q, r1, cut, hn, hc, sa, sb, _NO_POLYGON, cc, cr, s_a, s_item, g, s_n,
                       foot, counts)
    s_a, s_item, s_n = s_a[:ms], s_item[:ms], s_n[:ms]
    s_b = np.empty(ms)
    s_kind = np.empty(ms, dtype=np.int8)
    at = 0
    for kind in range(3):
        for _ in range(counts[kind]):
            s_kind[at] = kind
            at += 1
    for k in range(ms):
        s_b[k] = foot[k] + r1[s_a[k]]
    # project: the residuals at the prediction and their summary
    rp, rs = np.empty(m), np.empty(ms)
    row_residuals(pred, pi, pj, pe, pb, s_a, s_n, s_b, rp, rs)
    worst, active, broken = row_summary(rp, rs)
    lam = np.zeros(m + ms)
    y = pred.copy()
    qp_size = solves = rounds = 0
    bound = 0.0
    ok = True
    if broken:
        qp_size = row_agents(pi, pj, s_a).shape[0]
        count = m + ms
        lam0 = np.zeros(count)
        if has_warm and (old_lam_p.shape[0] + old_lam_s.shape[0]) > 0 and count > 0:
            old_keys = np.empty(old_i.shape[0] + old_a.shape[0], dtype=np.int64)
            row_keys(old_i, old_j, old_a, old_kind, old_item, n, old_keys)
            new_keys = np.empty(count, dtype=np.int64)
            row_keys(pi, pj, s_a, s_kind, s_item, n, new_keys)
            old_lam = np.empty(old_keys.shape[0])
            old_lam[:old_lam_p.shape[0]] = old_lam_p
            old_lam[old_lam_p.shape[0]:] = old_lam_s
            lam0 = carried(old_keys, old_lam, new_keys)
        ri, rj = np.empty(count, dtype=np.int64), np.empty(count, dtype=np.int64)
        re, h = np.empty((count, 2)), np.empty(count)
        displacement_rows(q, pi, pj, pe, pb, s_a, s_n, s_b, ri, rj, re, h)
        d = pred - q
        (lam, _, _, _, counted, _, _, x, _, gap, _, done,
         factor) = certified.first_rounds(d, ri, rj, re, h, lam0, tol, max_rounds)
        if factor or not done.all():  # the factored face step, or the cluster solvers
            ok = False
        else:
            y = pred + (x - d)
            bound = np.sqrt(2.0 * pairwise.numpy_sum(gap))
            solves, rounds = 1, counted[0]
            row_residuals(y, pi, pj, pe, pb, s_a, s_n, s_b, rp, rs)
            worst, active, broken = row_summary(rp, rs)
            # a row broken at the answer: project raises, naming the agents
            ok = bool(np.isfinite(worst)) and not worst < -ROW_TOLERANCE
    if ok:
        moved = math.sqrt(largest_step(q, y, r1)[0])
        margin = bound if np.isfinite(bound) else 0.0
        ok = 2.0 * (moved + margin) <= cut  # else a wider cutoff: project's loop
    return (ok, y, pi, pj, pe, pb, s_a, s_n, s_b, s_kind, s_item, lam, active, qp_size, solves,
            bound, rounds)
