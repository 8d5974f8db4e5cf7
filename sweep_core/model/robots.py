"""Robots of a scene (the ``robots:`` list) and how the crowd reacts to them
(``crowd_reaction:``): schema, validation, placement checks.

A robot is a disk of ``radius`` m that takes part in the projection as an extra disk, with a
``weight`` w in its metric min sum_i w_i |x_i - p_i|^2 (people have weight 1): ``inf`` means its
motion is prescribed (the crowd must yield), 1 that it is pushed like a person. It is not an
agent: the crowd's arrays, ``/poses`` and ``/agents`` hold people only. Footprints are disks
only (a polygon footprint is not supported: its contact rows with disks are not convex in the
robot's pose once it turns).

Kinematics: ``diff_drive`` takes (v, omega), ``holonomic`` (vx, vy, omega), in the robot's
frame (base_link), m/s and rad/s, clipped to ``max_speed``, ``max_angular_speed`` and, against
the last applied command, ``max_acceleration`` / ``max_angular_acceleration`` (per second).

The crowd's reaction ``avoid``: every person within ``radius`` m of the segment from a robot's
centre to where its current velocity takes it in ``horizon`` s gets a term added to its wished
velocity, ``strength`` (1 - d / radius) m/s along the direction from the nearest point of that
segment to the person (d the distance to the segment, m): people step aside from where the
robot is going, more the closer they are.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from sweep_core import checks
from sweep_core.errors import SceneError, show
from sweep_core.model.controller_spec import controller_from_spec
from sweep_core.model.gaps import gaps
from sweep_core.model.geometry import DENSE_SEGMENTS, Geometry, inside_polygons
from sweep_core.model.wall_kernels import single_gaps

KINEMATICS = ("diff_drive", "holonomic")
REACTIONS = ("none", "avoid")
NAME = re.compile(r"[a-z][a-z0-9_]*\Z")
MAX_ROBOTS = 16
#: most beams of one scan
MAX_BEAMS = 20_000
#: largest angular speed (rad/s) of a robot: the yaw is wrapped into (-pi, pi] every step and a
#: step of the longest time step (1 s, io/limits.py) evaluates the heading at
#: yaw + omega h / 2, within pi + 500 rad, where one ulp is 1.1e-13 rad; a fast wheeled robot
#: turns at about 10 rad/s. At 1e308 rad/s the yaw overflowed and the arc's sine failed.
MAX_ANGULAR_SPEED = 1e3
#: largest accelerations (m/s^2, rad/s^2): a change of the speed bound within the smallest
#: time step, 1e-5 s (io/limits.py DT_MIN, which model may not import): MAX_SPEED / 1e-5 and
#: MAX_ANGULAR_SPEED / 1e-5; any larger limit clips nothing more. Written out (a quotient may
#: round below the documented value and refuse it).
MAX_ACCELERATION = 1e9
MAX_ANGULAR_ACCELERATION = 1e8
#: finite weights of a robot in the projection's metric: its column of the rows is scaled by
#: 1 / sqrt(w), so w in [1e-6, 1e6] keeps those scales within 1e3 of the people's 1 (at
#: w = 1e-16 the scale 1e8 made a feasible push fail); beyond, inf (prescribed) or 1 serve
WEIGHT_RANGE = (1e-6, 1e6)
#: scan rates (Hz): LaserScan's float32 scan_time 1 / rate and the steps between scans
#: round(1 / (rate dt)) stay representable; above 1 / DT_MIN a scan is taken every step anyway
#: (written out, so that the documented 100000 Hz is the bound to the last bit)
SCAN_RATE_RANGE = (1e-3, 1e5)
#: largest ``crowd_reaction.horizon`` (s): a robot at the largest speed (checks.MAX_SPEED,
#: 1e4 m/s) reaches at most the agents' position bound (checks.POSITION_BOUND, 1e6 m) along
#: the segment of its horizon; people anticipate a few seconds. Beyond 1.3e154 s the
#: segment's squared length overflowed and the reaction acted as horizon 0.
MAX_REACTION_HORIZON = 100.0
_KEYS = {"name", "radius", "pose", "kinematics", "weight", "goal", "goal_radius", "controller",
         "scan", "enabled"}
_KIN_KEYS = {"type", "max_speed", "max_angular_speed", "max_acceleration",
             "max_angular_acceleration"}
_SCAN_KEYS = {"range_min", "range_max", "angle_min", "angle_max", "increment", "rate",
              "noise_std"}


@dataclass(frozen=True)
class ScanSpec:
    """A planar laser scanner at the robot's centre: ranges in [range_min, range_max] m, beams
    at angle_min + k increment (rad, robot frame) for k = 0 .. beams - 1, ``rate`` Hz,
    Gaussian range noise of ``noise_std`` m."""

    range_min: float
    range_max: float
    angle_min: float
    angle_max: float
    increment: float
    rate: float
    noise_std: float

    @property
    def beams(self) -> int:
        """Beams from angle_min to angle_max inclusive, except that a full turn does not repeat
        its first beam at its end."""
        count = int(math.floor((self.angle_max - self.angle_min) / self.increment + 1e-9)) + 1
        if count > 1 and self.angle_min + (count - 1) * self.increment >= \
                self.angle_min + 2 * math.pi - 1e-9:
            count -= 1
        return count

    def angles(self) -> np.ndarray:
        """(beams,) beam angles in the robot frame (rad)."""
        return self.angle_min + self.increment * np.arange(self.beams, dtype=np.float64)


@dataclass(frozen=True)
class Robot:
    """One robot of the scene (see the module docstring); lengths m, angles rad, speeds m/s and
    rad/s, accelerations m/s^2 and rad/s^2; ``weight`` > 0 or inf."""

    name: str
    radius: float
    pose: tuple[float, float, float]
    kinematics: str
    max_speed: float
    max_angular_speed: float
    max_acceleration: float
    max_angular_acceleration: float
    weight: float
    goal: tuple[float, float] | None
    goal_radius: float
    controller: str
    scan: ScanSpec | None
    #: the controller's parameters (model/controller_spec.py), every one, as (name, value)
    controller_params: tuple[tuple[str, float], ...] = ()

    @property
    def prescribed(self) -> bool:
        return math.isinf(self.weight)

    @property
    def params(self) -> dict[str, float]:
        """The controller's parameters by name."""
        return dict(self.controller_params)


