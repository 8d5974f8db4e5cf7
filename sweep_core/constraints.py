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

import numpy as np
from scipy.spatial import cKDTree

# codes of single-row kinds, in the order of scene.geometry
HALFPLANE, SEGMENT, CIRCLE = 0, 1, 2
KIND_NAMES = ("walls(halfplane)", "walls(segment)", "obstacles(circle)")


@dataclass(frozen=True)
class Geometry:
    """Static description of walls and obstacles (arrays may be empty).

    halfplane_normal (W, 2) unit, halfplane_offset (W,) m, halfplane_velocity (W,) m/s:
        <n, q_i> - (c + v t) >= r_i(t).
    segment_a, segment_b (S, 2) m: dist(q_i, [a, b]) >= r_i(t).
    circle_center (O, 2) m, circle_radius (O,) m: |q_i - c| >= R + r_i(t).
    halfplane_index, segment_index, circle_index: position of each item in the scene's
        ``walls`` / ``obstacles`` lists, for messages.
    """

    halfplane_normal: np.ndarray
    halfplane_offset: np.ndarray
    halfplane_velocity: np.ndarray
    segment_a: np.ndarray
    segment_b: np.ndarray
    circle_center: np.ndarray
    circle_radius: np.ndarray
    halfplane_index: np.ndarray
    segment_index: np.ndarray
    circle_index: np.ndarray

    @property
    def is_empty(self) -> bool:
        return not (len(self.halfplane_offset) or len(self.segment_a) or len(self.circle_radius))

    def describe(self, kind: int, item: int) -> str:
        """Scene-facing name of a wall/obstacle, e.g. ``walls[2] (segment)``."""
        if kind == HALFPLANE:
            return f"walls[{int(self.halfplane_index[item])}] (halfplane)"
        if kind == SEGMENT:
            return f"walls[{int(self.segment_index[item])}] (segment)"
        return f"obstacles[{int(self.circle_index[item])}] (circle)"


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
        d = y[self.pair_i] - y[self.pair_j]
        rp = np.einsum("ij,ij->i", self.pair_e, d) - self.pair_b
        rs = np.einsum("ij,ij->i", self.single_n, y[self.single_a]) - self.single_b
        return rp, rs

    def agents(self) -> np.ndarray:
        """Sorted indices of the agents that appear in any row."""
        return np.unique(np.concatenate([self.pair_i, self.pair_j, self.single_a]))


