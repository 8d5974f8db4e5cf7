"""A robot step that needs no projection, decided and checked in one compiled call.

On a small scene with static walls (a robot among ten people, as the CrowdNav environment
steps it) most robot steps are simple: no prescribed robot's target overlaps anything, the
people's prediction already holds every linearised row of C~(t1, q) with the robots' target
disks as obstacles, and nothing overlaps at the step's end. :meth:`Fleet.step
<sweep_core.numerics.robots.fleet.Fleet.step>` then settles the targets (a geometry pass per
robot), adds the robots' disks to the geometry, answers the projection without building rows
(:mod:`sweep_core.numerics.projection.clear`), sets empty contacts and checks the step
(:func:`~sweep_core.numerics.robots.overlaps.check_step`): tens of microseconds of Python
around a few microseconds of arithmetic.

:func:`clear_robot_step` asks the same questions of the same kernels, in one call: the
targets' walls and each other (the settle's), the cutoff (``first_cutoff``'s), the rows at
the prediction (``clear_count`` with the robots' target disks appended to the circles, as
``Geometry.with_circles`` appends them), the robots' gaps at the step's end (``robot_gaps``)
and their centre paths against the wall segments (``crossing_pairs``). Only when every answer
is the simple one does the fleet take the step from it; otherwise nothing has changed and the
step runs through the general path, which asks again and acts on the answer (a stop, a QP, an
error naming who overlaps). Each value is computed by the same kernel from the same
arguments, so a step taken here has the bits the general path gives it. (The fleet asks it
through :func:`~sweep_core.numerics.robots.small_step.robot_step`, whose call goes on with the
projection when the prediction breaks a row but no robot stops.)

It applies (:func:`applies`) when every robot is prescribed (weight inf), the scene has no map
of blocked cells, at most ``clear.MAX_AGENTS`` people, and a geometry without user
constraints, polygons, moving obstacles or moving half-planes.
"""
from __future__ import annotations

import math
from typing import Any, NamedTuple

import numba
import numpy as np

from sweep_core.model.crossing import DENSE_PAIRS
from sweep_core.model.gaps import Gaps, small_gaps, small_room, small_summary
from sweep_core.model.geometry import DENSE_SEGMENTS, Geometry
from sweep_core.model.wall_kernels import crossing_pairs, single_gaps
from sweep_core.numerics.projection import dual
from sweep_core.numerics.projection.clear import MAX_AGENTS, MIN_CUT, clear_count
from sweep_core.numerics.projection.summaries import largest_step
from sweep_core.numerics.robots.overlaps import NAN, TOLERANCE, check_step, robot_gaps

#: the overlap tolerance of the settle's target check (``model.robots.overlap``'s tol), m
SETTLE_TOLERANCE = 1e-9
#: ``gaps``' contact tolerance, which the settle's wall pass is given (m)
CONTACT_TOL = 1e-6
#: what :func:`clear_robot_step` returns when the step is not a simple one: a moving robot's
#: target overlaps something, or the settle's test is unsure
NOT_CLEAR = -1
#: ... or when no robot would stop (the settle has nothing to do) but the rest is not simple
SETTLED = -2


class _Room(NamedTuple):
    """The compiled calls' trailing arguments for N people in a static geometry: its packed
    arrays, the dense-pair cap, whether it has walls, and the gaps' and crossings' work
    arrays (``small_room``'s, then out_i, out_k, unsure of room len(near_a) + min(N S,
    DENSE_PAIRS))."""

    hn: np.ndarray
    hc: np.ndarray
    sa: np.ndarray
    sb: np.ndarray
    cc: np.ndarray
    cr: np.ndarray
    static: np.ndarray
    dense_pairs: int
    walls: bool
    i: np.ndarray
    j: np.ndarray
    pg: np.ndarray
    vals: np.ndarray
    near_a: np.ndarray
    near_k: np.ndarray
    out_i: np.ndarray
    out_k: np.ndarray
    unsure: np.ndarray
    out: np.ndarray

    def gaps(self) -> Gaps:
        """The people's gaps the compiled call left in these arrays."""
        return small_summary(self.i, self.j, self.pg, self.near_a, self.near_k, self.out,
                             self.walls)


def room_for(geom: Geometry, people: int) -> _Room:
    """:class:`_Room` for ``people`` people in ``geom`` (static)."""
    hn, hc, sa, sb, cc, cr = geom.packed
    walls = not geom.is_empty
    i, j, pg, vals, near_a, near_k, out = small_room(people, len(hc), len(sa), len(cr), walls)
    room = len(near_a) + min(people * len(sa), DENSE_PAIRS)
    return _Room(hn, hc, sa, sb, cc, cr, geom.static_segments, DENSE_PAIRS, walls, i, j, pg,
                 vals, near_a, near_k, np.empty(room, dtype=np.intp),
                 np.empty(room, dtype=np.intp), np.empty(room, dtype=np.bool_), out)