@dataclass(frozen=True)
class CrowdReaction:
    """How people react to robots: ``kind`` none or avoid (module docstring); radius m,
    horizon s, strength m/s."""

    kind: str = "none"
    radius: float = 2.0
    horizon: float = 1.0
    strength: float = 0.8


def _weight(value: Any, field: str) -> float:
    if isinstance(value, str) and value.strip().lower() in ("inf", ".inf", "infinity"):
        return math.inf
    if isinstance(value, float) and value == math.inf:
        return math.inf
    lo, hi = WEIGHT_RANGE
    fix = (f"set {field} to a number in [{lo:g}, {hi:g}] (1: pushed like a person) or inf "
           "(prescribed motion)")
    w = checks.number(value, field, positive=True, fix=fix)
    if not lo <= w <= hi:
        raise SceneError(field, f"{show(w)} is outside [{lo:g}, {hi:g}]: the projection scales "
                         "the robot's rows by 1 / sqrt(weight), too far from the people's 1 to "
                         "solve reliably", fix)
    return w


def _bounded(value: float, field: str, high: float, unit: str, why: str) -> float:
    if value > high:
        raise SceneError(field, f"{show(value)} {unit} is above {high:g} {unit} ({why})",
                         f"set {field} to at most {high:g} {unit}")
    return value


def _rounded_up(x: float, digits: int = 4) -> str:
    """``x`` > 0 written with ``digits`` significant digits, rounded up: the text's value is
    never below x (a bound that a user can copy and that is then accepted)."""
    text = f"{x:.{digits}g}"
    if float(text) < x:
        exponent = math.floor(math.log10(x)) - digits + 1
        text = f"{float(text) + 10.0 ** exponent:.{digits}g}"
    return text