def _pairs_within(q: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    if len(q) < 2:
        empty = np.empty(0, dtype=np.intp)
        return empty, empty
    p = cKDTree(q).query_pairs(reach, output_type="ndarray")
    return p[:, 0], p[:, 1]


def single_values(geom: Geometry, t: float, q: np.ndarray, r: np.ndarray
                  ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """For each kind: (g, n, foot) with g (N, K) = constraint values at (t, q) in m,
    n (N, K, 2) the unit gradient, foot (N, K) the bound offset <n, point on the wall>."""
    out = []
    # half-planes: g = <n, q> - (c + v t) - r
    c = geom.halfplane_offset + geom.halfplane_velocity * t
    n = np.broadcast_to(geom.halfplane_normal, (len(q),) + geom.halfplane_normal.shape)
    out.append((q @ geom.halfplane_normal.T - c - r[:, None], n,
                np.broadcast_to(c, (len(q), len(c)))))
    # segments: g = |q - p| - r with p the closest point of [a, b]
    ab = geom.segment_b - geom.segment_a
    rel = q[:, None, :] - geom.segment_a[None, :, :]
    s = np.clip(np.einsum("nkc,kc->nk", rel, ab) / np.einsum("kc,kc->k", ab, ab), 0.0, 1.0)
    foot = geom.segment_a[None] + s[..., None] * ab[None]
    d = q[:, None, :] - foot
    dist = np.sqrt(np.einsum("nkc,nkc->nk", d, d))
    e = d / np.maximum(dist, 1e-300)[..., None]
    out.append((dist - r[:, None], e, np.einsum("nkc,nkc->nk", e, foot)))
    # circles: g = |q - c| - R - r
    d = q[:, None, :] - geom.circle_center[None]
    dist = np.sqrt(np.einsum("nkc,nkc->nk", d, d))
    e = d / np.maximum(dist, 1e-300)[..., None]
    out.append((dist - geom.circle_radius[None] - r[:, None], e,
                np.einsum("nkc,kc->nk", e, geom.circle_center) + geom.circle_radius[None]))
    return out


def linearise(geom: Geometry, t1: float, q: np.ndarray, r1: np.ndarray, cut: float) -> Rows:
    """Rows of the convex set C~(t1, q) whose value at q is <= cut (m).

    q: (N, 2) positions at t_n; r1: (N,) radii at t1 = t_{n+1}.
    """
    n = len(q)
    i, j = _pairs_within(q, 2.0 * float(r1.max(initial=0.0)) + cut)
    d = q[i] - q[j]
    dist = np.sqrt(np.einsum("ij,ij->i", d, d))
    keep = dist - r1[i] - r1[j] <= cut
    i, j, d, dist = i[keep], j[keep], d[keep], dist[keep]
    pair_e = d / np.maximum(dist, 1e-300)[:, None]
    pair_b = r1[i] + r1[j]

    a_list, n_list, b_list, k_list, item_list = [], [], [], [], []
    if not geom.is_empty and n:
        for kind, (g, nrm, foot) in enumerate(single_values(geom, t1, q, r1)):
            if g.size == 0:
                continue
            a, k = np.nonzero(g <= cut)
            a_list.append(a)
            n_list.append(nrm[a, k])
            b_list.append(foot[a, k] + r1[a])
            k_list.append(np.full(len(a), kind, dtype=np.int8))
            item_list.append(k)
    if a_list:
        sa, sn, sb = np.concatenate(a_list), np.concatenate(n_list), np.concatenate(b_list)
        sk, si = np.concatenate(k_list), np.concatenate(item_list)
    else:
        sa, sn, sb = np.empty(0, np.intp), np.empty((0, 2)), np.empty(0)
        sk, si = np.empty(0, np.int8), np.empty(0, np.intp)
    return Rows(i, j, pair_e, pair_b, sa, sn, sb, sk, si)


@dataclass(frozen=True)
class Gaps:
    """True (non-linearised) constraint values at (t, q), m.

    min_pair, min_single: smallest gap (inf if none); contacts: number of constraints with
    gap <= contact_tol; worst_pair: (i, j, gap) or None; worst_single: (agent, kind, item, gap)
    or None.
    """

    min_pair: float
    min_single: float
    contacts: int
    worst_pair: tuple[int, int, float] | None
    worst_single: tuple[int, int, int, float] | None
    pair_i: np.ndarray
    pair_j: np.ndarray
    pair_gap: np.ndarray

    @property
    def min_gap(self) -> float:
        return min(self.min_pair, self.min_single)


def gaps(geom: Geometry, t: float, q: np.ndarray, r: np.ndarray,
         contact_tol: float = 1e-6) -> Gaps:
    """Evaluate every constraint that can be violated or touching at (t, q)."""
    i, j = _pairs_within(q, 2.0 * float(r.max(initial=0.0)) + contact_tol)
    d = q[i] - q[j]
    pg = np.sqrt(np.einsum("ij,ij->i", d, d)) - r[i] - r[j]
    contacts = int(np.count_nonzero(pg <= contact_tol))
    worst_pair = None
    min_pair = np.inf
    if len(pg):
        w = int(np.argmin(pg))
        min_pair = float(pg[w])
        worst_pair = (int(i[w]), int(j[w]), min_pair)
    min_single, worst_single = np.inf, None
    if not geom.is_empty and len(q):
        for kind, (g, _, _) in enumerate(single_values(geom, t, q, r)):
            if g.size == 0:
                continue
            contacts += int(np.count_nonzero(g <= contact_tol))
            a, k = np.unravel_index(int(np.argmin(g)), g.shape)
            if g[a, k] < min_single:
                min_single = float(g[a, k])
                worst_single = (int(a), kind, int(k), min_single)
    return Gaps(min_pair, min_single, contacts, worst_pair, worst_single, i, j, pg)
