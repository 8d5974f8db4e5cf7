"""The speed laws of the scene's optional ``flows.headway`` (docs/flows.md): their names,
default parameters and the validation of the key. The laws themselves are compiled kernels:
:mod:`sweep_core.numerics.csm` (``csm``, the default) and :mod:`sweep_core.numerics.headway`
(``lanes``).

    headway:  {law: csm, time_gap: T, repulsion: a, repulsion_range: D, lateral: k,
               fade: k2, length: f, follow: beta,                 s, -, m, -, -, -, -
               wall_repulsion: a_w, wall_range: D_w}              -, m
            | {law: lanes, time_gap: T, margin: w}                      s, m
"""
from __future__ import annotations

import math
from typing import Any

from sweep_core import checks
from sweep_core.errors import SceneError, show

#: the speed laws of ``flows.headway``: the collision-free speed model (numerics/csm.py) and
#: the free distance with a lateral margin (numerics/headway.py)
LAWS = ("csm", "lanes")
#: the law, time gap T (s), repulsion strength a and range D (m) of ``flows.headway`` when the
#: scene gives none: calibrated jointly against Weidmann's speed-density relation in a ring
#: corridor and the bottleneck flows of Seyfried et al. (docs/validation.md,
#: scripts/calibrate_speed_law.py)
DEFAULT_LAW = "csm"
DEFAULT_TIME_GAP = 2.1
DEFAULT_REPULSION = 2.0
DEFAULT_REPULSION_RANGE = 0.1
#: the fraction k of l_ij = r_i + r_j within which a neighbour beside the line of motion counts
#: as ahead (numerics/csm.py); 1 is the published law
DEFAULT_LATERAL = 0.8
#: the fraction f of l_ij the speed rule takes as the body length (gap d_ij - f l_ij); 1 is the
#: published law (numerics/csm.py)
DEFAULT_LENGTH = 1.0
#: the share beta of the leader's speed added to s / T (numerics/csm.py, ``follow``); 0 is the
#: published law (with T = 2.1 s a uniform queue moves as the published law with T = 1.1 s)
DEFAULT_FOLLOW = 0.9
#: the walls' term of the direction rule (numerics/csm.py): strength a_w (0: walls do not
#: enter the rule) and range D_w (m), JuPedSim's default for its collision-free speed model
DEFAULT_WALL_REPULSION = 0.0
DEFAULT_WALL_RANGE = 0.02
#: ``lateral`` of a recorded scene that does not name it: recordings made before the key
#: existed walked with the full stripe (analysis/run.py)
RECORDED_LATERAL = 1.0
#: the csm parameters a recorded scene may lack (made before the key existed) and the values
#: it walked with (analysis/run.py); ``fade`` missing is the sharp corridor of its ``lateral``,
#: filled in by :func:`recorded_headway`
RECORDED = {"lateral": RECORDED_LATERAL, "length": 1.0, "follow": 0.0}
#: the ``lanes`` law's time gap T (s) and lateral margin w (m) when the scene gives none
#: (calibrated against Weidmann alone, scripts/calibrate_headway.py)
LANES_TIME_GAP = 0.35
DEFAULT_MARGIN = 0.3
#: largest repulsion strength a (and wall_repulsion a_w): Tordeux et al. publish a = 5 (the
#: default here is 2); at a = 1e3 one neighbour at contact already outweighs the wished
#: direction a thousandfold, and the direction rule's sum overflows (every agent near another
#: or near a wall then stops) from about a = 1e150
MAX_REPULSION = 1e3
#: smallest repulsion range D (and wall_range D_w, m): contacts hold to 1e-9 m, so a disk may
#: overlap another or a wall by up to 1e-9 m and the exponential stays below e^0.001 for
#: D >= 1e-6 m; at D = 1e-300 it is inf and the directions NaN
MIN_REPULSION_RANGE = 1e-6
#: largest time gap T (s) and lanes margin w (m): the laws search the pairs within
#: max|u| T + 2 max r (+ w), so their number, and the memory, grow with T^2 and w^2 (at
#: T = 1e6 s every pair of the crowd, N^2 / 2); published calibrations have T of 0.3-2 s, the
#: default here is 2.1 s, and a margin beyond a few body widths counts people who are not ahead
MAX_TIME_GAP = 10.0
MAX_MARGIN = 2.0


