"""Projection onto the linearised feasible set: one convex QP per step (reference §4).

    y = argmin |y - p|^2  subject to the rows of C~(t1, q)   (identity Hessian)

Only agents that appear in a built row enter the QP; all others keep y_i = p_i. Rows are
built inside a cutoff (``constraints.linearise``) and the cutoff is proven sufficient after
the solve: an unbuilt row had value > cut at q, and moves by at most |y_i - q_i| + |y_j - q_j|
<= 2 max_i |y_i - q_i|, so if that is <= cut every unbuilt row holds at y; otherwise the
cutoff grows and the QP is solved again. Projecting onto a superset and landing inside the
set gives the projection onto the set. With an approximate answer y, within ``bound`` of the
superset's projection y*, the test is 2 (max_i |y_i - q_i| + bound) <= cut, so that y* itself
lands inside the set (an answer left uncertified, bound inf, is only proven feasible).

How the QP is solved (``SolverOptions.method``): "certified" runs the compiled dual sweeps of
:mod:`.certified` on every row at once, and sends the clusters they cannot certify within
``tol`` to the cluster solvers of :mod:`.clusters` (exact active set, interior point);
"clusters" uses those alone. Either way every answer gets the duality-gap certificate of
:mod:`.dual`, and ``Projection.bound`` is the proved bound on |y - y*|. A cluster solver's
answer whose bound is above its share of ``tol`` is refined (:mod:`.refine`: the QP solved
again around it, magnified) and, failing that, polished (:mod:`.polish`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from sweep_core.errors import InfeasibleError
from sweep_core.model.geometry import Geometry
from sweep_core.numerics.constraints import Rows, linearise
from sweep_core.numerics.projection import certified, dual, polish, refine, small
from sweep_core.numerics.projection.clear import clear_active
from sweep_core.numerics.projection.clusters import row_matrix, solve_qp
from sweep_core.numerics.projection.options import ROW_TOLERANCE, SolverOptions
from sweep_core.numerics.projection.summaries import largest_step, row_summary
from sweep_core.numerics.projection.warm import carry_multipliers

#: a cluster the certified rounds left to the cluster solvers is sent there directly on the
#: following steps, and given the rounds again on one step in RETRY
RETRY = 10
#: rounds at most on a retry (a jam that has become solvable certifies in 4 to 10; the rounds
#: of a cluster that has not cost a few times the backend's solve otherwise)
RETRY_ROUNDS = 10


@dataclass(frozen=True)
class Projection:
    """Result of one projection.

    y: (N, 2) projected positions (m); rows: the rows built; lam_pair (P,), lam_single (M,):
    multipliers (>= 0, m) of the rows, the reaction of each contact is lam * gradient;
    active: number of rows that hold with equality (residual <= ROW_TOLERANCE); qp_size: number
    of agents in the QP (0 when the prediction was already feasible); solves: QP solves done
    (one per cutoff tried); backend_agents: agents whose cluster was solved by the
    interior-point backend; bound: proved bound (m) on the distance from y to the exact
    projection onto the linearised set (0 when the prediction was feasible; ``inf`` if a
    cluster could not be certified); sweeps: Gauss-Seidel sweeps; fallback_agents: agents of
    the clusters the sweeps left to the cluster solvers; stuck: (N,) bool, the agents of those
    clusters (None: none), and stuck_steps: consecutive steps that have sent clusters holding
    them straight to the cluster solvers (``RETRY``).
    """

    y: np.ndarray
    rows: Rows
    lam_pair: np.ndarray
    lam_single: np.ndarray
    active: int
    qp_size: int
    solves: int
    backend_agents: int = 0
    bound: float = 0.0
    sweeps: int = 0
    fallback_agents: int = 0
    stuck: np.ndarray | None = None
    stuck_steps: int = 0


_NONE = np.empty(0)
#: the rows of a projection that built none (arrays of length 0: nothing to write in them)
NO_ROWS = Rows(np.empty(0, np.intp), np.empty(0, np.intp), np.empty((0, 2)), np.empty(0),
               np.empty(0, np.intp), np.empty((0, 2)), np.empty(0), np.empty(0, np.int8),
               np.empty(0, np.intp))


def first_cutoff(q: np.ndarray, pred: np.ndarray, r1: np.ndarray) -> float:
    """The cutoff (m) rows are first built with: 3 max_i |p_i - q_i| + 1e-3 max r.

    A margin beyond the provable 2 max|p - q|: a projection usually moves agents a little
    further than their prediction, and a second build costs more than a few extra rows."""
    # the largest |p_i - q_i| is the square root of the largest square (sqrt is monotone and
    # correctly rounded, so the bits are those of the largest root)
    square, r_max = largest_step(np.ascontiguousarray(q, dtype=np.float64),
                                 np.ascontiguousarray(pred, dtype=np.float64),
                                 np.ascontiguousarray(r1, dtype=np.float64))
    return 3.0 * math.sqrt(square) + 1e-3 * r_max


def project(geom: Geometry, t1: float, q: np.ndarray, pred: np.ndarray, r1: np.ndarray,
            opts: SolverOptions, warm: Projection | None = None) -> Projection:
    """Project the prediction pred (N, 2) onto C~(t1, q); q (N, 2) at t_n, r1 (N,) at t1.

    warm: the previous step's projection, whose multipliers start this one (matched by
    contact) when ``opts.warm_start``. Raises InfeasibleError (naming t1 and the agents) if the
    QP has no solution.
    """
    n = len(q)
    if n == 0:
        empty = linearise(geom, t1, q, r1, 0.0)
        return Projection(pred.copy(), empty, np.empty(0), np.empty(0), 0, 0, 0)
    cut = first_cutoff(q, pred, r1)
    solves = 0
    # clusters holding agents whose cluster the rounds could not certify last step go straight
    # to the cluster solvers, but for one step in RETRY (a jam that has become solvable, or a
    # cluster that only stalled for a while, gets the rounds again)
    held_for = warm.stuck_steps if warm is not None and warm.stuck is not None else 0
    skip = (warm.stuck if warm is not None and warm.stuck is not None and len(warm.y) == n
            and held_for + 1 < RETRY else None)
    # a small scene whose prediction holds every row: the answer is the prediction (no QP,
    # no multiplier), found without building the rows; the cutoff holds (2 max|p - q| <= cut,
    # first_cutoff), so the loop below would stop at once
    active = clear_active(geom, q, pred, r1, cut)
    if active >= 0:
        return Projection(pred.copy(), NO_ROWS, _NONE, _NONE, active, 0, 0, 0, 0.0, 0, 0, None,
                          held_for + 1 if skip is not None else 0)
    if small.applies(geom, n, opts, warm is not None and warm.stuck is not None):
        # a small scene's first pass in one compiled call (the same kernels, the same bits);
        # None where it would solve more than the rounds certify, or widen the cutoff
        carry = ((warm.rows, warm.lam_pair, warm.lam_single)
                 if opts.warm_start and warm is not None and len(warm.y) == n else None)
        fast = small.small_projection(geom, q, pred, r1, cut, opts, carry)
        if fast is not None:
            y, rows, lam_p, lam_s, active, qp_size, solves, bound, sweeps = fast
            return Projection(y, rows, lam_p, lam_s, active, qp_size, solves, 0, bound, sweeps)
    todo = np.zeros(n, dtype=bool)
    built: Rows | None = None  # the rows of the wider cutoff, when already built
    while True:
        rows = built if built is not None else linearise(geom, t1, q, r1, cut)
        rp, rs = rows.residuals(pred)
        summary = row_summary(rp, rs)  # (worst, active rows, a row broken) of rp, rs
        lam_p, lam_s = np.zeros(len(rp)), np.zeros(len(rs))
        y = pred.copy()
        qp_size = by_backend = sweeps = fallback = 0
        bound = 0.0
        if summary[2]:
            qp_size = len(rows.agents())
            start = (carry_multipliers(warm.rows, np.concatenate([warm.lam_pair,
                                                                  warm.lam_single]), rows, n)
                     if opts.warm_start and warm is not None and len(warm.y) == n else None)
            solved = _solve(rows, q, pred, opts, start, skip,
                            RETRY_ROUNDS if held_for and skip is None else None)
            solves += 1
            y, lam, bound, by_backend, sweeps, todo, ok = solved
            fallback = int(np.count_nonzero(todo))
            lam_p, lam_s = lam[: len(rp)], lam[len(rp):]
            rp, rs = rows.residuals(y)
            summary = row_summary(rp, rs)
            worst = summary[0]
            if not ok or not np.isfinite(worst) or worst < -ROW_TOLERANCE:
                why = "no feasible point" if not ok else "solver residual"
                raise InfeasibleError(t1, _culprits(rows, rp, rs),
                                      f"{why}, worst row residual {worst:.3g} m")
        # sqrt of the largest square: the bits of the largest root (first_cutoff)
        moved = math.sqrt(largest_step(np.ascontiguousarray(q, dtype=np.float64),
                                       np.ascontiguousarray(y, dtype=np.float64),
                                       np.ascontiguousarray(r1, dtype=np.float64))[0])
        # an uncertified answer (bound inf) claims nothing about y*: only y must hold the
        # unbuilt rows (an infinite cutoff would build every pair of the crowd)
        margin = bound if np.isfinite(bound) else 0.0
        if 2.0 * (moved + margin) <= cut:
            break
        cut = 3.0 * (moved + margin)
        built = linearise(geom, t1, q, r1, cut)
        if _new_rows_hold(rows, built, y, margin):
            break
    # a row is active when it holds with equality (to the solver tolerance); an interior-point
    # solver leaves tiny positive multipliers on slack rows, so multipliers are not counted
    active = summary[1]
    stuck = todo if todo.any() else None
    return Projection(y, rows, lam_p, lam_s, active, qp_size, solves, by_backend, bound,
                      sweeps, fallback, stuck, held_for + 1 if skip is not None else 0)


def _new_rows_hold(rows: Rows, more: Rows, y: np.ndarray, margin: float) -> bool:
    """Whether y (N, 2), the projection onto ``rows`` (within ``margin`` m of it, 0 when
    uncertified), is also the projection onto C~ (t1, q), given ``more``, the rows of a wider
    cutoff (3 (moved + margin)): the rows unbuilt there hold at y* by the cutoff test
    (2 (moved + margin) <= cutoff), and each row of ``more`` not in ``rows`` is checked at y
    with room for y*, whose distance to y is at most margin and moves a row's value by at most
    sqrt(2) margin (|a_k| <= sqrt 2). Then y* lies in C~, a subset of the set it is the
    projection onto, so it is the projection onto C~ too, and the QP need not be solved again
    with the wider rows: in a jam at a door, where the crowd pushes some agents further than
    their prediction, one step in seven did."""
    n = len(y)
    old_pairs = rows.pair_i.astype(np.int64) * n + rows.pair_j
    new_pairs = ~np.isin(more.pair_i.astype(np.int64) * n + more.pair_j, old_pairs)
    kinds = int(max(more.single_kind.max(initial=0), rows.single_kind.max(initial=0))) + 1

    def key(r: Rows) -> np.ndarray:
        return (r.single_item.astype(np.int64) * kinds + r.single_kind) * n + r.single_a

    new_singles = ~np.isin(key(more), key(rows))
    rp, rs = more.select(new_pairs, new_singles).residuals(y)
    need = float(np.sqrt(2.0)) * margin
    return bool(rp.min(initial=np.inf) >= need and rs.min(initial=np.inf) >= need)


def _solve(rows: Rows, q: np.ndarray, pred: np.ndarray, opts: SolverOptions,
           start: np.ndarray | None, skip: np.ndarray | None, cap: int | None = None
           ) -> tuple[np.ndarray, np.ndarray, float, int, int, np.ndarray, bool]:
    """The QP of ``rows``: y (N, 2), multipliers (K,), certified bound (m), agents solved by
    the interior-point backend, Gauss-Seidel sweeps, the agents (N,) bool of the clusters left
    to the cluster solvers, and whether every cluster was solved. skip: (N,) bool or None,
    agents whose clusters go to the cluster solvers without the certified rounds; cap: the
    rounds at most (None: ``opts.max_rounds``)."""
    n = len(q)
    ri, rj, re, h = rows.displacement_rows(q)
    d = pred - q
    lam0 = start if start is not None else np.zeros(len(ri))
    rounds = opts.max_rounds if opts.method == "certified" else 0
    if cap is not None:
        rounds = min(rounds, cap)
    held = None  # rows of the clusters that skip the rounds (None: none)
    if skip is not None and rounds > 0:
        label, clusters = dual.cluster_labels(n, ri, rj)
        hit = np.zeros(clusters, dtype=bool)
        hit[label[skip & (label >= 0)]] = True
        held = hit[label[ri]]
        if not held.any():
            held = None
    if held is None:  # every row to the rounds, as they are (their clusters and floor too)
        res = certified.solve(d, ri, rj, re, h, lam0, tol=opts.tol, max_rounds=rounds)
        if res.done.all():  # every cluster certified: no cluster solver, nothing to improve
            return (pred + (res.x - d), res.lam, float(np.sqrt(2.0 * res.gap.sum())), 0,
                    res.sweeps, np.zeros(n, dtype=bool), True)
        lam = res.lam.copy()
        label, clusters, floor = res.label, res.clusters, res.floor
    else:
        free = ~held
        res = certified.solve(d, ri[free], rj[free], re[free], h[free], lam0[free],
                              tol=opts.tol, max_rounds=rounds)
        lam = np.zeros(len(ri))
        lam[free] = res.lam
        floor = certified.rounding_floor(d, h)
    x = res.x
    by_backend = 0
    ok = True
    # the agents of the clusters not certified (and of the held ones)
    agent_todo = ((res.label >= 0) & ~res.done[np.maximum(res.label, 0)]
                  if not res.done.all() else np.zeros(n, dtype=bool))
    if held is not None:
        agent_todo |= np.bincount(np.concatenate([ri[held], rj[held][rj[held] >= 0]]),
                                  minlength=n)[:n] > 0
    if not agent_todo.any():
        gap = res.gap
    else:
        # the clusters not certified: the cluster solvers, in absolute coordinates
        agents, c, picked = _sub_qp(rows, agent_todo)
        # in displacement coordinates (the rows' bounds h, small numbers), tightened by the
        # skin, so that an answer exact up to rounding holds every true row
        xs, lam_sub, ok, by_backend = solve_qp(d[agents].ravel(), c, h[picked] + res.skin,
                                               opts)
        lam[picked] = lam_sub
        x, gap = _certified_point(d, ri, rj, re, h, lam, label, clusters, agents, xs, opts.tol,
                                  floor)
    bound = float(np.sqrt(2.0 * gap.sum()))
    if ok and bound > opts.tol:
        x, lam, gap = _improve(rows, d, ri, rj, re, h, x, lam, gap, label, clusters, opts.tol,
                               floor, agent_todo)
        bound = float(np.sqrt(2.0 * gap.sum()))
    # y = p + A^T lam (+ r): agents in no row, or with no multiplier, keep their prediction
    # bit for bit
    y = pred + (x - d)
    return y, lam, bound, by_backend // 2, res.sweeps, agent_todo, ok


def _certified_point(d: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray,
                     h: np.ndarray, lam: np.ndarray, label: np.ndarray, clusters: int,
                     agents: np.ndarray, xs: np.ndarray, tol: float, floor: float
                     ) -> tuple[np.ndarray, np.ndarray]:
    """x (N, 2): d + A^T lam, with the cluster solvers' own answer xs (2 per agent of
    ``agents``) there, and the gap (m^2) of each cluster for x and lam."""
    x = dual.apply_multipliers(d, ri, rj, re, lam)
    # the cluster solvers' own x, where it differs from d + A^T lam by more than rounding (an
    # interior point's multipliers do not reproduce its x exactly), is kept with the residual
    # term 1/2 |r|^2 of the certificate
    r = xs.reshape(-1, 2) - x[agents]
    x[agents] += r
    gap, _, _, _ = certified.certify(x, ri, rj, re, h, lam, label, clusters, tol, floor)
    gap = gap + 0.5 * np.bincount(label[agents], weights=(r ** 2).sum(axis=1),
                                  minlength=clusters)
    return x, gap


def _improve(rows: Rows, d: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray,
             h: np.ndarray, x: np.ndarray, lam: np.ndarray, gap: np.ndarray, label: np.ndarray,
             clusters: int, tol: float, floor: float, solved: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The clusters of the agents ``solved`` (N,) bool by the cluster solvers whose gap is
    above their share of tol (an interior point's answer): refined (the QP solved again
    around the answer, magnified, :mod:`.refine`), and where that does not prove tol, moved
    towards the projection (:mod:`.polish`); each kept per cluster where the certificate
    proves it closer. x (N, 2), lam (K,), gap (clusters,) in and out. (The rounds' clusters
    are left as they are: where the rounding floor of their skin sets their budget, refining
    them doubled the step of a 1000-agent jam of radii 0.20-0.27 m at a door.)"""
    share = certified.budgets(label, clusters, np.bincount(label[ri], weights=lam,
                                                           minlength=clusters), tol, 0.0)
    over = gap > share
    todo = solved & (label >= 0) & over[np.maximum(label, 0)]
    if not todo.any():
        return x, lam, gap
    agents, c, picked = _sub_qp(rows, todo)
    refined = refine.refine(d[agents].ravel(), x[agents].ravel(), c, h[picked])
    if refined is not None:
        lam2 = lam.copy()
        lam2[picked] = refined[1]
        x2, gap2 = _certified_point(d, ri, rj, re, h, lam2, label, clusters, agents, refined[0],
                                    tol, floor)
        x, lam, gap = _keep_better(x, lam, gap, x2, lam2, gap2, label, ri)
    if float(np.sqrt(2.0 * gap.sum())) > tol:
        moved = polish.shrink(x[agents].ravel(), c, h[picked], floor)
        x2, gap2 = _certified_point(d, ri, rj, re, h, lam, label, clusters, agents, moved, tol,
                                    floor)
        x, lam, gap = _keep_better(x, lam, gap, x2, lam, gap2, label, ri)
    return x, lam, gap


