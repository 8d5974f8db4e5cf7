"""The true gaps after a robot step: nobody overlaps anybody or any wall, and no robot's centre
went through a wall (the fleet's check, :func:`check_step`).

The people's own gaps are those the simulator's post-step check takes (the same call,
:func:`~sweep_core.model.gaps.gaps` of the people at the step's end), so they are computed
once and handed back. The robots' gaps (robot-person, robot-robot, robot-wall and obstacle
values, the arithmetic of :func:`~sweep_core.model.wall_kernels.pair_gaps` and
:func:`~sweep_core.model.wall_kernels.single_gaps`) are one compiled pass over every pair
(:func:`robot_gaps`), for geometries of half-planes, segments and circles; with polygons or
user constraints, or a NaN value, everyone's gaps are evaluated together instead.
"""
from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

from sweep_core.errors import InfeasibleError
from sweep_core.model.crossing import crossings
from sweep_core.model.gaps import Gaps, gaps
from sweep_core.model.geometry import Geometry
from sweep_core.model.wall_kernels import disk_gap, halfplane_value, segment_foot

#: a gap below -TOLERANCE (m) after a step is an overlap
TOLERANCE = 1e-9

#: robot_gaps' kinds of the smallest value: robot-person and robot-robot pairs, then a robot
#: against a half-plane, a segment or a circle (the geometry's kind codes plus 2)
PERSON, ROBOT, HALFPLANE_OF, SEGMENT_OF, CIRCLE_OF = 0, 1, 2, 3, 4
#: robot_gaps' kind when a value is NaN
NAN = -2


def check_step(geom: Geometry, states: list[Any], start: list[tuple], y: np.ndarray,
               r1: np.ndarray, t1: float) -> Gaps | None:
    """Raises InfeasibleError when someone overlaps someone or something by more than
    TOLERANCE at the step's end, or a robot's centre went through a wall during the step
    (``start``: each robot's pose before it). y (N, 2) m: the people at t1 (s), r1 (N,) m
    their radii; ``states``: the robots' (their poses at the step's end). Returns the
    people's :func:`gaps` at (t1, y) when it computed them (None otherwise)."""
    centres = np.array([st.pose[:2] for st in states], dtype=np.float64).reshape(-1, 2)
    radii = np.array([st.robot.radius for st in states], dtype=np.float64)
    n = len(y)

    def who(i: int) -> str:
        return f"robot {states[i - n].robot.name}" if i >= n else f"agent {i}"

    here = geom.at(t1)
    people: Gaps | None = None
    worst: tuple[float, bool, tuple] | None = None  # (gap, is a pair, what)
    if not here.user and not here.has_polygons:
        people = gaps(geom, t1, y, r1)
        hn, _, sa, sb, cc, cr = here.packed
        out = np.empty(4)
        robot_gaps(centres, radii, np.ascontiguousarray(y, dtype=np.float64),
                   np.ascontiguousarray(r1, dtype=np.float64), hn, here.offsets(t1), sa, sb,
                   cc, cr, out)
        kind = int(out[1])
        if kind == NAN:  # a NaN: everyone's gaps together, as below
            people = None
        else:
            worst = _smallest(people, float(out[0]), kind, int(out[2]), int(out[3]), n)
    if people is None:
        g = gaps(geom, t1, np.concatenate([y, centres]), np.concatenate([r1, radii]))
        if g.min_pair <= g.min_single and g.worst_pair is not None:
            worst = (g.min_pair, True, g.worst_pair[:2])
        elif g.worst_single is not None:
            worst = (g.min_single, False, g.worst_single[:3])
    if worst is not None and worst[0] < -TOLERANCE:
        gap, pair, what = worst
        if pair:
            i, j = int(what[0]), int(what[1])
            text = f"{who(i)} and {who(j)} overlap"
            robot = who(j) if j >= n else who(i)
        else:
            i, kind, item = (int(v) for v in what)
            text = f"{who(i)} overlaps {geom.describe(kind, item)}"
            robot = who(i)
            if i >= n and geom.moves(kind, item) and states[i - n].robot.prescribed:
                raise InfeasibleError(t1, [], f"{text} by {-gap:.3g} m", fix=(
                    f"{geom.path(kind, item)} moves into {robot}, whose motion is prescribed "
                    "(weight inf) and cannot yield: give it a finite weight (it is then "
                    "pushed) or steer it clear of the obstacle's path"))
        raise InfeasibleError(t1, [], f"{text} by {-gap:.3g} m", fix=(
            f"the solver left {robot} overlapping: tighten the solver's tol or use a smaller "
            "dt"))
    before = np.array([p[:2] for p in start], dtype=np.float64).reshape(-1, 2)
    through, _ = crossings(geom, before, centres, radii)
    if len(through):
        name = states[int(through[0])].robot.name
        raise InfeasibleError(t1, [], f"robot {name} went through a wall during the step",
                              fix=f"use a smaller dt, or a lower max_speed for robot {name}")
    return people


