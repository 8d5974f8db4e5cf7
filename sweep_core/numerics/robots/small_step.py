"""A small scene's robot step in one compiled call: the simple step, or the step with contacts.

Where :func:`~sweep_core.numerics.robots.clear_step.applies` holds (prescribed robots among at
most ``clear.MAX_AGENTS`` people in a static geometry, no map), :meth:`Fleet.step
<sweep_core.numerics.robots.fleet.Fleet.step>` asks :func:`robot_step` first. Its first
compiled call asks the simple step's questions
(:func:`~sweep_core.numerics.robots.clear_step.clear_robot_step`, which answers with one
number); when they find that no robot stops but the prediction breaks a row (people touch each
other, a wall or a robot's disk), a second call (:func:`_contact_step`) goes on with what the
general path does next for such a step:

- the projection (:func:`~sweep_core.numerics.projection.small.small_projection`'s arithmetic,
  on the geometry with the robots' target disks appended to the circles, as
  ``Geometry.with_circles`` appends them, warm-started from the last step);
- each robot's contacts from the rows of its disk (:func:`~sweep_core.numerics.robots.contacts.
  circle_contacts`, then sorted stably by person, as ``set_contacts`` sorts them);
- the end check (:func:`~sweep_core.numerics.robots.clear_step.clear_end`: nothing overlaps,
  no robot's path might cross a wall, and the people's gaps).

Each value comes from the same kernel with the same arguments as on the general path, so the
step has its bits. Whenever one of those would do anything else (a robot stops, the projection
needs more than the certified rounds or a wider cutoff, the end check is unsure) nothing has
changed and the general path takes the step, from the start.
"""
from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

from sweep_core.model.gaps import Gaps
from sweep_core.model.geometry import CIRCLE, Geometry
from sweep_core.numerics.constraints import Rows
from sweep_core.numerics.projection import certified
from sweep_core.numerics.projection.clear import MIN_CUT, clear_count
from sweep_core.numerics.projection.options import SolverOptions
from sweep_core.numerics.projection.project import NO_ROWS, Projection
from sweep_core.numerics.projection.small import first_pass
from sweep_core.numerics.projection.summaries import largest_step
from sweep_core.numerics.robots.clear_step import (
    SETTLED,
    Rooms,
    applies,
    clear_end,
    clear_robot_step,
)
from sweep_core.numerics.robots.contacts import circle_contacts

#: what :func:`_contact_step` returns for a step with contacts it has taken
CONTACT = -3

_NO_MULTIPLIER = np.empty(0)
_NO_INDEX = np.empty(0, dtype=np.intp)
_NO_KIND = np.empty(0, dtype=np.int8)