def _scan(value: Any, field: str) -> ScanSpec:
    d = checks.mapping(value, field, allowed=_SCAN_KEYS)
    r0 = checks.length(d.get("range_min", 0.05), f"{field}.range_min", nonnegative=True)
    r1 = checks.length(d.get("range_max", 10.0), f"{field}.range_max", positive=True)
    if r1 <= r0:
        raise SceneError(f"{field}.range_max", f"{show(r1)} m is not above range_min {show(r0)} m",
                         f"set {field}.range_max above {field}.range_min")
    a0 = checks.number(d.get("angle_min", -math.pi), f"{field}.angle_min")
    a1 = checks.number(d.get("angle_max", math.pi), f"{field}.angle_max")
    if not -2 * math.pi <= a0 <= a1 <= 2 * math.pi or a1 - a0 > 2 * math.pi + 1e-9:
        raise SceneError(f"{field}.angle_max", f"[{show(a0)}, {show(a1)}] rad is not an "
                         "interval of at most one turn within [-2 pi, 2 pi]",
                         f"give {field}.angle_min <= angle_max, at most 2 pi apart")
    inc = checks.number(d.get("increment", math.pi / 180), f"{field}.increment", positive=True)
    least = _rounded_up((a1 - a0) / (MAX_BEAMS - 1))
    if (a1 - a0) / inc > MAX_BEAMS or inc > 2 * math.pi:
        raise SceneError(f"{field}.increment", f"{show(inc)} rad is outside [{least}, "
                         f"2 pi] rad: more than {MAX_BEAMS} beams over [{show(a0)}, {show(a1)}] "
                         "rad, or more than a turn between beams",
                         f"set {field}.increment to at least {least} rad and at most 2 pi")
    rate = checks.number(d.get("rate", 10.0), f"{field}.rate", positive=True)
    lo, hi = SCAN_RATE_RANGE
    if not lo <= rate <= hi:
        raise SceneError(f"{field}.rate", f"{show(rate)} Hz is outside [{lo:g}, {hi:g}] Hz "
                         "(a scan every 1000 s at least; above, one every step anyway)",
                         f"set {field}.rate to a rate in [{lo:g}, {hi:g}] Hz, e.g. 10")
    noise = checks.number(d.get("noise_std", 0.0), f"{field}.noise_std", nonnegative=True)
    if noise > r1:
        raise SceneError(f"{field}.noise_std", f"{show(noise)} m is above range_max "
                         f"{show(r1)} m", f"set {field}.noise_std to at most range_max (a "
                         "laser's range noise is about 0.01 m)")
    spec = ScanSpec(r0, r1, a0, a1, inc, rate, noise)
    if spec.beams > MAX_BEAMS:
        raise SceneError(f"{field}.increment", f"{show(inc)} rad gives {spec.beams} beams, more "
                         f"than {MAX_BEAMS}", f"set {field}.increment to at least {least} rad")
    return spec


