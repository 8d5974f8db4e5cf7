"""Robot controllers without ROS: what a controller sees (:class:`Observation`), what it is
(:class:`Controller`, any callable of an observation returning (vx, vy, omega) in the robot's
frame, m/s and rad/s; the fleet clips it to the limits), and the bundled :class:`Pursuit`
(the planners that see people are in :mod:`.planners`).

``Pursuit`` follows a geodesic field to the goal (computed once, round the walls, obstacles and
map cells, keeping ``wall_buffer`` = the robot's radius + 0.1 m from them): it turns towards the
field's direction at ``turn_gain`` times the heading error (rad/s per rad), drives at the
field's speed (the robot's max_speed, slowing within 0.5 m of the goal) times cos(error) (not
backwards), and slows for the scan's nearest return within ``cone`` (45 degrees) of its
direction of travel: speed factor min(1, max(0, (range - radius - stop_margin) / slow_distance)). It stops
inside the goal radius.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol

import numba
import numpy as np

from sweep_core.model import elementary
from sweep_core.model.controller_spec import sensor_range
from sweep_core.model.geodesic import navigation_from_spec
from sweep_core.model.maps import map_from_spec
from sweep_core.model.robots import Robot
from sweep_core.model.scene import Scene
from sweep_core.numerics.robots.kinematics import clip, wrap
from sweep_core.numerics.robots.scan import Scan


@dataclass(frozen=True)
class Observation:
    """What a controller sees at time ``t`` (s): the robot's ``pose`` (x, y, yaw) m, rad
    (exact odometry), ``twist`` (vx, vy, omega) of the last step in its frame, its latest
    ``scan`` (or None), its ``goal`` (x, y) or None, ``goal_radius`` and ``radius`` (m);
    ``people`` (M, 2) m and ``people_radii`` (M,) m: the people whose disks come within the
    controller's sensor range of the robot's centre (empty for a controller that sees the scan
    only), in the order of the simulator's arrays; ``command`` the command applied over the
    last step (robot frame; None: ``twist``) and ``dt`` the step (s; 0: unknown, no
    acceleration limit applied by the controller)."""

    t: float
    pose: tuple[float, float, float]
    twist: tuple[float, float, float]
    scan: Scan | None
    goal: tuple[float, float] | None
    goal_radius: float
    radius: float
    people: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))
    people_radii: np.ndarray = field(default_factory=lambda: np.empty(0))
    command: tuple[float, float, float] | None = None
    dt: float = 0.0


class Controller(Protocol):
    def __call__(self, obs: Observation) -> tuple[float, float, float]: ...


def observe(state: Any, t: float, people: np.ndarray | None = None,
            radii: np.ndarray | None = None, dt: float = 0.0) -> Observation:
    """The observation of a fleet's ``RobotState`` at time t (s): of ``people`` (N, 2) m with
    ``radii`` (N,) m, those whose disk comes within the controller's ``sensor_range`` (m) of
    the robot's centre (none for a controller without one); ``dt`` the step (s)."""
    r = state.robot
    reach = sensor_range(r.params)
    seen, seen_r = np.empty((0, 2)), np.empty(0)
    if people is not None and radii is not None and len(people) and math.isfinite(reach):
        near = np.empty(len(people), dtype=np.bool_)
        within_reach(np.ascontiguousarray(people, dtype=np.float64),
                     np.ascontiguousarray(radii, dtype=np.float64), float(state.pose[0]),
                     float(state.pose[1]), float(reach), near)
        seen, seen_r = people[near], radii[near]
    return Observation(t, state.pose, state.twist, state.scan, r.goal, r.goal_radius, r.radius,
                       seen, seen_r, state.command, dt)


@numba.njit(cache=True, nogil=True)
def within_reach(people: np.ndarray, radii: np.ndarray, x: float, y: float, reach: float,
                 near: np.ndarray) -> None:  # pragma: no cover - compiled
    """near (M,) = whether the disk of each person (``people`` (M, 2) m, ``radii`` (M,) m)
    comes within ``reach`` m of (x, y): hypot(dx, dy) - radius <= reach, the C library's
    hypot as numpy's, in numpy's order (NaN: not near)."""
    for k in range(people.shape[0]):
        near[k] = math.hypot(people[k, 0] - x, people[k, 1] - y) - radii[k] <= reach