class Rooms:
    """One simulation's :class:`_Room`, kept from step to step and made again when the
    geometry or the number of people changes. The compiled calls write every entry they read,
    so a kept room gives the bits a new one gives. The :class:`Gaps` of ``_Room.gaps`` are
    views of its arrays: they hold until the next step's call."""

    __slots__ = ("geom", "people", "room")

    def __init__(self) -> None:
        self.geom: Geometry | None = None
        self.people = -1
        self.room: _Room | None = None

    def get(self, geom: Geometry, people: int) -> _Room:
        """The room for ``people`` people in ``geom`` (static): the kept one if it fits."""
        room = self.room
        if room is None or self.geom is not geom or self.people != people:
            room = self.room = room_for(geom, people)
            self.geom, self.people = geom, people
        return room


def applies(geom: Geometry, people: int, all_prescribed: bool, has_map: bool) -> bool:
    """Whether :func:`clear_robot_step` may answer a step of this scene (module docstring):
    ``geom`` the scene's geometry, ``people`` its people now."""
    return (all_prescribed and not has_map and 0 < people <= MAX_AGENTS and not geom.user
            and not geom.is_moving and not geom.has_polygons and geom.fixed_halfplanes
            and people * len(geom.segment_a) <= DENSE_SEGMENTS)


def checked_end(geom: Geometry, t1: float, q: np.ndarray, y: np.ndarray, r1: np.ndarray,
                states: list[Any], start: list[tuple], has_map: bool
                ) -> tuple[Gaps | None, bool]:
    """The general robot step's check at its end (:func:`~sweep_core.numerics.robots.
    overlaps.check_step`: raises InfeasibleError on an overlap or a robot through a wall) and
    whether the people's paths from q (N, 2) to y (N, 2) are clear of the wall segments. Where
    :func:`applies`, first in one compiled call (:func:`clear_end`) that answers only when
    nothing overlaps and no robot's path might cross a segment: then the people's gaps are
    ``check_step``'s (the same kernel and arguments); otherwise ``check_step`` itself runs and
    the paths are left to the simulator's check (False). ``states``: the robots at the step's
    end; ``start``: their poses before it."""
    if (applies(geom, len(y), all(st.robot.prescribed for st in states), has_map)
            and len(q) == len(y)):
        q = np.ascontiguousarray(q, dtype=np.float64)
        r1 = np.ascontiguousarray(r1, dtype=np.float64)
        room = room_for(geom, len(y))
        if clear_end(q, y, r1, np.array([p[:2] for p in start], dtype=np.float64),
                     np.array([st.pose[:2] for st in states], dtype=np.float64),
                     np.array([st.robot.radius for st in states], dtype=np.float64), *room):
            return room.gaps(), bool(room.out[10])
    return check_step(geom, states, start, y, r1, t1), False


@numba.njit(cache=True, nogil=True)
def clear_end(q: np.ndarray, y: np.ndarray, r1: np.ndarray, start: np.ndarray,
              end: np.ndarray, radius: np.ndarray, hn: np.ndarray, hc: np.ndarray,
              sa: np.ndarray, sb: np.ndarray, cc: np.ndarray, cr: np.ndarray,
              static: np.ndarray, dense_pairs: int, walls: bool, i: np.ndarray, j: np.ndarray,
              pg: np.ndarray, vals: np.ndarray, near_a: np.ndarray, near_k: np.ndarray,
              out_i: np.ndarray, out_k: np.ndarray, unsure: np.ndarray,
              out: np.ndarray) -> bool:  # pragma: no cover - compiled
    """Whether a general step's end is clear: no robot (``end`` (R, 2), ``radius`` (R,), from
    ``start`` (R, 2)) overlaps a person (y (N, 2), r1 (N,)), another robot, a wall or an
    obstacle by more than TOLERANCE, nor is a value NaN (``robot_gaps``); no robot's centre
    path might meet a wall segment (``crossing_pairs`` finds no candidate); the people's gaps
    at y and their paths from q: :func:`_people_clear` (into its arrays and out[0:11]), with
    r1's largest value as numpy's max (a NaN answers False: ``check_step`` then decides)."""
    r_max = r1[0]
    for a in range(1, r1.shape[0]):
        r_max = dual.maximum(r_max, r1[a])
    if r_max != r_max:
        return False
    return _end_clear(q, y, r1, r_max, start, end, radius, hn, hc, sa, sb, cc, cr, static,
                      dense_pairs, walls, i, j, pg, vals, near_a, near_k, out_i, out_k,
                      unsure, out)


