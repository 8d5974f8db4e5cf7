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

from sweep_core.numerics.projection import dual, factored

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


@dataclass
class Certified:
    """x (N, 2) displacements (m); lam (K,) multipliers (m); label (N,) cluster of each agent
    (-1: in no row); gap (clusters,) duality gap of each (m^2, inf: a row violated); budget
    (clusters,) the gap each may keep; done (clusters,) gap <= budget; rounds: rounds run;
    skin: the skin delta of the last round (m)."""

    x: np.ndarray
    lam: np.ndarray
    label: np.ndarray
    gap: np.ndarray
    budget: np.ndarray
    done: np.ndarray
    rounds: int
    skin: float

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
    large_d, large_h = largest_scale(np.ascontiguousarray(d, dtype=np.float64).reshape(-1),
                                     np.ascontiguousarray(h, dtype=np.float64))
    scale = max(large_d, large_h, 1e-3)
    return 64.0 * float(np.finfo(float).eps) * scale


@numba.njit(cache=True, nogil=True)
def largest_scale(d: np.ndarray, h: np.ndarray) -> tuple[float, float]:  # pragma: no cover
    """max(|d|) and max(h), each from 0 (numpy's max with ``initial=0``: NaN as soon as one
    value is)."""
    large_d = large_h = 0.0
    for v in d:
        large_d = dual.maximum(large_d, abs(v))
    for v in h:
        large_h = dual.maximum(large_h, v)
    return large_d, large_h


def certify(x: np.ndarray, ri: np.ndarray, rj: np.ndarray, re: np.ndarray, h: np.ndarray,
            lam: np.ndarray, label: np.ndarray, clusters: int, tol: float, floor: float
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Gap (m^2; inf where a true row is broken), budget (m^2), done and smallest slack (m),
    per cluster, of x and
    lam (x = d + A^T lam; h the untightened bounds). A cluster's budget is tol^2 / 4 times its
    share of the agents plus its share of the multipliers (the shares sum to 1 over clusters,
    so the squared bounds sum to at most tol^2), and never below the skin's rounding floor's
    cost 4 floor sum_c lam."""
    comp, low, total = dual.cluster_certificates(x, ri, rj, re, h, lam, label, clusters)
    budget = budgets(label, clusters, total, tol, floor)
    gap, done = np.empty(clusters), np.empty(clusters, dtype=np.bool_)
    judged(comp, low, budget, gap, done)
    return gap, budget, done, low


def budgets(label: np.ndarray, clusters: int, total: np.ndarray, tol: float, floor: float
            ) -> np.ndarray:
    """The gap (m^2) each cluster may keep (:func:`certify`): label (N,) the cluster of each
    agent (-1: none), total (clusters,) the sum of its multipliers (m)."""
    total = np.ascontiguousarray(total, dtype=np.float64)
    out = np.empty(clusters)
    # the sum of the multipliers in numpy's (pairwise) order; the rest elementwise
    shares(label, total, float(total.sum()), 0.5 * tol * tol, 4.0 * floor, out)
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
    the rounds (0: certify the start only)."""
    n = len(d)
    lam = np.array(lam0, dtype=float)
    label, clusters = dual.cluster_labels(n, ri, rj)
    floor = rounding_floor(d, h)
    x = dual.apply_multipliers(d, ri, rj, re, lam)
    rounds = stall = 0
    best = np.inf
    skin = floor
    settled: np.ndarray | None = None  # the face after the previous round
    while True:
        gap, budget, done, low = certify(x, ri, rj, re, h, lam, label, clusters, tol, floor)
        if done.all() or rounds >= max_rounds:
            break
        # progress: the largest violation of a true row, or the square root of the largest
        # gap once the rows hold (both in m)
        undone = ~done
        worst = max(float(np.max(np.sqrt(gap[undone & np.isfinite(gap)]), initial=0.0)),
                    float(-np.min(np.minimum(low, 0.0)[undone], initial=0.0)))
        if worst < 0.5 * best:
            best, stall = worst, 0
        else:
            stall += 1
            if stall >= STALL:
                break
        skin = max(floor, min(1e-8 * tol, tol * tol / (16.0 * max(float(lam.sum()), 1e-300))))
        tight = h + skin
        dual.pgs(x, ri, rj, re, tight, lam, SWEEPS)
        face = lam > 0.0
        if not (settled is not None and np.array_equal(face, settled)
                and factored.face_step(x, d, ri, rj, re, tight, lam)):
            dual.face_step(x, d, ri, rj, re, tight, lam, CG_ITERS, PASSES)
        settled = lam > 0.0
        x = dual.apply_multipliers(d, ri, rj, re, lam)
        rounds += 1
    return Certified(x, lam, label, gap, budget, done, rounds, skin)