def _robot(value: Any, field: str) -> tuple[Robot, dict]:
    d = checks.mapping(value, field, allowed=_KEYS, required={"name", "radius", "pose"})
    name = d["name"]
    if not isinstance(name, str) or not NAME.match(name) or len(name) > 64:
        raise SceneError(f"{field}.name", f"{show(name)} is not a robot name",
                         "use lowercase letters, digits and _, starting with a letter "
                         "(it becomes a ROS namespace)")
    radius = checks.length(d["radius"], f"{field}.radius", positive=True, what="radius")
    pose = checks.array(d["pose"], f"{field}.pose", (3,), "as [x, y, yaw]")
    checks.within_bound(pose[:2], f"{field}.pose")
    kin = checks.mapping(d.get("kinematics") or {}, f"{field}.kinematics", allowed=_KIN_KEYS)
    kind = kin.get("type", "diff_drive")
    if kind not in KINEMATICS:
        raise SceneError(f"{field}.kinematics.type", f"unknown kinematics {show(kind)}",
                         f"use one of {list(KINEMATICS)}")
    limits = {key: checks.number(kin.get(key, default), f"{field}.kinematics.{key}",
                                 positive=True)
              for key, default in (("max_speed", 1.0), ("max_angular_speed", 1.5),
                                   ("max_acceleration", 2.0), ("max_angular_acceleration", 4.0))}
    checks.speed(limits["max_speed"], f"{field}.kinematics.max_speed", positive=True)
    for key, high, unit, why in (
            ("max_angular_speed", MAX_ANGULAR_SPEED, "rad/s", "the heading of a step of 1 s "
             "would lose its precision; robots turn at about 10 rad/s"),
            ("max_acceleration", MAX_ACCELERATION, "m/s^2", "the speed bound reached within "
             "the smallest time step; a larger limit clips nothing more"),
            ("max_angular_acceleration", MAX_ANGULAR_ACCELERATION, "rad/s^2", "the angular "
             "speed bound reached within the smallest time step; a larger limit clips nothing "
             "more")):
        _bounded(limits[key], f"{field}.kinematics.{key}", high, unit, why)
    weight = _weight(d.get("weight", "inf"), f"{field}.weight")
    goal = None
    if d.get("goal") is not None:
        g = checks.point(d["goal"], f"{field}.goal")
        goal = (float(g[0]), float(g[1]))
    goal_radius = checks.length(d.get("goal_radius", 0.5), f"{field}.goal_radius", positive=True)
    scan = _scan(d["scan"], f"{field}.scan") if d.get("scan") is not None else None
    controller, params, controller_spec = controller_from_spec(
        d.get("controller", "none"), f"{field}.controller", goal is not None,
        None if scan is None else scan.range_max)
    robot = Robot(name, radius, (float(pose[0]), float(pose[1]), float(pose[2])), kind,
                  weight=weight, goal=goal, goal_radius=goal_radius, controller=controller,
                  scan=scan, controller_params=tuple(params.items()), **limits)
    spec: dict = {"name": name, "radius": radius, "pose": pose.tolist(),
                  "kinematics": {"type": kind, **limits},
                  "weight": "inf" if math.isinf(weight) else weight,
                  "goal_radius": goal_radius, "controller": controller_spec}
    if goal is not None:
        spec["goal"] = list(goal)
    if scan is not None:
        spec["scan"] = {k: getattr(scan, k) for k in ("range_min", "range_max", "angle_min",
                                                      "angle_max", "increment", "rate",
                                                      "noise_std")}
    enabled = d.get("enabled", True)
    if isinstance(enabled, str) and enabled.lower() in ("true", "false"):  # --vary gives text
        enabled = enabled.lower() == "true"
    if not isinstance(enabled, bool):
        raise SceneError(f"{field}.enabled", f"must be true or false, got {show(enabled)}",
                         f"set {field}.enabled to true or false")
    spec["enabled"] = enabled
    return robot, spec


def robots_from_spec(value: Any, geometry: Geometry, positions: np.ndarray,
                     radii: np.ndarray, blocked: Any = None) -> tuple[tuple[Robot, ...], list]:
    """The scene's ``robots`` list validated, and its normalised spec. Each robot must not
    overlap a person (``positions`` (N, 2), ``radii`` (N,) at t = 0), another robot, a wall or
    an obstacle, nor stand in a blocked map cell (``blocked(points) -> (n,) bool``)."""
    value = checks.items(value, "robots",
                         "write robots as a list of mappings, one '- name: ...' per robot")
    if not value:
        return (), []
    if len(value) > MAX_ROBOTS:
        raise SceneError("robots", f"has {len(value)} robots, more than {MAX_ROBOTS}",
                         f"keep at most {MAX_ROBOTS} robots")
    robots: list[Robot] = []
    specs: list[dict] = []
    for k, item in enumerate(value):
        robot, spec = _robot(item, f"robots[{k}]")
        if any(s["name"] == robot.name for s in specs):
            raise SceneError(f"robots[{k}].name", f"{show(robot.name)} is used twice",
                             "give every robot its own name")
        specs.append(spec)
        if spec["enabled"]:  # enabled: false keeps it in the spec only (paired ensembles)
            robots.append(robot)
    for k, robot in enumerate(robots):
        others = [(r.pose[0], r.pose[1], r.radius, f"robot {r.name}") for r in robots[:k]]
        problem = overlap(robot, robot.pose[:2], geometry, positions, radii, others, blocked)
        if problem:
            index = next(i for i, s in enumerate(specs) if s["name"] == robot.name)
            raise SceneError(f"robots[{index}].pose", problem,
                             f"move robot {robot.name} to free space, at least its radius "
                             f"{robot.radius:g} m from walls and clear of people")
    return tuple(robots), specs


