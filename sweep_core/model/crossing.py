"""Centre paths through walls: the check that no agent's centre went through a wall segment
during a step, decided exactly.

The post-step check (:func:`sweep_core.model.gaps.gaps`) evaluates the constraints at the
step's end; an agent whose centre jumped through a thin wall in one step ends on the far side
with a positive distance, which that check alone cannot tell from a feasible position. The
straight path [q0_i, q1_i] of each centre is therefore tested against every static wall
segment (walls, polyline pieces, polygon edges, map walls) with exact orientation signs
(compiled float orientations behind Shewchuk's error filter,
:func:`sweep_core.model.wall_kernels.paths_meet_exactly`, and
:func:`sweep_core.model.outlines.segments_meet`'s rational arithmetic for the pairs the filter
cannot vouch for): a path that meets a segment is a crossing
(a feasible centre never comes within its radius of a wall). Moving obstacles' edges are not
tested: their relative path is not a straight segment. The candidate pairs are those the
post-step check found near the end positions, plus a search for the agents that moved farther
than that check's reach, so the test adds little to it.
"""
from __future__ import annotations

import numpy as np

from sweep_core.model.gaps import Gaps
from sweep_core.model.geometry import Geometry
from sweep_core.model.neighbours import segments_within
from sweep_core.model.outlines import segments_meet
from sweep_core.model.wall_kernels import crossing_pairs, paths_meet_exactly

#: agent x segment pairs up to which candidates are found by direct bounding-box comparison
DENSE_PAIRS = 1 << 16


def crossings(geom: Geometry, q0: np.ndarray, q1: np.ndarray, r1: np.ndarray,
              near: Gaps | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(agent, segment) index arrays of the centre paths [q0_i, q1_i] ((N, 2) m each) that
    meet a static segment of ``geom``, decided exactly; r1 (N,): the radii at the end (m).

    ``near``: the post-step check's :func:`gaps` at q1, whose segment pairs within its reach
    are the candidates of every agent that moved at most reach + r1_i (a path through a
    segment ends within its length of it, so its value there is at most |q1 - q0| - r1_i);
    agents that moved farther (or all, without ``near``) are searched here."""
    static = geom.static_segments
    empty = np.empty(0, dtype=np.intp)
    if len(static) == 0:
        return empty, empty
    q0 = np.ascontiguousarray(q0, dtype=np.float64)
    q1 = np.ascontiguousarray(q1, dtype=np.float64)
    r1 = np.ascontiguousarray(r1, dtype=np.float64)
    i, k = (empty, empty) if near is None else (near.near_agent, near.near_segment)
    room = len(i) + max(0, min(len(q0) * len(static), DENSE_PAIRS))
    out_i, out_k = np.empty(room, dtype=np.intp), np.empty(room, dtype=np.intp)
    unsure = np.empty(room, dtype=np.bool_)
    # the candidates gathered and tested in one compiled pass: bounding boxes (exact
    # comparisons), then the orientations in float where the error filter vouches for their
    # signs; the pairs it leaves unsure are decided exactly here
    found = crossing_pairs(q0, q1, r1, np.ascontiguousarray(i, dtype=np.intp),
                           np.ascontiguousarray(k, dtype=np.intp),
                           -1.0 if near is None else float(near.reach),
                           geom.packed[2], geom.packed[3], static, DENSE_PAIRS, out_i, out_k,
                           unsure)
    if found == 0:  # no path near a segment (most steps)
        return empty, empty
    if found > 0:
        i, k, unsure = out_i[:found], out_k[:found], unsure[:found]
        hit = ~unsure
        if unsure.any():
            hit[unsure] = segments_meet(q0[i[unsure]], q1[i[unsure]],
                                        geom.segment_a[k[unsure]], geom.segment_b[k[unsure]])
        return i[hit], k[hit]
    return _searched(geom, q0, q1, r1, near, static)


def _searched(geom: Geometry, q0: np.ndarray, q1: np.ndarray, r1: np.ndarray,
              near: Gaps | None, static: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`crossings` with the far agents' candidates found by the spatial index."""
    step = np.hypot(q1[:, 0] - q0[:, 0], q1[:, 1] - q0[:, 1])
    empty = np.empty(0, dtype=np.intp)
    i, k = (empty, empty) if near is None else (near.near_agent, near.near_segment)
    far = np.flatnonzero(step > (-1.0 if near is None else near.reach + r1))
    seg = np.flatnonzero(static)
    fi, fk = segments_within(q0[far], geom.segment_a[seg], geom.segment_b[seg],
                             max(float(step[far].max()), 1e-6) * 1.001)
    i, k = np.concatenate([i, far[fi]]), np.concatenate([k, seg[fk]])
    keep = static[k] & (step[i] > 0)
    i, k = i[keep], k[keep]
    hit = paths_meet_exactly(q0[i], q1[i], geom.segment_a[k], geom.segment_b[k])
    return i[hit], k[hit]
