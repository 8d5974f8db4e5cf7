"""Commands and maps from ROS messages for sweep_node, as pure functions (no node, no engine
state).

Incoming crowd commands are parsed and validated here (:func:`uniform_from_twist`,
:func:`goal_from_point`; velocity-field clouds in :mod:`sweep_ros.clouds`), and maps
(:func:`map_from_grid`); anything malformed raises :class:`CommandError` and never reaches the
engine. :func:`time_msg` builds a builtin_interfaces/Time. Outgoing markers are in
:mod:`sweep_ros.markers`, diagnostics in :mod:`sweep_ros.diagnostics`.
"""
from __future__ import annotations

import math
import re
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time

from sweep_core import SceneError
from sweep_core.checks import COORDINATE_BOUND
from sweep_core.errors import show
from sweep_core.model import elementary
from sweep_core.model.fields import Goal, Uniform
from sweep_core.model.maps import OccupancyMap

#: goals farther than this from the origin (m) are refused: the scene's coordinate bound, within
#: which float64 distances hold (sweep_core.checks.COORDINATE_BOUND)
MAX_COORDINATE = COORDINATE_BOUND


class CommandError(ValueError):
    """A command that must not reach the engine: ``topic: problem``."""

    def __init__(self, topic: str, problem: str) -> None:
        self.topic = topic
        self.problem = problem
        super().__init__(f"{topic}: {problem}")

    def __reduce__(self) -> tuple:
        """Pickled with its arguments (a worker process sends it to its parent)."""
        return (type(self), (self.topic, self.problem), self.__dict__)


# ---------------------------------------------------------------------------------------------
# Time
# ---------------------------------------------------------------------------------------------

def time_msg(stamp_ns: int) -> Time:
    """builtin_interfaces/Time of integer nanoseconds (nanosec always in [0, 1e9))."""
    sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
    return Time(sec=sec, nanosec=nsec)


def stamp_ns_of(stamp: Time) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


# ---------------------------------------------------------------------------------------------
# Commands
# ---------------------------------------------------------------------------------------------

def check_speed(topic: str, speed: float, max_speed: float) -> None:
    """Refuses (:class:`CommandError`) a command faster than ``max_speed`` (m/s)."""
    if speed > max_speed:
        raise CommandError(topic, f"speed {speed:.6g} m/s exceeds max_speed {max_speed:g} m/s "
                                  "(fix: send a slower field or raise the max_speed parameter)")


def uniform_from_twist(msg: Any, max_speed: float, topic: str = "crowd/cmd_vel") -> Uniform:
    """geometry_msgs/Twist -> uniform field (linear.x, linear.y); the other components must be
    finite and are ignored."""
    values = [msg.linear.x, msg.linear.y, msg.linear.z,
              msg.angular.x, msg.angular.y, msg.angular.z]
    if not all(math.isfinite(v) for v in values):
        raise CommandError(topic, f"non-finite component in linear {show(values[:3])} / "
                                  f"angular {show(values[3:])} (fix: send finite numbers; "
                                  "linear.x and linear.y are the velocity, m/s)")
    v = np.array([float(msg.linear.x), float(msg.linear.y)])
    check_speed(topic, float(np.hypot(*v)), max_speed)
    return Uniform(velocity=v)


def goal_point(msg: Any, frame_id: str, topic: str = "goal") -> np.ndarray:
    """geometry_msgs/PointStamped -> the goal (2,) m, checked: finite, within MAX_COORDINATE of
    the origin; the header's frame must be empty or ``frame_id`` (there is no TF lookup)."""
    frame = msg.header.frame_id
    if frame not in ("", frame_id):
        raise CommandError(topic, f"frame {show(frame)} is not the simulation frame {frame_id!r} "
                                  f"(fix: send the goal in {frame_id!r})")
    p = [msg.point.x, msg.point.y, msg.point.z]
    if not all(math.isfinite(c) for c in p):
        raise CommandError(topic, f"non-finite goal {show(p)} (fix: send finite coordinates, m)")
    if max(abs(p[0]), abs(p[1])) > MAX_COORDINATE:
        raise CommandError(topic, f"goal {show(p[:2])} is more than {MAX_COORDINATE:g} m away "
                                  f"(fix: send a goal within {MAX_COORDINATE:g} m of the origin "
                                  f"of {frame_id!r})")
    return np.array([float(p[0]), float(p[1])])


def goal_from_point(msg: Any, speed: float, slow_radius: float, frame_id: str,
                    topic: str = "goal") -> Goal:
    """geometry_msgs/PointStamped -> straight goal-directed field at ``speed`` (see
    :func:`goal_point`)."""
    return Goal(goal=goal_point(msg, frame_id, topic), speed=float(speed),
                slow_radius=float(slow_radius))