def headway_from_spec(raw: Any, bounded: bool = True) -> dict | None:
    """``flows.headway`` validated and normalised (None: absent): ``law`` (``csm``, default,
    or ``lanes``; a ``margin`` without a ``law`` is the ``lanes`` law, whose parameter it is)
    with its parameters, defaults filled in; ``bounded``: the repulsions (of agents and of
    walls) and their ranges within MAX_REPULSION and MIN_REPULSION_RANGE, the time gap and the
    margin within MAX_TIME_GAP and MAX_MARGIN (a recording's scene is not held to them)."""
    if raw is None:
        return None
    hw = checks.mapping(raw, "flows.headway", allowed={"law", "time_gap", "margin", "repulsion",
                                                       "repulsion_range", "lateral", "fade",
                                                       "length", "follow", "wall_repulsion",
                                                       "wall_range"})
    law = hw.get("law", "lanes" if "margin" in hw else DEFAULT_LAW)
    if law not in LAWS:
        raise SceneError("flows.headway.law", f"unknown law {show(law)}",
                         f"use one of {', '.join(LAWS)} (or omit it for {DEFAULT_LAW})")
    own = {"csm": {"repulsion", "repulsion_range", "lateral", "fade", "length", "follow",
                   "wall_repulsion", "wall_range"},
           "lanes": {"margin"}}[law]
    for key in sorted(set(hw) - own - {"law", "time_gap"}):
        raise SceneError(f"flows.headway.{key}", f"is not a parameter of the {law} law",
                         "remove it, or set flows.headway.law to the law it belongs to")
    if law == "lanes":
        return {"law": law, "time_gap": _time_gap(hw.get("time_gap", LANES_TIME_GAP), bounded),
                "margin": _within(checks.length(hw.get("margin", DEFAULT_MARGIN),
                                                "flows.headway.margin", nonnegative=True),
                                  "flows.headway.margin", 0.0,
                                  MAX_MARGIN if bounded else math.inf)}
    k = lateral_from_spec(hw.get("lateral", DEFAULT_LATERAL))
    return {"law": law,
            "time_gap": _time_gap(hw.get("time_gap", DEFAULT_TIME_GAP), bounded),
            "repulsion": _within(checks.number(hw.get("repulsion", DEFAULT_REPULSION),
                                               "flows.headway.repulsion", nonnegative=True),
                                 "flows.headway.repulsion", 0.0,
                                 MAX_REPULSION if bounded else math.inf),
            "repulsion_range": _within(checks.length(
                hw.get("repulsion_range", DEFAULT_REPULSION_RANGE),
                "flows.headway.repulsion_range", positive=True), "flows.headway.repulsion_range",
                MIN_REPULSION_RANGE if bounded else 0.0, math.inf),
            "lateral": k, "fade": fade_from_spec(hw.get("fade", k), k),
            "length": fraction_from_spec(hw.get("length", DEFAULT_LENGTH), "flows.headway.length",
                                         "the fraction of the two radii the speed rule takes "
                                         "as the body length"),
            "follow": follow_from_spec(hw.get("follow", DEFAULT_FOLLOW)),
            "wall_repulsion": _within(checks.number(
                hw.get("wall_repulsion", DEFAULT_WALL_REPULSION), "flows.headway.wall_repulsion",
                nonnegative=True, fix="set flows.headway.wall_repulsion to a number >= 0 (0: "
                "walls do not turn the direction)"), "flows.headway.wall_repulsion", 0.0,
                MAX_REPULSION if bounded else math.inf),
            "wall_range": _within(checks.length(hw.get("wall_range", DEFAULT_WALL_RANGE),
                                                "flows.headway.wall_range", positive=True),
                                  "flows.headway.wall_range",
                                  MIN_REPULSION_RANGE if bounded else 0.0, math.inf)}


