"""Constraints of the feasible set Q(t) and their linearisation (reference §2-4).

Two families of rows, both written as linear inequalities in the new positions y (N, 2):

* pair rows     <e_ij, y_i - y_j> >= b_ij        (agents i, j)
* single rows   <n_k,  y_a>      >= b_k          (agent a against a wall or obstacle)

For a convex constraint g(t, q) >= 0 the row is g(t1, q) + <grad g(t1, q), y - q> >= 0 (§4),
which lies inside the true set because g is convex: for two disks
<e_ij, y_i - y_j> >= r_i(t1) + r_j(t1) with e_ij = (q_i - q_j) / |q_i - q_j|.
Only rows whose value at q is at most ``cut`` (m) are built; far pairs never are.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from sweep_core.model.geometry import DENSE_SEGMENTS, Geometry, dense_rows, single_rows
from sweep_core.model.neighbours import pairs_within
from sweep_core.model.wall_kernels import pair_rows

#: the single rows' kind codes, in the order of scene.geometry (HALFPLANE, SEGMENT, CIRCLE)
_KINDS = np.arange(3, dtype=np.int8)


@dataclass(frozen=True)
class Rows:
    """Linearised constraints at (t1, q); see the module docstring for their meaning."""

    pair_i: np.ndarray      # (P,) int
    pair_j: np.ndarray      # (P,) int
    pair_e: np.ndarray      # (P, 2) unit vectors
    pair_b: np.ndarray      # (P,) m
    single_a: np.ndarray    # (M,) int
    single_n: np.ndarray    # (M, 2) unit vectors
    single_b: np.ndarray    # (M,) m
    single_kind: np.ndarray  # (M,) int8, HALFPLANE / SEGMENT / CIRCLE
    single_item: np.ndarray  # (M,) int, index within its kind

    @property
    def count(self) -> int:
        return len(self.pair_b) + len(self.single_b)

    def residuals(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Row values minus bounds at y (N, 2): >= 0 where satisfied (m)."""
        rp, rs = np.empty(len(self.pair_b)), np.empty(len(self.single_b))
        row_residuals(np.asarray(y, dtype=np.float64), self.pair_i, self.pair_j, self.pair_e,
                      self.pair_b, self.single_a, self.single_n, self.single_b, rp, rs)
        return rp, rs

    def select(self, pairs: np.ndarray, singles: np.ndarray) -> Rows:
        """The rows picked by ``pairs`` (P,) and ``singles`` (M,) (boolean masks or indices)."""
        return Rows(self.pair_i[pairs], self.pair_j[pairs], self.pair_e[pairs],
                    self.pair_b[pairs], self.single_a[singles], self.single_n[singles],
                    self.single_b[singles], self.single_kind[singles], self.single_item[singles])

    def displacement_rows(self, q: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Every row written for the displacement x = y - q (reference §4 with y - q_n as the
        unknown), pair rows first: agents ri (K,), rj (K,) (-1 for a wall or obstacle row),
        unit vectors re (K, 2) and bounds h (K,) m of <re_k, x_ri - x_rj> >= h_k (or
        <re_k, x_ri> >= h_k). The bounds are small (a step's motion), so a slack is computed
        to about 1e-18 m instead of the 1e-15 m of absolute positions."""
        k = self.count
        ri, rj = np.empty(k, dtype=np.int64), np.empty(k, dtype=np.int64)
        re, h = np.empty((k, 2)), np.empty(k)
        displacement_rows(np.ascontiguousarray(q, dtype=np.float64), self.pair_i, self.pair_j,
                          self.pair_e, self.pair_b, self.single_a, self.single_n,
                          self.single_b, ri, rj, re, h)
        return ri, rj, re, h

    def agents(self) -> np.ndarray:
        """Sorted indices of the agents that appear in any row."""
        return row_agents(self.pair_i, self.pair_j, self.single_a)


@numba.njit(cache=True)
def row_residuals(y: np.ndarray, pi: np.ndarray, pj: np.ndarray, pe: np.ndarray,
                  pb: np.ndarray, sa: np.ndarray, sn: np.ndarray, sb: np.ndarray,
                  rp: np.ndarray, rs: np.ndarray) -> None:  # pragma: no cover - compiled
    """:meth:`Rows.residuals` into rp (P,) and rs (M,), m: <e, y_i - y_j> - b and
    <n, y_a> - b, each product sum in the order numpy's ``einsum("ij,ij->i")`` takes
    (x then y), so the bits are the same."""
    for k in range(len(pb)):
        i, j = pi[k], pj[k]
        rp[k] = (pe[k, 0] * (y[i, 0] - y[j, 0]) + pe[k, 1] * (y[i, 1] - y[j, 1])) - pb[k]
    for k in range(len(sb)):
        a = sa[k]
        rs[k] = (sn[k, 0] * y[a, 0] + sn[k, 1] * y[a, 1]) - sb[k]


@numba.njit(cache=True, nogil=True)
def displacement_rows(q: np.ndarray, pi: np.ndarray, pj: np.ndarray, pe: np.ndarray,
                      pb: np.ndarray, sa: np.ndarray, sn: np.ndarray, sb: np.ndarray,
                      ri: np.ndarray, rj: np.ndarray, re: np.ndarray, h: np.ndarray
                      ) -> None:  # pragma: no cover - compiled
    """:meth:`Rows.displacement_rows` into ri, rj (K,), re (K, 2), h (K,), pair rows first:
    h = b - <e, q_i - q_j> and b - <n, q_a>, each product sum in the order numpy's
    ``einsum("kc,kc->k")`` takes (x then y), so the bits are the same."""
    m = len(pb)
    for k in range(m):
        i, j = pi[k], pj[k]
        h[k] = pb[k] - (pe[k, 0] * (q[i, 0] - q[j, 0]) + pe[k, 1] * (q[i, 1] - q[j, 1]))
        ri[k], rj[k] = i, j
        re[k, 0], re[k, 1] = pe[k, 0], pe[k, 1]
    for k in range(len(sb)):
        a = sa[k]
        h[m + k] = sb[k] - (sn[k, 0] * q[a, 0] + sn[k, 1] * q[a, 1])
        ri[m + k], rj[m + k] = a, -1
        re[m + k, 0], re[m + k, 1] = sn[k, 0], sn[k, 1]


@numba.njit(cache=True, nogil=True)
def row_agents(pi: np.ndarray, pj: np.ndarray, sa: np.ndarray
               ) -> np.ndarray:  # pragma: no cover - compiled
    """The sorted distinct agents (intp) of the rows (what ``np.unique`` of the three gives),
    by marking them."""
    top = -1
    for arr in (pi, pj, sa):
        for k in range(len(arr)):
            top = max(top, arr[k])
    mark = np.zeros(top + 1, dtype=np.bool_)
    for arr in (pi, pj, sa):
        for k in range(len(arr)):
            mark[arr[k]] = True
    return np.flatnonzero(mark).astype(np.intp)


def linearise(geom: Geometry, t1: float, q: np.ndarray, r1: np.ndarray, cut: float) -> Rows:
    """Rows of the convex set C~(t1, q) whose value at q is <= cut (m).

    q: (N, 2) positions at t_n; r1: (N,) radii at t1 = t_{n+1}.
    """
    n = len(q)
    q = np.ascontiguousarray(q, dtype=np.float64)
    r1 = np.ascontiguousarray(r1, dtype=np.float64)
    i, j = pairs_within(q, 2.0 * float(r1.max(initial=0.0)) + cut)
    pi, pj = np.empty(len(i), dtype=np.intp), np.empty(len(i), dtype=np.intp)
    pair_e, pair_b = np.empty((len(i), 2)), np.empty(len(i))
    m = pair_rows(q, r1, i, j, float(cut), pi, pj, pair_e, pair_b)
    i, j, pair_e, pair_b = pi[:m], pj[:m], pair_e[:m], pair_b[:m]
    if geom.is_empty or n == 0:
        none = np.empty(0, np.intp)
        return Rows(i, j, pair_e, pair_b, none, np.empty((0, 2)), np.empty(0),
                    np.empty(0, np.int8), none)
    here = geom.at(t1)
    if not here.user and (len(here.segment_a) == 0
                          or n * len(here.segment_a) <= DENSE_SEGMENTS):
        # the rows of single_rows, in its order, from one compiled pass
        sa, si, _, sn, foot, counts = dense_rows(here, t1, q, r1, cut)
        return Rows(i, j, pair_e, pair_b, sa, sn, foot + r1[sa], np.repeat(_KINDS, counts),
                    si)

    a_list, n_list, b_list, k_list, item_list = [], [], [], [], []
    if not geom.is_empty and n:
        for kind, (a, k, _, nrm, foot) in enumerate(single_rows(geom, t1, q, r1, cut)):
            if len(a) == 0:
                continue
            a_list.append(a)
            n_list.append(nrm)
            b_list.append(foot + r1[a])
            k_list.append(np.full(len(a), kind, dtype=np.int8))
            item_list.append(k)
    if a_list:
        sa, sn, sb = np.concatenate(a_list), np.concatenate(n_list), np.concatenate(b_list)
        sk, si = np.concatenate(k_list), np.concatenate(item_list)
    else:
        sa, sn, sb = np.empty(0, np.intp), np.empty((0, 2)), np.empty(0)
        sk, si = np.empty(0, np.int8), np.empty(0, np.intp)
    return Rows(i, j, pair_e, pair_b, sa, sn, sb, sk, si)