def overlap(robot: Robot, xy: Any, geometry: Geometry, positions: np.ndarray, radii: np.ndarray,
            others: list[tuple[float, float, float, str]], blocked: Any = None,
            t: float = 0.0, tol: float = 1e-9, ids: np.ndarray | None = None) -> str:
    """What the robot's disk at ``xy`` (m) overlaps, as a message ('' when nothing): a person,
    another robot (``others``: (x, y, radius, label)), a wall or obstacle at time t, or a
    blocked map cell. ``ids``: the people's ids, row by row of ``positions`` (None: the rows
    are the ids)."""
    c = np.array([[float(xy[0]), float(xy[1])]])

    def where() -> str:  # formatted only for a message (every robot's every step asks)
        return f"robot {robot.name} at {show(c[0])} (radius {robot.radius:g} m)"

    if len(positions):
        d = np.hypot(*(positions - c).T) - radii - robot.radius
        a = int(np.argmin(d))
        if d[a] < -tol:
            who = a if ids is None else int(ids[a])
            return f"{where()} overlaps agent {who} at {show(positions[a])} by {-d[a]:.3g} m"
    for x, y, r, label in others:
        gap = math.hypot(c[0, 0] - x, c[0, 1] - y) - r - robot.radius
        if gap < -tol:
            return f"{where()} overlaps {label} by {-gap:.3g} m"
    if not geometry.is_empty and not _clear_of_geometry(geometry, t, c, robot.radius, tol):
        g = gaps(geometry, t, c, np.array([robot.radius]))
        if g.worst_single is not None and g.min_single < -tol:
            _, kind, item, gap = g.worst_single
            return f"{where()} overlaps {geometry.describe(kind, item)} by {-gap:.3g} m"
    if blocked is not None and bool(blocked(c)[0]):
        return f"{where()} has its centre in a blocked (occupied or unknown) cell of the map"
    return ""


_NO_POLYGON = np.zeros((0, 0), dtype=np.bool_)


def _clear_of_geometry(geometry: Geometry, t: float, c: np.ndarray, radius: float,
                       tol: float) -> bool:
    """True when the disk at c (1, 2) m of the radius (m) surely clears every wall and
    obstacle at time t by more than -tol: the compiled pass :func:`gaps` makes for one disk
    (the same kernel, arguments and values), without its summary. False when unsure (a user
    constraint, a NaN value, many segments) or overlapping: the caller then asks :func:`gaps`."""
    here = geometry.at(t)
    if here.user or len(here.segment_a) > DENSE_SEGMENTS:
        return False
    hn, _, sa, sb, cc, cr = here.packed
    inside = inside_polygons(c, here) if here.has_polygons else _NO_POLYGON
    contact_tol = 1e-6  # gaps' default, so that the kernel does the same work
    out = np.empty(6)
    single_gaps(c, np.array([float(radius)]), hn, here.offsets(t), sa, sb, inside, cc, cr,
                contact_tol, max(contact_tol, 2.0 * float(radius), 1e-3),
                np.empty(len(hn) + len(sa) + len(cr)), np.empty(len(sa), dtype=np.intp),
                np.empty(len(sa), dtype=np.intp), out)
    if out[3] == -2.0:  # a NaN value
        return False
    return bool(out[3] < 0 or out[2] >= -tol)


def reaction_from_spec(value: Any) -> tuple[CrowdReaction, dict]:
    """The scene's ``crowd_reaction`` validated, and its normalised spec."""
    d = checks.mapping(value or {}, "crowd_reaction",
                       allowed={"kind", "radius", "horizon", "strength"})
    kind = checks.kind(d, "crowd_reaction", REACTIONS, default="none")
    reaction = CrowdReaction(
        kind,
        checks.length(d.get("radius", 2.0), "crowd_reaction.radius", positive=True),
        _bounded(checks.number(d.get("horizon", 1.0), "crowd_reaction.horizon",
                               nonnegative=True), "crowd_reaction.horizon",
                 MAX_REACTION_HORIZON, "s", "over it a robot at the largest speed, 1e4 m/s, "
                 "would pass the position bound 1e6 m; people anticipate a few seconds"),
        checks.speed(d.get("strength", 0.8), "crowd_reaction.strength"))  # m/s
    return reaction, {"kind": kind, "radius": reaction.radius, "horizon": reaction.horizon,
                      "strength": reaction.strength}