def _time_gap(raw: Any, bounded: bool) -> float:
    """flows.headway.time_gap (s): > 0, and at most MAX_TIME_GAP when ``bounded``."""
    field = "flows.headway.time_gap"
    t = checks.number(raw, field, positive=True)
    if bounded and t > MAX_TIME_GAP:
        raise SceneError(field, f"must be at most {show(MAX_TIME_GAP)} s, got {show(t)}",
                         f"set {field} between 0 and {show(MAX_TIME_GAP)} (people keep gaps "
                         "of 0.3-2 s)")
    return t


def _within(x: float, field: str, low: float, high: float) -> float:
    """x unchanged when low <= x <= high, else SceneError naming the range."""
    if not low <= x <= high:
        want = (f"at least {show(low)}" if math.isinf(high)
                else f"between {show(low)} and {show(high)}")
        raise SceneError(field, f"must be {want}, got {show(x)}", f"set {field} {want}")
    return x


def follow_from_spec(raw: Any) -> float:
    """``flows.headway.follow`` validated: a number in [0, 1)."""
    fix = ("set flows.headway.follow to a number in [0, 1) (the share of the leader's speed "
           "added to the gap's speed; 0: the speed rule alone)")
    beta = checks.number(raw, "flows.headway.follow", nonnegative=True, fix=fix)
    if beta >= 1.0:
        raise SceneError("flows.headway.follow", f"must be below 1, got {show(raw)}", fix)
    return beta


def fade_from_spec(raw: Any, lateral: float) -> float:
    """``flows.headway.fade`` validated: a number in [k, 1], k the law's ``lateral`` (k: the
    sharp corridor, no fade)."""
    k2 = checks.number(raw, "flows.headway.fade", fix=f"set flows.headway.fade to a number "
                       f"in [{show(lateral)}, 1] (flows.headway.lateral to 1)")
    if not lateral <= k2 <= 1.0:
        raise SceneError("flows.headway.fade", f"must be in [{show(lateral)}, 1] (from "
                         f"flows.headway.lateral to 1), got {show(raw)}",
                         f"set flows.headway.fade to a number in [{show(lateral)}, 1], or "
                         "omit it for the sharp corridor")
    return k2


def fraction_from_spec(raw: Any, field: str, what: str) -> float:
    """A number in (0, 1] at ``field``."""
    f = checks.number(raw, field, positive=True,
                      fix=f"set {field} to a number in (0, 1] ({what})")
    if f > 1.0:
        raise SceneError(field, f"must be at most 1, got {show(raw)}",
                         f"set {field} to a number in (0, 1] ({what})")
    return f


def lateral_from_spec(raw: Any) -> float:
    """``flows.headway.lateral`` validated: a number in (0, 1] (1: every neighbour whose disk
    overlaps the path is ahead)."""
    return fraction_from_spec(raw, "flows.headway.lateral", "the fraction of the two radii "
                              "within which a neighbour beside the path is ahead")


def recorded_headway(spec: Any) -> dict | None:
    """A recorded scene dict with the csm law's parameters that its recording does not name
    filled in as it walked when the recording was made (``RECORDED``: recordings made before a
    key existed have none of it), or None when nothing is to be filled in. Recorded scenes
    carry their law normalised, every other parameter written out."""
    if not isinstance(spec, dict) or not isinstance(spec.get("flows"), dict):
        return None
    flows = spec["flows"]
    hw = flows.get("headway")
    if (not isinstance(hw, dict) or hw.get("law") != "csm"
            or all(k in hw for k in (*RECORDED, "fade"))):
        return None
    filled = {**RECORDED, **hw}
    filled.setdefault("fade", filled["lateral"])  # the sharp corridor of the recorded k
    return {**spec, "flows": {**flows, "headway": filled}}