def _smallest(people: Gaps, value: float, kind: int, a: int, b: int, n: int
              ) -> tuple[float, bool, tuple] | None:
    """The smallest of the people's gaps and the robots' (``robot_gaps``' answer), a pair
    before a wall or obstacle at equal values, with its agents in the indices of everyone
    (people 0..n-1, then the robots): (gap, is a pair, (i, j) or (agent, kind, item))."""
    pair: tuple[float, tuple] | None = None
    single: tuple[float, tuple] | None = None
    if people.worst_pair is not None:
        pair = (people.min_pair, people.worst_pair[:2])
    if people.worst_single is not None:
        single = (people.min_single, people.worst_single[:3])
    if kind in (PERSON, ROBOT) and (pair is None or value < pair[0]):
        pair = (value, (b, n + a) if kind == PERSON else (n + a, n + b))
    elif kind >= HALFPLANE_OF and (single is None or value < single[0]):
        single = (value, (n + a, kind - HALFPLANE_OF, b))
    if pair is not None and (single is None or pair[0] <= single[0]):
        return pair[0], True, pair[1]
    return None if single is None else (single[0], False, single[1])


@numba.njit(cache=True, nogil=True, inline="always")
def keep_smallest(v: float, what: int, a: int, b: int, best: float, kind: int, first: int,
                   second: int) -> tuple[float, int, int, int]:  # pragma: no cover - compiled
    """:func:`robot_gaps`' running minimum (best, kind, first, second) after the value v (m)
    of kind ``what`` between a and b: v and its place when v is smaller (or nothing was kept,
    kind -1), else unchanged; kind NAN from the first NaN value on."""
    if kind == NAN or v != v:
        return best, NAN, first, second
    if v < best or kind < 0:
        return v, what, a, b
    return best, kind, first, second


@numba.njit(cache=True, nogil=True)
def robot_gaps(c: np.ndarray, rc: np.ndarray, q: np.ndarray, r: np.ndarray, hn: np.ndarray,
               hc: np.ndarray, sa: np.ndarray, sb: np.ndarray, cc: np.ndarray,
               cr: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """The smallest gap (m) of the robots c (R, 2), rc (R,) against the people q (N, 2), r
    (N,), each other, the half-planes hn (W, 2), hc (W,), the segments [sa, sb] (S, 2) and the
    circles cc (O, 2), cr (O,) into out (4,): the value, its kind (PERSON .. CIRCLE_OF; -1:
    nothing to compare; -2: a value is NaN), the robot (or the first robot of a pair) and the
    person, the second robot or the item; the first of equal values."""
    best, kind, first, second = math.inf, -1, -1, -1
    for k in range(c.shape[0]):
        x, y, rk = c[k, 0], c[k, 1], rc[k]
        for i in range(q.shape[0]):
            v = disk_gap(q[i, 0], q[i, 1], x, y, r[i], rk)[0]
            best, kind, first, second = keep_smallest(v, PERSON, k, i, best, kind, first,
                                                       second)
        for j in range(k + 1, c.shape[0]):
            v = disk_gap(x, y, c[j, 0], c[j, 1], rk, rc[j])[0]
            best, kind, first, second = keep_smallest(v, ROBOT, k, j, best, kind, first,
                                                       second)
    for k in range(c.shape[0]):
        x, y, rk = c[k, 0], c[k, 1], rc[k]
        for m in range(hn.shape[0]):
            v = halfplane_value(x, y, hn[m, 0], hn[m, 1], hc[m], rk)
            best, kind, first, second = keep_smallest(v, HALFPLANE_OF, k, m, best, kind,
                                                       first, second)
        for m in range(sa.shape[0]):
            v = segment_foot(x, y, sa[m, 0], sa[m, 1], sb[m, 0], sb[m, 1])[0] - rk
            best, kind, first, second = keep_smallest(v, SEGMENT_OF, k, m, best, kind,
                                                       first, second)
        for m in range(cc.shape[0]):
            v = disk_gap(x, y, cc[m, 0], cc[m, 1], cr[m], rk)[0]
            best, kind, first, second = keep_smallest(v, CIRCLE_OF, k, m, best, kind,
                                                       first, second)
    out[0], out[1], out[2], out[3] = best, kind, first, second