#: the fields of a geodesic drift spec and the node's parameters that set them
_GOAL_PARAMETERS = {"cell": "parameter goal_cell", "wall_buffer": "parameter goal_wall_buffer",
                    "goal": "the goal", "speed": "the speed"}


def navigation_refusal(topic: str, err: SceneError, field: str = "goal",
                       members: np.ndarray | None = None) -> CommandError:
    """A geodesic field's SceneError (its ``field.key`` names) as a command refusal naming
    the node's parameters instead (``goal.cell`` -> ``parameter goal_cell``); ``members``: the
    scene's indices of the agents the field was built for (a group's), so that an agent the
    error names by its place among them is named by its index in the scene."""
    problem, fix = err.problem, err.fix
    if members is not None:
        problem = re.sub(r"\bagent (\d+) at",
                         lambda m: f"agent {int(members[int(m.group(1))])} at", problem)
    for key, name in _GOAL_PARAMETERS.items():
        problem = problem.replace(f"{field}.{key}", name)
        fix = fix.replace(f"{field}.{key}", name)
    where = err.field.removeprefix(field).lstrip(".")
    what = _GOAL_PARAMETERS.get(where, "the geodesic field")
    return CommandError(topic, f"{what} refused: {problem}" + (f" (fix: {fix})" if fix else ""))


#: largest |roll| or |pitch| quaternion component of a map's origin taken as planar
PLANAR_TOLERANCE = 1e-6

#: a quaternion of a smaller norm names no rotation (it is refused)
MIN_QUATERNION_NORM = 1e-9

#: a quaternion whose largest |component| exceeds this is scaled down first (its squares would
#: overflow to inf)
QUATERNION_SCALE_BOUND = 2.0 ** 500


def bounded_quaternion(quat: list[float]) -> list[float]:
    """The finite quaternion ``quat`` (x, y, z, w), or, when its largest |component| exceeds
    QUATERNION_SCALE_BOUND, it times the power of two that brings that component into
    [0.5, 1): exact, so it names the same rotation, and its norm, products and yaw stay
    finite (a component of 1e200 squared is inf)."""
    big = max(abs(c) for c in quat)
    if big <= QUATERNION_SCALE_BOUND:
        return quat
    shift = math.frexp(big)[1]
    return [math.ldexp(c, -shift) for c in quat]


def map_from_grid(msg: Any, frame_id: str, topic: str = "map") -> OccupancyMap:
    """nav_msgs/OccupancyGrid -> OccupancyMap (its cells, resolution and origin; a cell is
    free iff its occupancy is 0..24 %, the map files' free_thresh 0.25). The header's frame
    must be empty or ``frame_id`` (there is no TF lookup); the origin's orientation must be a
    rotation about z."""
    frame = msg.header.frame_id
    if frame not in ("", frame_id):
        raise CommandError(topic, f"frame {show(frame)} is not the simulation frame {frame_id!r} "
                                  f"(fix: publish the map in {frame_id!r}, or set the node's "
                                  f"frame_id to {show(frame)})")
    info = msg.info
    o, p = info.origin.orientation, info.origin.position
    quat = [o.x, o.y, o.z, o.w]
    if not all(math.isfinite(c) for c in quat + [p.x, p.y]):
        raise CommandError(topic, f"non-finite info.origin {show([p.x, p.y] + quat)} (fix: "
                                  "publish a finite origin pose)")
    qx, qy, qz, qw = bounded_quaternion(quat)
    norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    if norm < MIN_QUATERNION_NORM:
        raise CommandError(topic, f"info.origin.orientation {show(quat)} is not a rotation "
                                  f"about z: its norm {norm:.3g} is below "
                                  f"{MIN_QUATERNION_NORM:g} (fix: publish a unit quaternion, "
                                  "x = y = 0, z = sin(yaw / 2), w = cos(yaw / 2))")
    if max(abs(qx), abs(qy)) > PLANAR_TOLERANCE * norm:
        raise CommandError(topic, f"info.origin.orientation {show(quat)} is not a rotation "
                                  "about z (fix: publish a planar map, quaternion x = y = 0)")
    yaw = 2.0 * elementary.atan2(qz, qw)
    if not math.isfinite(info.resolution):
        raise CommandError(topic, f"info.resolution {show(info.resolution)} is not finite "
                                  "(fix: publish the cell size, m)")
    try:
        return OccupancyMap.from_occupancy_grid(
            np.asarray(msg.data, dtype=np.int8), int(info.width), int(info.height),
            float(info.resolution), (float(p.x), float(p.y), yaw), source=topic, field="grid")
    except SceneError as err:
        where = "the grid" if err.field == "grid" else err.field.removeprefix("grid.")
        fix = err.fix.replace("grid.", "")
        raise CommandError(topic, f"{where} {err.problem} (fix: {fix})") from err
