"""A robot's ``controller:`` key validated: the name of a bundled local planner, or a mapping
``{kind: NAME, PARAMETER: value, ...}`` with that planner's parameters (the rest default).

The planners (``sweep_core.numerics.robots``; docs/robots.md says what each sees and does):

- ``none``: no controller (commands come from ``cmd_vel`` or the Python API);
- ``pursuit``: along the geodesic field to the goal, slowing for the scan's returns ahead;
- ``orca``: optimal reciprocal collision avoidance (van den Berg et al. 2011) among the people
  within ``sensor_range``, its preferred velocity along the geodesic field;
- ``social_force``: the social force model (Helbing & Molnar 1995) of the robot among the
  people within ``sensor_range``, its goal force along the geodesic field;
- ``window``: sampled velocities scored by progress along the geodesic field against a
  Gaussian forecast of the people within ``sensor_range`` (and of their avoid reaction).

Each parameter is a finite number within its bounds (:data:`PARAMETERS`: default, low, high,
unit, meaning); ``sensor_range`` defaults to the robot's scan ``range_max`` (5 m without a
scan).
"""
from __future__ import annotations

import math
from typing import Any

from sweep_core import checks
from sweep_core.errors import SceneError, show

#: the bundled controllers, in the order the benchmark runs them
CONTROLLERS = ("none", "pursuit", "orca", "social_force", "window")
#: sensor range (m) of a robot without a scan
DEFAULT_SENSOR_RANGE = 5.0
#: most people a planner takes into account (the nearest first)
MAX_NEIGHBOURS = 64

#: the parameters the planners that see people share: what they see, and their safety layer
#: (:mod:`sweep_core.numerics.robots.guard`) and heading control
_SENSOR_RANGE = (None, 0.5, 100.0, "m", "people within this distance are seen")
_STOP_MARGIN = (0.1, 0.0, 2.0, "m", "clearance it can always stop short of")
_PEOPLE_NOISE = (0.0, 0.0, 5.0, "m/sqrt(s)", "people may also come closer by this times the "
                 "square root of the time (the safety layer)")
_TURN_GAIN = (3.0, 0.1, 20.0, "1/s", "turn rate per rad of heading error (diff_drive)")


def _people_speed(default: float) -> tuple[float, float, float, str, str]:
    """The safety layer's ``people_speed`` entry with its planner's default (m/s)."""
    return (default, 0.0, 5.0, "m/s", "speed at which people are assumed to close in (the "
            "safety layer)")


#: per controller: parameter -> (default, low, high, unit, meaning); a default of None is
#: filled in from the robot (sensor_range: its scan's range_max)
PARAMETERS: dict[str, dict[str, tuple[float | None, float, float, str, str]]] = {
    "none": {},
    "pursuit": {
        "turn_gain": (2.0, 0.1, 20.0, "1/s", "turn rate per rad of heading error"),
        "slow_distance": (0.6, 0.01, 10.0, "m", "returns this far beyond the stop margin "
                          "slow it"),
        "stop_margin": (0.05, 0.0, 2.0, "m", "clearance at which it stops"),
    },
    "orca": {
        "sensor_range": _SENSOR_RANGE,
        "time_horizon": (2.0, 0.1, 20.0, "s", "velocities collision-free for this long"),
        "safety_margin": (0.1, 0.0, 1.0, "m", "added to the robot's radius"),
        "neighbours": (16.0, 1.0, float(MAX_NEIGHBOURS), "", "nearest people considered"),
        "stop_margin": _STOP_MARGIN,
        "people_speed": _people_speed(0.0),
        "people_noise": _PEOPLE_NOISE,
        "turn_gain": _TURN_GAIN,
    },
    "social_force": {
        "sensor_range": _SENSOR_RANGE,
        "relaxation": (0.5, 0.05, 10.0, "s", "time to reach the preferred velocity"),
        "strength": (2.0, 0.0, 50.0, "m/s^2", "repulsion of a person at contact"),
        "range": (0.4, 0.05, 5.0, "m", "decay length of the repulsion"),
        "anisotropy": (0.35, 0.0, 1.0, "", "weight of people behind the robot"),
        "anticipation": (2.0, 0.0, 10.0, "s", "how far ahead people's relative motion is "
                         "taken"),
        "side": (0.5, 0.0, 2.0, "", "share of a person ahead's repulsion turned to the "
                 "robot's right"),
        "stop_margin": _STOP_MARGIN,
        "people_speed": _people_speed(0.0),
        "people_noise": _PEOPLE_NOISE,
        "wall_strength": (2.0, 0.0, 50.0, "m/s^2", "repulsion of a wall at contact"),
        "wall_range": (0.2, 0.05, 5.0, "m", "decay length of the wall repulsion"),
        "turn_gain": _TURN_GAIN,
    },
    "window": {
        "sensor_range": _SENSOR_RANGE,
        "horizon": (1.0, 0.1, 10.0, "s", "how far ahead people are forecast"),
        "spread": (0.3, 0.0, 5.0, "m/sqrt(s)", "forecast spread of a person per axis per "
                   "square root of the time"),
        "hazard_margin": (0.1, 0.0, 2.0, "m", "forecast gap counted as a contact"),
        "hazard_weight": (2.0, 0.0, 100.0, "", "rate of the contact hazard in the chance "
                          "of no contact"),
        "passive": (0.25, 0.0, 10.0, "", "weight of a forecast contact the robot does not "
                    "advance into, against one it drives into at full speed (1)"),
        "steadiness": (0.1, 0.0, 10.0, "", "weight of a change of the chosen velocity"),
        "stop_margin": _STOP_MARGIN,
        "people_speed": _people_speed(0.3),
        "people_noise": _PEOPLE_NOISE,
        "turn_gain": _TURN_GAIN,
    },
}


