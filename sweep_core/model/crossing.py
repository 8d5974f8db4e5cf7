"""Centre paths through walls: the check that no agent's centre went through a wall segment
during a step, decided exactly.

The post-step check (:func:`sweep_core.model.geometry.gaps`) evaluates the constraints at the
step's end; an agent whose centre jumped through a thin wall in one step ends on the far side
with a positive distance, which that check alone cannot tell from a feasible position. The
straight path [q0_i, q1_i] of each centre is therefore tested against every static wall
segment (walls, polyline pieces, polygon edges, map walls) with exact orientation signs
(:func:`sweep_core.model.outlines.segments_meet`): a path that meets a segment is a crossing
(a feasible centre never comes within its radius of a wall). Moving obstacles' edges are not
tested: their relative path is not a straight segment.
"""
from __future__ import annotations

import numpy as np

from sweep_core.model.geometry import Geometry
from sweep_core.model.neighbours import segments_within
from sweep_core.model.outlines import segments_meet

#: agent x segment pairs up to which candidates are found by direct bounding-box comparison
DENSE_PAIRS = 1 << 16


def crossings(geom: Geometry, q0: np.ndarray, q1: np.ndarray, reach: float = 0.0
              ) -> tuple[np.ndarray, np.ndarray]:
    """(agent, segment) index arrays of the centre paths [q0_i, q1_i] ((N, 2) m each) that
    meet a static segment of ``geom``, exactly. ``reach`` (m): a distance within which
    candidates are searched beyond each path's length when there are many pairs (the search
    index's cell size; any value > 0 works, the largest radius is a good one)."""
    static = np.flatnonzero(geom.segment_motion < 0)
    moved = np.flatnonzero(np.any(q0 != q1, axis=1))
    empty = np.empty(0, dtype=np.intp)
    if len(static) == 0 or len(moved) == 0:
        return empty, empty
    a, b = geom.segment_a[static], geom.segment_b[static]
    p0, p1 = q0[moved], q1[moved]
    if len(moved) * len(static) <= DENSE_PAIRS:
        i, k = (m.ravel() for m in np.meshgrid(np.arange(len(moved)), np.arange(len(static)),
                                                indexing="ij"))
    else:
        step = np.hypot(p1[:, 0] - p0[:, 0], p1[:, 1] - p0[:, 1])
        i, k = segments_within(p0, a, b, max(float(step.max()), reach, 1e-6) * 1.001)
    # bounding boxes overlap (exact comparisons), then the exact test
    lo, hi = np.minimum(p0[i], p1[i]), np.maximum(p0[i], p1[i])
    s_lo, s_hi = np.minimum(a[k], b[k]), np.maximum(a[k], b[k])
    near = np.all((lo <= s_hi) & (s_lo <= hi), axis=1)
    i, k = i[near], k[near]
    hit = segments_meet(p0[i], p1[i], a[k], b[k])
    return moved[i[hit]], static[k[hit]]
