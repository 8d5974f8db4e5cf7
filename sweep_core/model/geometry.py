"""What the walls and obstacles are, and the true constraint values g_k(t, q) (reference §2-3).

The feasible set Q(t) = {q : |q_i - q_j| >= r_i(t) + r_j(t), g_k(t, q_i) >= 0}: this module
evaluates those functions exactly (no linearisation; that is :mod:`sweep_core.numerics.constraints`).
Distances in m, positions (N, 2).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sweep_core.model.neighbours import pairs_within

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

    def path(self, kind: int, item: int) -> str:
        """Scene path of a wall/obstacle, e.g. ``walls[2]``."""
        return self.describe(kind, item).split(" ")[0]

    def describe(self, kind: int, item: int) -> str:
        """Scene-facing name of a wall/obstacle, e.g. ``walls[2] (segment)``."""
        if kind == HALFPLANE:
            return f"walls[{int(self.halfplane_index[item])}] (halfplane)"
        if kind == SEGMENT:
            return f"walls[{int(self.segment_index[item])}] (segment)"
        return f"obstacles[{int(self.circle_index[item])}] (circle)"


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
    i, j = pairs_within(q, 2.0 * float(r.max(initial=0.0)) + contact_tol)
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
