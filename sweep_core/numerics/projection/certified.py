"""The certified solve of one step's QP: the compiled dual iterations of :mod:`.dual`, and the
duality-gap certificate deciding, cluster by cluster, when an answer is good enough.

Certificate (strong convexity of 1/2 |x - d|^2). For x feasible (every s_k = <a_k, x> - h_k
>= 0) and any lam >= 0, with r = x - d - A^T lam,

    gap = 1/2 |r|^2 + sum_k lam_k s_k     and     |x - x*| <= sqrt(2 gap),

x* the exact projection: gap bounds f(x) - f(x*) from above (weak duality) and f is
1-strongly convex with x* its minimiser over the feasible set. Here x = d + A^T lam is
recomputed from the multipliers, so r = 0 up to rounding (about 1e-18 m in displacement
coordinates) and gap = sum_k lam_k s_k. Clusters of agents linked by rows are independent
QPs, so the gap splits into one term per cluster, and a cluster is done when its term is
within its share of the budget tol^2 / 2.

The dual iterations converge to a point whose rows hold only up to rounding, never certifiably
(s_k a few 1e-17 m negative). So they solve the QP with every row tightened by a skin delta
(h_k + delta): once the tightened rows hold to within delta, the true rows hold (s_k >= 0),
and the skin costs at most 2 delta sum_k lam_k in the gap. delta is chosen so that this cost is
an eighth of the budget (delta = tol^2 / (16 sum lam)), at most 1e-8 tol (so that a few
contacts, whose budget is large, are still solved to near rounding: 1e-14 m at the default
tol), and never below the rounding of a slack (``rounding_floor``); where that floor
dominates (tens of thousands of agents in one deep jam at tol = 1e-6) the bound reported is
the honest, larger one.

Per step: start from the previous step's multipliers (:mod:`.warm`); repeat rounds of
``SWEEPS`` projected Gauss-Seidel sweeps and one face step; after each round certify every
cluster. The face step is conjugate gradients on the rows with lam > 0 (at most ``CG_ITERS``
iterations, ``PASSES`` passes) while the face is still changing, and the factored Newton step
of :mod:`.factored` once the sweeps leave it as the previous round did (the active rows are
found; what remains is a linear system that plain conjugate gradients solve slowly). Stop
when all are done, after ``max_rounds`` rounds, or when ``STALL`` rounds in a row have not
lowered the largest gap; the clusters not done go to the caller's exact or interior-point
solvers.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from sweep_core.numerics.projection import dual, factored, pairwise

#: projected Gauss-Seidel sweeps per round (they find the active rows)
SWEEPS = 10
#: conjugate-gradient iterations of a round's face step (Newton on the active rows)
CG_ITERS = 50
#: face passes of a round (each drops the rows whose multipliers reach 0)
PASSES = 4
#: rounds without progress of the largest gap after which the rounds stop (with the projected
#: search and the factored face step a non-degenerate jam certifies in 4 to 10 rounds, the
#: bundled door scene in at most 5; a degenerate hexagonal lattice never does, and every
#: stalled round is time lost before the cluster solvers: docs/jam_solvers.md)
STALL = 4
#: the spacing of doubles at 1
EPS = float(np.finfo(float).eps)


@dataclass
class Certified:
    """x (N, 2) displacements (m); lam (K,) multipliers (m); label (N,) cluster of each agent
    (-1: in no row); gap (clusters,) duality gap of each (m^2, inf: a row violated); budget
    (clusters,) the gap each may keep; done (clusters,) gap <= budget; rounds: rounds run;
    skin: the skin delta of the last round (m); floor: :func:`rounding_floor` of d and h."""

    x: np.ndarray
    lam: np.ndarray
    label: np.ndarray
    gap: np.ndarray
    budget: np.ndarray
    done: np.ndarray
    rounds: int
    skin: float
    floor: float

    @property
    def clusters(self) -> int:
        return len(self.gap)

    @property
    def sweeps(self) -> int:
        """Gauss-Seidel sweeps run (``SWEEPS`` a round)."""
        return self.rounds * SWEEPS


def rounding_floor(d: np.ndarray, h: np.ndarray) -> float:
    """Smallest skin (m) that rounding cannot eat: 64 ulp of the step's scale, the largest
    displacement d (N, 2) or positive bound h (K,) (m).

    A row that can hold with equality has |<a_k, x>| = |h_k|, and x (from the compensated
    :func:`dual.apply_multipliers`) is exact up to its own last bits, so its slack is computed
    to a few ulp of the displacements. Rows with a negative bound (pairs apart by up to the
    cutoff) have slacks of about |h_k| and never need the skin, so they do not set the scale:
    with them the floor was 3 times larger in a jam at a door (bounds down to -0.15 m against
    displacements of 0.05 m), and the skin's cost in the gap, 4 floor sum lam, kept the bound
    of half the steps of a 1000-agent jam of radii 0.20-0.27 m above 1e-6 m."""
    return floor_of(np.ascontiguousarray(d, dtype=np.float64).reshape(-1, 2),
                    np.ascontiguousarray(h, dtype=np.float64))


@numba.njit(cache=True, nogil=True)
def floor_of(d: np.ndarray, h: np.ndarray) -> float:  # pragma: no cover - compiled
    """:func:`rounding_floor` of d (N, 2) and h (K,): 64 EPS times the largest of max |d| and
    max h (each numpy's max from 0: NaN as soon as one value is) and 1e-3, taken as Python's
    max takes it (a NaN first stays, a NaN after is passed over)."""
    large_d = large_h = 0.0
    for i in range(d.shape[0]):
        large_d = dual.maximum(large_d, abs(d[i, 0]))
        large_d = dual.maximum(large_d, abs(d[i, 1]))
    for k in range(h.shape[0]):
        large_h = dual.maximum(large_h, h[k])
    scale = large_h if large_h > large_d else large_d
    scale = 1e-3 if 1e-3 > scale else scale
    return 64.0 * EPS * scale


def certify(x: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray, h: np.ndarray,
            lam: np.ndarray, label: np.ndarray, clusters: int, tol: float, floor: float
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Gap (m^2; inf where a true row is broken), budget (m^2), done and smallest slack (m),
    per cluster, of x and
    lam (x = d + A^T lam; h the untightened bounds). A cluster's budget is tol^2 / 4 times its
    share of the agents plus its share of the multipliers (the shares sum to 1 over clusters,
    so the squared bounds sum to at most tol^2), and never below the skin's rounding floor's
    cost 4 floor sum_c lam."""
    return certificate(x, ri, rj, re, h, lam, label, clusters, tol, floor)


@numba.njit(cache=True, nogil=True)
def certificate(x: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray, h: np.ndarray,
                lam: np.ndarray, label: np.ndarray, clusters: int, tol: float, floor: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover
    """:func:`certify`, compiled."""
    comp, low, total = dual.cluster_certificates(x, ri, rj, re, h, lam, label, clusters)
    budget = np.empty(clusters)
    shares(label, total, pairwise.numpy_sum(total), 0.5 * tol * tol, 4.0 * floor, budget)
    gap, done = np.empty(clusters), np.empty(clusters, dtype=np.bool_)
    judged(comp, low, budget, gap, done)
    return gap, budget, done, low


def budgets(label: np.ndarray, clusters: int, total: np.ndarray, tol: float, floor: float
            ) -> np.ndarray:
    """The gap (m^2) each cluster may keep (:func:`certify`): label (N,) the cluster of each
    agent (-1: none), total (clusters,) the sum of its multipliers (m)."""
    total = np.ascontiguousarray(total, dtype=np.float64)
    out = np.empty(clusters)
    shares(label, total, pairwise.numpy_sum(total), 0.5 * tol * tol, 4.0 * floor, out)
    return out


@numba.njit(cache=True, nogil=True)
def shares(label: np.ndarray, total: np.ndarray, lam_all: float, half_tol2: float,
           floor4: float, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """:func:`budgets` into out (clusters,): sizes counted, share = size / agents (the count
    of agents in rows, an integer: exact in any order), averaged with total / lam_all when
    lam_all > 0, and max(half_tol2 share, floor4 total) as numpy's maximum."""
    clusters = out.shape[0]
    sizes = np.zeros(clusters)
    for a in range(label.shape[0]):
        if label[a] >= 0:
            sizes[label[a]] += 1.0
    count = 0.0
    for c in range(clusters):
        count += sizes[c]
    count = max(count, 1.0)
    for c in range(clusters):
        share = sizes[c] / count
        if lam_all > 0.0:
            share = 0.5 * (share + total[c] / lam_all)
        out[c] = dual.maximum(half_tol2 * share, floor4 * total[c])


@numba.njit(cache=True, nogil=True)
def judged(comp: np.ndarray, low: np.ndarray, budget: np.ndarray, gap: np.ndarray,
           done: np.ndarray) -> None:  # pragma: no cover - compiled
    """gap = max(comp, 0) where low >= 0, else inf (a row broken), as numpy's maximum; done =
    gap <= budget."""
    for c in range(comp.shape[0]):
        gap[c] = dual.maximum(comp[c], 0.0) if low[c] >= 0.0 else np.inf
        done[c] = gap[c] <= budget[c]


def solve(d: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray, h: np.ndarray,
          lam0: np.ndarray, *, tol: float, max_rounds: int) -> Certified:
    """The rounds of the module docstring for the QP of every row at once.

    d: (N, 2) predicted displacements p - q (m); ri, rj, re, h: the rows (:mod:`.dual`);
    lam0: (K,) starting multipliers (>= 0, m); tol: the bound wanted (m); max_rounds: cap on
    the rounds (0: certify the start only). The rounds run compiled (:func:`rounds`); a round
    whose sweeps leave the face as the previous round did comes back here for the factored
    step (sparse Cholesky), then the compiled rounds go on."""
    (lam, label, clusters, floor, count, value, settled, x, tight, gap, budget, done,
     factor) = first_rounds(d, ri, rj, re, h, np.ascontiguousarray(lam0, dtype=np.float64),
                            tol, max_rounds)
    while factor:
        if not factored.face_step(x, d, ri, rj, re, tight, lam):
            dual.face_step(x, d, ri, rj, re, tight, lam, CG_ITERS, PASSES)
        x = after_face(d, ri, rj, re, lam, settled, count)
        x, tight, gap, budget, done, factor = rounds(d, ri, rj, re, h, lam, x, label, clusters,
                                                     tol, floor, max_rounds, count, value,
                                                     settled)
    return Certified(x, lam, label, gap, budget, done, int(count[0]), float(value[1]), floor)


@numba.njit(cache=True, nogil=True)
def first_rounds(d: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray, h: np.ndarray,
                 lam0: np.ndarray, tol: float, max_rounds: int
                 ) -> tuple:  # pragma: no cover - compiled
    """:func:`solve`'s start and its :func:`rounds` up to the first factored step (or the
    end): lam (a copy of lam0), the clusters' labels and count, the rounding floor, the
    rounds' state (count, value, settled) and what :func:`rounds` returns."""
    lam = lam0.copy()
    label, clusters = dual.cluster_labels(d.shape[0], ri, rj)
    floor = floor_of(d, h)
    count = np.zeros(3, dtype=np.int64)  # rounds, stalled rounds, whether a face is settled
    value = np.array([np.inf, floor])  # the best progress, the skin
    settled = np.zeros(ri.shape[0], dtype=np.bool_)
    x = dual.apply_multipliers(d, ri, rj, re, lam)
    x, tight, gap, budget, done, factor = rounds(d, ri, rj, re, h, lam, x, label, clusters, tol,
                                                 floor, max_rounds, count, value, settled)
    return (lam, label, clusters, floor, count, value, settled, x, tight, gap, budget, done,
            factor)


@numba.njit(cache=True, nogil=True)
def rounds(d: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray, h: np.ndarray,
           lam: np.ndarray, x: np.ndarray, label: np.ndarray, clusters: int, tol: float,
           floor: float, max_rounds: int, count: np.ndarray, value: np.ndarray,
           settled: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                         np.ndarray, bool]:  # pragma: no cover - compiled
    """The rounds of :func:`solve` from x = d + A^T lam, in place on lam, count (rounds,
    stalled rounds, 1 once ``settled`` holds the face lam > 0 after the last round), value
    (best progress m, skin m) and settled (K,). Returns x, the tightened bounds of the round,
    the last certificate's gap, budget and done (per cluster), and whether it stopped for the
    factored face step (the round's sweeps are done; the caller takes the face step, sets
    settled and x, and counts the round) rather than at the end."""
    while True:
        gap, budget, done, low = certificate(x, ri, rj, re, h, lam, label, clusters, tol,
                                             floor)
        if done.all() or count[0] >= max_rounds:
            return x, h, gap, budget, done, False
        # progress: the largest violation of a true row, or the square root of the largest
        # gap once the rows hold (both in m; numpy's max and min with initial 0, then Python's
        # max of the two: a NaN slack leaves the gap's term)
        worst_gap, worst_row, nan_row = 0.0, 0.0, False
        for c in range(clusters):
            if done[c]:
                continue
            if np.isfinite(gap[c]):
                worst_gap = dual.maximum(worst_gap, np.sqrt(gap[c]))
            if low[c] != low[c]:
                nan_row = True
            elif -low[c] > worst_row:
                worst_row = -low[c]
        worst = worst_row if (not nan_row and worst_row > worst_gap) else worst_gap
        if worst < 0.5 * value[0]:
            value[0], count[1] = worst, 0
        else:
            count[1] += 1
            if count[1] >= STALL:
                return x, h, gap, budget, done, False
        # Python's max and min (the first argument unless the second is larger or smaller)
        total = pairwise.numpy_sum(lam)
        total = 1e-300 if 1e-300 > total else total
        skin = tol * tol / (16.0 * total)
        skin = skin if skin < 1e-8 * tol else 1e-8 * tol
        value[1] = skin if skin > floor else floor
        tight = h + value[1]
        dual.pgs(x, ri, rj, re, tight, lam, SWEEPS)
        if count[2] and same_face(lam, settled):
            return x, tight, gap, budget, done, True
        dual.face_step(x, d, ri, rj, re, tight, lam, CG_ITERS, PASSES)
        x = after_face(d, ri, rj, re, lam, settled, count)


@numba.njit(cache=True, nogil=True)
def after_face(d: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray,
               lam: np.ndarray, settled: np.ndarray,
               count: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """A round's end after its face step (compiled or factored): ``settled`` (K,) becomes
    the face lam > 0, the round is counted and a face marked settled in ``count``
    (:func:`rounds`), and x = d + A^T lam (N, 2) m is returned."""
    for k in range(lam.shape[0]):
        settled[k] = lam[k] > 0.0
    count[0] += 1
    count[2] = 1
    return dual.apply_multipliers(d, ri, rj, re, lam)


@numba.njit(cache=True, nogil=True)
def same_face(lam: np.ndarray, settled: np.ndarray) -> bool:  # pragma: no cover - compiled
    """Whether the face lam > 0 (K,) is ``settled`` (K,) bool."""
    for k in range(lam.shape[0]):
        if (lam[k] > 0.0) != settled[k]:
            return False
    return True