def goal_field(scene: Scene, robot: Robot) -> Any:
    """The geodesic field to the robot's goal at its max_speed, round the walls, obstacles and
    map cells with ``wall_buffer`` = its radius + 0.1 m, built once (the global plan of every
    bundled controller)."""
    if robot.goal is None:
        raise ValueError(f"robot {robot.name} has no goal to pursue")
    grid = map_from_spec(scene.spec["map"], "map", None) if scene.spec.get("map") else None
    index = scene.robots.index(robot)
    return navigation_from_spec(
        {"kind": "geodesic", "goal": list(robot.goal), "speed": robot.max_speed,
         "wall_buffer": robot.radius + 0.1}, f"robots[{index}].goal", scene.geometry, grid,
        np.array([robot.pose[:2]]))


def feasible(robot: Robot, wanted: tuple[float, float, float], obs: Observation
             ) -> tuple[float, float, float]:
    """``wanted`` (vx, vy, omega) clipped to the robot's kinematic limits (speed, angular
    speed and, when ``obs.dt`` > 0, acceleration against the last applied command), so that
    the fleet applies it unchanged."""
    last = obs.command if obs.command is not None else obs.twist
    if obs.dt > 0:
        return clip(robot, wanted, last, obs.dt)[0]
    return _speed_only(robot, wanted)


def _speed_only(robot: Robot, wanted: tuple[float, float, float]
                ) -> tuple[float, float, float]:
    vx, vy, omega = wanted
    if robot.kinematics == "diff_drive":
        vy = 0.0
    speed = math.hypot(vx, vy)
    if speed > robot.max_speed:
        vx, vy = vx * robot.max_speed / speed, vy * robot.max_speed / speed
    w = robot.max_angular_speed
    return (vx, vy, min(max(omega, -w), w))


class Pursuit:
    """The bundled controller (module docstring) of ``robot`` in ``scene``."""

    def __init__(self, scene: Scene, robot: Robot, *, turn_gain: float = 2.0,
                 slow_distance: float = 0.6, stop_margin: float = 0.05,
                 cone: float = math.pi / 4) -> None:
        self.field = goal_field(scene, robot)
        self.robot = robot
        self.turn_gain = turn_gain
        self.slow_distance = slow_distance
        self.stop_margin = stop_margin
        self.cone = cone

    def rescene(self, scene: Scene, field: Any) -> None:
        """Pursue the goal by ``scene``'s goal ``field`` (new walls, obstacles or map)."""
        self.field = field

    def __call__(self, obs: Observation) -> tuple[float, float, float]:
        x, y, yaw = obs.pose
        if obs.goal is not None and math.hypot(obs.goal[0] - x, obs.goal[1] - y) <= \
                obs.goal_radius:
            return (0.0, 0.0, 0.0)
        u = self.field(obs.t, np.array([[x, y]]))[0]
        speed = float(math.hypot(u[0], u[1]))
        if speed == 0.0:
            return (0.0, 0.0, 0.0)
        heading = elementary.atan2(u[1], u[0])
        error = wrap(heading - yaw)
        omega = self.turn_gain * error
        slow = 1.0
        if obs.scan is not None:
            rel = wrap_all(obs.scan.spec.angles() + obs.scan.pose[2] - heading)
            ahead = obs.scan.ranges[np.abs(rel) < self.cone]
            if len(ahead):
                nearest = float(ahead.min())
                slow = min(1.0, max(0.0, (nearest - obs.radius - self.stop_margin)
                                    / self.slow_distance))
        if self.robot.kinematics == "holonomic":
            s, c = elementary.sincos(yaw)
            v = speed * slow
            return (v * (c * u[0] + s * u[1]) / speed, v * (-s * u[0] + c * u[1]) / speed,
                    omega)
        return (speed * slow * max(0.0, elementary.cos(error)), 0.0, omega)


def wrap_all(angles: np.ndarray) -> np.ndarray:
    """Angles (rad) in [-pi, pi)."""
    return (angles + math.pi) % (2 * math.pi) - math.pi