@numba.njit(cache=True, nogil=True)
def clear_robot_step(q: np.ndarray, pred: np.ndarray, r1: np.ndarray, start: np.ndarray,
                     target: np.ndarray, radius: np.ndarray, moving: np.ndarray,
                     hn: np.ndarray, hc: np.ndarray, sa: np.ndarray, sb: np.ndarray,
                     cc: np.ndarray, cr: np.ndarray, static: np.ndarray, dense_pairs: int,
                     walls: bool, i: np.ndarray, j: np.ndarray, pg: np.ndarray,
                     vals: np.ndarray, near_a: np.ndarray, near_k: np.ndarray,
                     out_i: np.ndarray, out_k: np.ndarray, unsure: np.ndarray,
                     out: np.ndarray) -> int:  # pragma: no cover - compiled
    """The number of rows holding with equality at the prediction (``Projection.active``)
    when the step from q (N, 2) to pred (N, 2), r1 (N,) m at t1, with the prescribed robots
    going from ``start`` (R, 2) to ``target`` (R, 2), radii ``radius`` (R,), ``moving`` (R,)
    bool (a non-zero command), is a simple one; else NOT_CLEAR, or SETTLED when only the
    first test passed (no robot stops: the general path's settle would stop none). The
    geometry's packed arrays
    at t1: half-planes hn, hc, segments sa, sb, circles cc, cr, ``static`` (S,) the segments
    that do not move. A simple step (each test the general path's, in its arithmetic):

    - no moving robot's target disk overlaps another robot's target by more than
      SETTLE_TOLERANCE, nor is it unsure of clearing the walls and obstacles (``single_gaps``
      for the one disk, as ``model.robots`` asks it);
    - the cutoff 3 max|p - q| + 1e-3 max r1 is at least MIN_CUT and the prediction holds every
      row within it (``clear_count``, the targets appended to the circles);
    - at the step's end (people at pred, robots at their targets) no robot's gap to a person,
      another robot, a wall or an obstacle is below -TOLERANCE or NaN (``robot_gaps``);
    - no robot's centre path meets a wall segment, nor might it (``crossing_pairs`` finds no
      candidate);
    - the people's gaps at the step's end (``gaps``' passes, :func:`~sweep_core.model.gaps.
      small_gaps`, into i, j, pg (room 4 N), vals, near_a, near_k and out[0:10], as ``gaps``
      documents them; ``walls``: the geometry is not empty) find no pair or wall value below
      -TOLERANCE or NaN and no more pairs than i has room for.

    out[10] is 1.0 when no person's centre path from q to pred meets a static wall segment,
    nor might it (``crossings``' one pass, with those gaps' near pairs and reach, finds no
    candidate, in out_i, out_k, unsure of room len(near_a) + min(N S, dense_pairs)), else 0.0:
    the simulator's own crossing check then runs."""
    robots = target.shape[0]
    nh, ns, nc = hn.shape[0], sa.shape[0], cc.shape[0]
    no_polygon = np.zeros((0, 0), dtype=np.bool_)
    one_vals = np.empty(nh + ns + nc)
    one_a = np.empty(ns, dtype=np.intp)
    one_k = np.empty(ns, dtype=np.intp)
    summary = np.empty(6)
    one = np.empty((1, 2))
    one_r = np.empty(1)
    for k in range(robots):
        if not moving[k]:
            continue
        x, y, rk = target[k, 0], target[k, 1], radius[k]
        for o in range(robots):
            if o != k:
                dx, dy = x - target[o, 0], y - target[o, 1]
                if not math.hypot(dx, dy) - radius[o] - rk >= -SETTLE_TOLERANCE:
                    return NOT_CLEAR
        one[0, 0], one[0, 1], one_r[0] = x, y, rk
        single_gaps(one, one_r, hn, hc, sa, sb, no_polygon, cc, cr, CONTACT_TOL,
                    max(CONTACT_TOL, 2.0 * rk, 1e-3), one_vals, one_a, one_k, summary)
        if summary[3] == -2.0 or (summary[3] >= 0 and summary[2] < -SETTLE_TOLERANCE):
            return NOT_CLEAR
    square, r_max = largest_step(q, pred, r1)
    cut = 3.0 * math.sqrt(square) + 1e-3 * r_max
    if not cut >= MIN_CUT:
        return SETTLED
    circles = np.empty((nc + robots, 2))
    circle_r = np.empty(nc + robots)
    circles[:nc], circle_r[:nc] = cc, cr
    circles[nc:], circle_r[nc:] = target, radius
    active = clear_count(q, pred, r1, cut, hn, hc, sa, sb, circles, circle_r)
    if active < 0:
        return SETTLED
    if not _end_clear(q, pred, r1, r_max, start, target, radius, hn, hc, sa, sb, cc, cr,
                      static, dense_pairs, walls, i, j, pg, vals, near_a, near_k, out_i, out_k,
                      unsure, out):
        return SETTLED
    return active