def _read_only(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


#: a robot's contacts when it has none: person ids (0,), positions (0, 2), impulses (0, 2)
#: (read only: every robot without contacts shares them)
_NO_CONTACTS = (_read_only(np.empty(0, dtype=np.int64)), _read_only(np.empty((0, 2))),
                _read_only(np.empty((0, 2))))


def robot_step(geom: Geometry, t1: float, q: np.ndarray, pred: np.ndarray, r1: np.ndarray,
               states: list[Any], targets: list[tuple], moving: list[bool], has_map: bool,
               warm: Projection | None, opts: SolverOptions, h: float, rooms: Rooms
               ) -> tuple[Projection, np.ndarray, Gaps, bool] | bool:
    """A fleet's step of h s when this module takes it: the robots (``states``,
    ``RobotState``) moved to their ``targets`` (x, y, yaw) with their commands as twists and
    their contacts set, and (the projection, the people's positions at the step's end, their
    gaps there, whether their paths are clear of the wall segments) returned; otherwise,
    nothing changed, True when no robot would stop (the general path may skip its settle)
    and False when some might, the scene is not one this applies to (``has_map``: blocked
    cells) or the last projection (``warm``) held clusters back (the general path then
    counts their steps). ``opts``: the scheme's solver options; ``rooms``: the simulation's
    kept work arrays (the gaps returned are views of them, valid until the next step)."""
    if (not applies(geom, len(q), all(st.robot.prescribed for st in states), has_map)
            or (warm is not None and warm.stuck is not None and len(warm.y) == len(q))):
        return False
    if warm is not None and (not opts.warm_start or len(warm.y) != len(q)):
        warm = None
    done = simple_step(geom, q, pred, r1,
                       np.array([st.pose[:2] for st in states], dtype=np.float64),
                       np.array([p[:2] for p in targets], dtype=np.float64),
                       np.array([st.robot.radius for st in states], dtype=np.float64),
                       np.array(moving, dtype=np.bool_), warm, opts, h, rooms)
    if not isinstance(done, tuple):
        return done
    proj, people, gaps, paths, contacts = done
    for k, st in enumerate(states):
        st.pose, st.twist = targets[k], st.command
        st.contact_ids, st.contact_xy, st.contact_impulse = contacts[k]
    return proj, people, gaps, paths


def simple_step(geom: Geometry, q: np.ndarray, pred: np.ndarray, r1: np.ndarray,
                start: np.ndarray, target: np.ndarray, radius: np.ndarray, moving: np.ndarray,
                warm: Projection | None, opts: SolverOptions, h: float, rooms: Rooms
                ) -> tuple | bool:
    """The step's projection, the people's positions at its end (a copy of the projection's),
    their gaps there, whether their paths are clear of the wall segments, and each robot's
    contacts (person ids (K,), their positions (K, 2) m, impulses (K, 2) m/s), when
    :func:`_step` takes it; otherwise, nothing changed, True when no robot would stop and
    False else. The robots go from ``start`` (R, 2) to ``target`` (R, 2), radii ``radius``
    (R,), ``moving`` (R,) bool; ``geom`` the scene's (static) geometry; ``warm`` the last
    projection to start from (None: none); ``rooms``: the kept work arrays."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    pred = np.ascontiguousarray(pred, dtype=np.float64)
    r1 = np.ascontiguousarray(r1, dtype=np.float64)
    room = rooms.get(geom, len(q))
    # the simple step's questions alone first: its answer is one number, where the call
    # that goes on with the projection returns some twenty arrays (each boxed on return)
    code = clear_robot_step(q, pred, r1, start, target, radius, moving, *room)
    robots = len(target)
    if code >= 0:  # no row broken: the prediction itself, no contact
        y = pred.copy()
        proj = Projection(y, NO_ROWS, _NO_MULTIPLIER, _NO_MULTIPLIER, code, 0, 0, 0, 0.0, 0,
                          0, None, 0)
        return proj, y.copy(), room.gaps(), bool(room.out[10]), [_NO_CONTACTS] * robots
    if code != SETTLED or not (len(q) >= 2 and opts.method == "certified"):
        return code == SETTLED
    # the warm start the projection starts from (the simple step reads none)
    if warm is None:
        old = (_NO_INDEX, _NO_INDEX, _NO_INDEX, _NO_KIND, _NO_INDEX, _NO_MULTIPLIER,
               _NO_MULTIPLIER, False)
    else:
        rows = warm.rows
        old = (rows.pair_i, rows.pair_j, rows.single_a, rows.single_kind, rows.single_item,
               np.ascontiguousarray(warm.lam_pair, dtype=np.float64),
               np.ascontiguousarray(warm.lam_single, dtype=np.float64), True)
    (code, y, pi, pj, pe, pb, s_a, s_n, s_b, s_kind, s_item, lam, active, qp_size, solves,
     rounds, bound, ids, xy, imp, counts) = _contact_step(
        q, pred, r1, start, target, radius, *room, float(h), *old, float(opts.tol),
        int(opts.max_rounds))
    if code != CONTACT:
        return code == SETTLED
    m = len(pb)
    proj = Projection(y, Rows(pi, pj, pe, pb, s_a, s_n, s_b, s_kind, s_item), lam[:m],
                      lam[m:], active, qp_size, solves, 0, bound, rounds * certified.SWEEPS)
    contacts, at = [], 0
    for c in counts.tolist():  # robot after robot
        contacts.append((ids[at:at + c], xy[at:at + c], imp[at:at + c]))
        at += c
    return proj, y.copy(), room.gaps(), bool(room.out[10]), contacts


@numba.njit(cache=True, nogil=True)
def _contact_step(q: np.ndarray, pred: np.ndarray, r1: np.ndarray, start: np.ndarray,
                  target: np.ndarray, radius: np.ndarray, hn: np.ndarray, hc: np.ndarray,
                  sa: np.ndarray, sb: np.ndarray, cc: np.ndarray, cr: np.ndarray,
                  static: np.ndarray, dense_pairs: int, walls: bool, i: np.ndarray,
                  j: np.ndarray, pg: np.ndarray, vals: np.ndarray, near_a: np.ndarray,
                  near_k: np.ndarray, out_i: np.ndarray, out_k: np.ndarray,
                  unsure: np.ndarray, out: np.ndarray, h: float, old_i: np.ndarray,
                  old_j: np.ndarray, old_a: np.ndarray, old_kind: np.ndarray,
                  old_item: np.ndarray, old_lam_p: np.ndarray, old_lam_s: np.ndarray,
                  has_warm: bool, tol: float, max_rounds: int
                  ) -> tuple:  # pragma: no cover - compiled
    """:func:`simple_step`'s arithmetic after ``clear_robot_step`` answered SETTLED (no robot
    stops, the prediction is not a simple step): the projection, tried where its cutoff
    admits it, then the contacts and the end check. The first value: CONTACT with the step
    taken, else SETTLED (nothing taken); then the projection's y, rows, multipliers, active
    rows, QP agents, solves, rounds and bound, and the robots' contacts, robot after robot
    (ids, positions, impulses, and each robot's count)."""
    robots = target.shape[0]
    code = SETTLED
    # project's geometry: the robots' target disks after the scene's circles
    nc = cc.shape[0]
    circles = np.empty((nc + robots, 2))
    circle_r = np.empty(nc + robots)
    circles[:nc], circle_r[:nc] = cc, cr
    circles[nc:], circle_r[nc:] = target, radius
    counts = np.zeros(robots, dtype=np.intp)
    ids = np.empty(0, dtype=np.int64)
    xy, imp = np.empty((0, 2)), np.empty((0, 2))
    # project's cutoff, and its test of the prediction against the rows: a prediction
    # that holds them all (its end not clear) is left to the general path
    square, r_max = largest_step(q, pred, r1)
    cut = 3.0 * math.sqrt(square) + 1e-3 * r_max
    if not cut >= MIN_CUT or clear_count(q, pred, r1, cut, hn, hc, sa, sb, circles,
                                          circle_r) < 0:
        ok, y, pi, pj, pe, pb, s_a, s_n, s_b, s_kind, s_item, lam, active, qp_size, \
            solves, bound, rounds = first_pass(q, pred, r1, cut, hn, hc, sa, sb, circles,
                                          circle_r, True, old_i, old_j, old_a, old_kind,
                                          old_item, old_lam_p, old_lam_s, has_warm, tol,
                                          max_rounds)
        if ok:
            code = CONTACT
    if code != CONTACT:
        none = np.empty(0, dtype=np.intp)
        return (code, pred, none, none, np.empty((0, 2)), np.empty(0), none,
                np.empty((0, 2)), np.empty(0), np.empty(0, dtype=np.int8), none, np.empty(0),
                0, 0, 0, 0, 0.0, ids, xy, imp, counts)
    # set_contacts: each robot's disk rows with lam > 0, sorted stably by person
    m = pb.shape[0]
    lam_s = lam[m:]
    ids = np.empty(robots * lam_s.shape[0], dtype=np.int64)
    xy, imp = np.empty((ids.shape[0], 2)), np.empty((ids.shape[0], 2))
    one_ids = np.empty(lam_s.shape[0], dtype=np.int64)
    one_imp = np.empty((lam_s.shape[0], 2))
    at = 0
    for k in range(robots):
        found = circle_contacts(s_kind, s_item, s_a, s_n, lam_s, CIRCLE, nc + k, h, one_ids,
                                one_imp)
        order = np.argsort(one_ids[:found], kind="mergesort")
        for u in range(found):
            ids[at + u] = one_ids[order[u]]
            imp[at + u, 0], imp[at + u, 1] = one_imp[order[u], 0], one_imp[order[u], 1]
            xy[at + u, 0], xy[at + u, 1] = y[ids[at + u], 0], y[ids[at + u], 1]
        counts[k] = found
        at += found
    # the end check: the robots at their targets, the people at y
    code = CONTACT if clear_end(q, y, r1, start, target, radius, hn, hc, sa, sb, cc, cr,
                                static, dense_pairs, walls, i, j, pg, vals, near_a, near_k,
                                out_i, out_k, unsure, out) else SETTLED
    return (code, y, pi, pj, pe, pb, s_a, s_n, s_b, s_kind, s_item, lam, active, qp_size,
            solves, rounds, bound, ids[:at], xy[:at], imp[:at], counts)