def controller_from_spec(value: Any, field: str, has_goal: bool, scan_range: float | None
                         ) -> tuple[str, dict[str, float], Any]:
    """The controller's kind, its parameters (all of them, defaults filled in) and its
    normalised spec (the name alone when no parameter is given, else the mapping)."""
    if isinstance(value, str) or value is None:
        kind, given = ("none" if value is None else value), {}
    elif isinstance(value, dict):
        if "kind" not in value:
            raise SceneError(f"{field}.kind", f"missing (the keys given are "
                             f"{sorted(str(k) for k in value)})",
                             f"add kind: one of {list(CONTROLLERS)} under {field}")
        kind = value["kind"]
        given = {k: v for k, v in value.items() if k != "kind"}
    else:
        raise SceneError(field, f"must be a controller name or a mapping, got "
                         f"{type(value).__name__} {show(value)}",
                         f"write {field}: orca, or {field}: {{kind: orca, time_horizon: 2}}")
    if not isinstance(kind, str) or kind not in CONTROLLERS:
        where = field if isinstance(value, str) else f"{field}.kind"
        raise SceneError(where, f"unknown controller {show(kind)}",
                         f"use one of {list(CONTROLLERS)}")
    table = PARAMETERS[kind]
    for key in given:
        if key not in table:
            raise SceneError(f"{field}.{key}", f"is not a parameter of controller {kind}",
                             f"remove it or use one of {sorted(table) or 'no parameters'}")
    params: dict[str, float] = {}
    for key, (default, low, high, unit, _) in table.items():
        if key in given:
            v = checks.number(given[key], f"{field}.{key}")
            if not low <= v <= high:
                raise SceneError(f"{field}.{key}", f"{show(v)} {unit} is outside "
                                 f"[{low:g}, {high:g}]".replace("  ", " "),
                                 f"set {field}.{key} between {low:g} and {high:g} {unit}"
                                 .rstrip())
            if key == "neighbours" and not float(v).is_integer():
                raise SceneError(f"{field}.{key}", f"must be a whole number, got {show(v)}",
                                 f"set {field}.{key} to a whole number of people")
            params[key] = float(v)
        elif default is None:  # sensor_range: the scan's, within the bounds
            params[key] = min(max(scan_range if scan_range is not None
                                  else DEFAULT_SENSOR_RANGE, low), high)
        else:
            params[key] = float(default)
    if kind != "none" and not has_goal:
        goal_field = field.rsplit(".", 1)[0] + ".goal"
        raise SceneError(goal_field, f"missing: controller {kind} drives to a goal",
                         f"add {goal_field}: [x, y], or set {field}: none")
    spec: Any = {"kind": kind, **{k: params[k] for k in given}} if given else kind
    return kind, params, spec


def sensor_range(params: dict[str, float]) -> float:
    """The distance (m) within which a controller with these parameters sees people (inf for
    the ones that see the scan only)."""
    return params.get("sensor_range", math.inf)