@numba.njit(cache=True, nogil=True)
def _end_clear(q: np.ndarray, y: np.ndarray, r1: np.ndarray, r_max: float, start: np.ndarray,
               end: np.ndarray, radius: np.ndarray, hn: np.ndarray, hc: np.ndarray,
               sa: np.ndarray, sb: np.ndarray, cc: np.ndarray, cr: np.ndarray,
               static: np.ndarray, dense_pairs: int, walls: bool, i: np.ndarray,
               j: np.ndarray, pg: np.ndarray, vals: np.ndarray, near_a: np.ndarray,
               near_k: np.ndarray, out_i: np.ndarray, out_k: np.ndarray, unsure: np.ndarray,
               out: np.ndarray) -> bool:  # pragma: no cover - compiled
    """The end of a step with the robots moved from ``start`` to ``end`` (R, 2), radii
    ``radius`` (R,), and the people from q to y (N, 2), r1 (N,) at the end, r_max r1's
    largest (finite): whether no robot's gap to a person, another robot, a wall or an
    obstacle is below -TOLERANCE or NaN (``robot_gaps``), no robot's centre path might meet
    a wall segment (``crossing_pairs`` finds no candidate) and the people are clear
    (:func:`_people_clear`)."""
    worst = np.empty(4)
    robot_gaps(end, radius, y, r1, hn, hc, sa, sb, cc, cr, worst)
    if worst[1] == NAN or (worst[1] >= 0 and not worst[0] >= -TOLERANCE):
        return False
    room = min(end.shape[0] * sa.shape[0], dense_pairs)
    none = np.empty(0, dtype=np.intp)
    if sa.shape[0] and crossing_pairs(start, end, radius, none, none, -1.0, sa, sb, static,
                                      dense_pairs, np.empty(room, dtype=np.intp),
                                      np.empty(room, dtype=np.intp),
                                      np.empty(room, dtype=np.bool_)) != 0:
        return False
    return _people_clear(q, y, r1, r_max, dense_pairs, walls, hn, hc, sa, sb, cc, cr, static,
                         i, j, pg, vals, near_a, near_k, out_i, out_k, unsure, out)


@numba.njit(cache=True, nogil=True)
def _people_clear(q: np.ndarray, y: np.ndarray, r1: np.ndarray, r_max: float,
                  dense_pairs: int, walls: bool, hn: np.ndarray, hc: np.ndarray,
                  sa: np.ndarray, sb: np.ndarray, cc: np.ndarray, cr: np.ndarray,
                  static: np.ndarray, i: np.ndarray, j: np.ndarray, pg: np.ndarray,
                  vals: np.ndarray, near_a: np.ndarray, near_k: np.ndarray,
                  out_i: np.ndarray, out_k: np.ndarray, unsure: np.ndarray,
                  out: np.ndarray) -> bool:  # pragma: no cover - compiled
    """:func:`clear_robot_step`'s last test: the people's gaps at y (N, 2) and whether their
    paths from q might cross a wall segment (its docstring). r_max: the largest of r1
    (finite: ``largest_step``'s, which a NaN would have made the cutoff fail on); ``gaps``
    takes max(r1.max(), 0)."""
    r_max = max(r_max, 0.0)
    small_gaps(y, r1, 2.0 * r_max + CONTACT_TOL, walls, hn, hc, sa, sb,
               np.zeros((0, 0), dtype=np.bool_), cc, cr, CONTACT_TOL,
               max(CONTACT_TOL, 2.0 * r_max, 1e-3), i, j, pg, vals, near_a, near_k, out)
    if out[6] > i.shape[0] or out[3] == -2.0:
        return False
    w = int(out[8])
    if w >= 0 and not pg[w] >= -TOLERANCE:
        return False
    if walls and out[3] >= 0 and not out[2] >= -TOLERANCE:
        return False
    out[10] = 1.0
    if sa.shape[0] and walls:
        near = int(out[9])
        if crossing_pairs(q, y, r1, near_a[:near], near_k[:near], out[0], sa, sb, static,
                          dense_pairs, out_i, out_k, unsure) != 0:
            out[10] = 0.0
    return True