def _sub_qp(rows: Rows, todo: np.ndarray) -> tuple[np.ndarray, sp.csc_matrix, np.ndarray]:
    """The rows holding the agents ``todo`` (N,) bool as one QP: its agents (m,), the row
    matrix C (rows x 2m) and which of ``rows`` (pairs, then walls) it holds (bool)."""
    pick_p, pick_s = todo[rows.pair_i], todo[rows.single_a]
    sub = rows.select(pick_p, pick_s)
    agents = sub.agents()
    loc = np.full(len(todo), -1, dtype=np.intp)
    loc[agents] = np.arange(len(agents))
    c, _ = row_matrix(sub, loc, len(agents))
    return agents, c, np.concatenate([pick_p, pick_s])


def _keep_better(x: np.ndarray, lam: np.ndarray, gap: np.ndarray, x2: np.ndarray,
                 lam2: np.ndarray, gap2: np.ndarray, label: np.ndarray, ri: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per cluster, the point and multipliers of the smaller gap: x (N, 2), lam (K,), gap
    (clusters,) (m^2); label: the cluster of each agent (-1: none), ri: the first agent of each
    row."""
    better = gap2 < gap
    take = better[label] & (label >= 0)
    rows = better[label[ri]]
    x, lam = x.copy(), lam.copy()
    x[take] = x2[take]
    lam[rows] = lam2[rows]
    return x, lam, np.where(better, gap2, gap)


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
