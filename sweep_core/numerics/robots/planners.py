"""The bundled local planners that steer round people, beside :class:`~.control.Pursuit`
(docs/robots.md): :class:`Orca` and :class:`SocialForce`, and :func:`controllers_of`, the
controllers a scene names.

What they see: the robot's own pose and last command (exact odometry), and the people whose
disks come within ``sensor_range`` m of its centre (:func:`.control.observe`), positions and
radii; their velocities are estimated by the planner itself (:class:`Tracker`: each person
matched to the nearest one of the previous observation, the velocity smoothed over
``TRACK_TIME`` s). Walls, obstacles and map cells are known (the map a robot navigates by): the
preferred velocity follows the geodesic field to the goal round them (:func:`.control.
goal_field`), and the wall segments and circle obstacles within the sensor range are obstacles
of the planner.

Both turn a wished velocity u (m/s, map frame) into a command (:func:`to_command`) through
the safety layer of :mod:`.guard` (passive motion safety: u replaced by the nearest velocity
from which the robot can be at rest before any person seen ahead, closing in at
``people_speed`` and by noise of ``people_noise``, comes within ``stop_margin``): holonomic
(u in the robot's frame, turning towards u, the change of command scaled as a whole into
the acceleration limit); diff_drive (turn rate ``turn_gain`` times the heading error, speed
|u| cos(error), never backwards, 0 beyond 90 degrees of error, at most the safe speed along
its heading), clipped to the robot's speed, angular speed and acceleration limits against its
last command, so the fleet applies it unchanged. The layer also bounds the speed along the
direction of travel by the braking distance to the wall segments and circle obstacles seen
(:class:`.guard.Walls`), so that a robot touching a wall turns before it moves off.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
import pyrvo

from sweep_core.model import elementary
from sweep_core.model.robots import Robot
from sweep_core.model.scene import Scene
from sweep_core.numerics.robots.control import (
    Controller,
    Observation,
    Pursuit,
    feasible,
    goal_field,
)
from sweep_core.numerics.robots.guard import Walls, nearest_safe, safe_speed
from sweep_core.numerics.robots.kinematics import wrap
from sweep_core.numerics.robots.social_kernels import (
    near_segments,
    people_terms,
    pushes,
    scaled_sum,
    track,
    wall_offsets,
)

#: the time (s) over which a tracked person's velocity is smoothed
TRACK_TIME = 0.5
#: farthest a person may move between two observations and keep its track (m)
GATE = 0.5
#: sides of the polygon circumscribing a circle obstacle for ORCA
CIRCLE_SIDES = 12
#: the time step (s) ORCA's collision case assumes when the observation gives none
DEFAULT_STEP = 0.05


class Tracker:
    """Velocities (m/s) of the people a robot sees, from their positions alone: each person of
    an observation takes the track of the nearest person of the previous one when they are
    each other's nearest and within :data:`GATE` m; a track's velocity v moves towards the
    displacement over the elapsed time dt by the factor 1 - exp(-dt / TRACK_TIME); a new
    track starts at rest."""

    def __init__(self) -> None:
        self.t: float | None = None
        self.xy = np.empty((0, 2))
        self.v = np.empty((0, 2))

    def update(self, t: float, xy: np.ndarray) -> np.ndarray:
        """(M, 2) velocities of the people at ``xy`` (M, 2) m seen at time t (s)."""
        v = np.zeros_like(xy)
        if self.t is not None and t > self.t and len(xy) and len(self.xy):
            dt = t - self.t
            a = 1.0 - elementary.exp(-dt / TRACK_TIME)
            track(np.ascontiguousarray(xy, dtype=np.float64), self.xy, self.v, dt, a,
                  GATE * GATE, v)
        self.t, self.xy, self.v = t, np.array(xy, dtype=np.float64), v
        return v


def to_command(robot: Robot, u: np.ndarray, obs: Observation, params: dict[str, float],
               walls: Walls | None = None
               ) -> tuple[float, float, float]:
    """The command (vx, vy, omega) that follows the wished velocity ``u`` (2,) m/s (module
    docstring): the nearest safe velocity (:func:`.guard.nearest_safe`), its speed at most
    the safe speed along the direction the robot moves in, within the robot's limits.
    ``walls``: the largest speed (m/s) along a unit direction (2,) from which the robot can
    stop short of the walls and obstacles (None: not limited by them)."""
    yaw = obs.pose[2]
    u = nearest_safe(u, obs.pose, obs.radius, obs.people, obs.people_radii,
                     robot.max_acceleration, params["stop_margin"], params["people_speed"],
                     people_noise=params["people_noise"])
    speed = float(math.hypot(u[0], u[1]))
    heading = elementary.atan2(u[1], u[0]) if speed > 1e-9 else yaw
    error = wrap(heading - yaw)
    omega = params["turn_gain"] * error if speed > 1e-9 else 0.0
    s, c = elementary.sincos(yaw)
    if robot.kinematics == "holonomic":
        along = u / speed if speed > 1e-9 else np.array([c, s])
    else:
        speed = speed * max(0.0, elementary.cos(error))
        along = np.array([c, s])
    speed = min(speed, safe_speed(obs.pose, along, obs.radius, obs.people, obs.people_radii,
                                  robot.max_acceleration, params["stop_margin"],
                                  params["people_speed"], params["people_noise"]),
                math.inf if walls is None else walls(along))
    if robot.kinematics == "holonomic":
        return holonomic_command(robot, speed * along, omega, obs, params, walls)
    return feasible(robot, (speed, 0.0, omega), obs)


def holonomic_command(robot: Robot, u: np.ndarray, omega: float, obs: Observation,
                      params: dict[str, float],
                      walls: Walls | None = None
                      ) -> tuple[float, float, float]:
    """The holonomic command towards the safe velocity ``u`` (2,) m/s (map frame): the change
    from the last command scaled as a whole into the acceleration limit (so that, from rest,
    the command is parallel to u); when the result is still faster than the safe speed along
    its own direction (or than ``walls`` allows, as in :func:`to_command`), the last command
    slowed as hard as the limit allows."""
    yaw = obs.pose[2]
    s, c = elementary.sincos(yaw)
    want = np.array([c * u[0] + s * u[1], -s * u[0] + c * u[1]])
    last = np.array((obs.command if obs.command is not None else obs.twist)[:2], dtype=float)
    step = robot.max_acceleration * obs.dt if obs.dt > 0 else math.inf
    change = want - last
    big = float(np.abs(change).max())
    v = last + change * (min(1.0, step / big) if big > 0 else 1.0)
    speed = float(np.hypot(*v))
    if speed > 1e-12:
        world = np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]]) / speed
        if speed > min(safe_speed(obs.pose, world, obs.radius, obs.people, obs.people_radii,
                                  robot.max_acceleration, params["stop_margin"],
                                  params["people_speed"], params["people_noise"]),
                       math.inf if walls is None else walls(world)):
            big = float(np.abs(last).max())
            v = last * (max(0.0, 1.0 - step / big) if big > 0 else 0.0)
    return feasible(robot, (float(v[0]), float(v[1]), omega), obs)


def world_velocity(obs: Observation) -> np.ndarray:
    """(2,) the robot's velocity over the last step in the map frame (m/s)."""
    vx, vy, _ = obs.twist
    s, c = elementary.sincos(obs.pose[2])
    return np.array([c * vx - s * vy, s * vx + c * vy])


class Planner:
    """What both planners share: the goal field, the tracker, the walls near the robot."""

    def __init__(self, scene: Scene, robot: Robot) -> None:
        self.scene, self.robot = scene, robot
        self.params = robot.params
        self.field = goal_field(scene, robot)
        self.reset()

    def rescene(self, scene: Scene, field: Any) -> None:
        """Plan in ``scene`` (new walls, obstacles or map) by its goal ``field``
        (:func:`.control.goal_field` of the scene and this robot)."""
        self.scene, self.field = scene, field

    def reset(self) -> None:
        """Back to before its first call (as built, and at the simulator's reset): no tracks
        of people."""
        self.tracker = Tracker()

    def state(self) -> tuple[dict, dict]:
        """What a call changes (its attributes, the tracker's), for :meth:`set_state`: every
        change is an assignment, never a write into an array held."""
        return dict(self.__dict__), dict(self.tracker.__dict__)

    def set_state(self, saved: tuple[dict, dict]) -> None:
        """The planner as :meth:`state` saw it (a failed step is undone)."""
        mine, tracker = saved
        self.__dict__.clear()
        self.__dict__.update(mine)
        self.tracker.__dict__.clear()
        self.tracker.__dict__.update(tracker)

    def preferred(self, obs: Observation) -> np.ndarray | None:
        """(2,) the field's velocity at the robot (m/s), None inside the goal radius."""
        x, y, _ = obs.pose
        if obs.goal is not None and math.hypot(obs.goal[0] - x, obs.goal[1] - y) <= \
                obs.goal_radius:
            return None
        return np.asarray(self.field(obs.t, np.array([[x, y]]))[0], dtype=np.float64)

    def segments(self, obs: Observation) -> tuple[np.ndarray, np.ndarray]:
        """Wall segments (S, 2), (S, 2) m of the geometry at obs.t within the sensor range."""
        g = self.scene.geometry.at(obs.t)
        a, b = g.segment_a.reshape(-1, 2), g.segment_b.reshape(-1, 2)
        if not len(a):
            return a, b
        near = np.empty(len(a), dtype=np.bool_)
        near_segments(float(obs.pose[0]), float(obs.pose[1]), np.ascontiguousarray(a),
                      np.ascontiguousarray(b), float(self.params["sensor_range"]), near)
        return a[near], b[near]

    def walls(self, obs: Observation,
              seen: tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
              | None = None) -> Walls:
        """The wall segments and circle obstacles seen (:meth:`segments`, :meth:`circles`, or
        ``seen``, their results at this ``obs`` when the caller has them) as the safety
        layer's :class:`~.guard.Walls` (stopping ``stop_margin`` short of them)."""
        (a, b), (c, r) = (self.segments(obs), self.circles(obs)) if seen is None else seen
        return Walls(np.asarray(obs.pose[:2], dtype=np.float64), obs.radius, a, b, c, r,
                     self.robot.max_acceleration, self.params["stop_margin"])

    def circles(self, obs: Observation) -> tuple[np.ndarray, np.ndarray]:
        """Circle obstacles (centres (C, 2), radii (C,)) at obs.t within the sensor range."""
        g = self.scene.geometry.at(obs.t)
        c, r = g.circle_center.reshape(-1, 2), g.circle_radius
        if not len(r):  # none to see
            return c, r
        d = np.hypot(*(c - np.array(obs.pose[:2])).T) - r
        near = d <= self.params["sensor_range"]
        return c[near], r[near]


class Orca(Planner):
    """Optimal reciprocal collision avoidance (van den Berg, Guy, Lin & Manocha 2011, through
    the RVO2 library's Python bindings, ``pyrvo``): the velocity nearest the preferred one
    (the goal field's) outside every person's velocity obstacle truncated at ``time_horizon``
    s, half the avoidance left to the person (reciprocity), the robot's radius grown by
    ``safety_margin`` m; a person it already overlaps (by that margin) is left within one step.
    Walls and circle obstacles (circumscribed polygons) within the sensor range are ORCA's
    static obstacles (horizon time_horizon / 2). Positions are taken relative to the robot (the
    library computes in single precision)."""

    def __call__(self, obs: Observation) -> tuple[float, float, float]:
        pref = self.preferred(obs)
        v_people = self.tracker.update(obs.t, obs.people)
        if pref is None:
            return feasible(self.robot, (0.0, 0.0, 0.0), obs)
        p = self.params
        o = np.array(obs.pose[:2])
        sim = pyrvo.RVOSimulator()
        sim.set_time_step(obs.dt if obs.dt > 0 else DEFAULT_STEP)
        horizon = p["time_horizon"]
        seen = self.segments(obs), self.circles(obs)
        for a, b in zip(*seen[0], strict=True):
            sim.add_obstacle([tuple(a - o), tuple(b - o)])
        for c, r in zip(*seen[1], strict=True):
            k = np.arange(CIRCLE_SIDES) * 2 * math.pi / CIRCLE_SIDES
            big = r / elementary.cos(math.pi / CIRCLE_SIDES)
            sim.add_obstacle([(float(c[0] - o[0] + big * elementary.cos(t)),
                               float(c[1] - o[1] + big * elementary.sin(t))) for t in k])
        sim.process_obstacles()
        v0 = world_velocity(obs)
        me = sim.add_agent((0.0, 0.0), p["sensor_range"] + 2.0, int(p["neighbours"]), horizon,
                           horizon / 2, obs.radius + p["safety_margin"], self.robot.max_speed,
                           (float(v0[0]), float(v0[1])))
        sim.set_agent_pref_velocity(me, (float(pref[0]), float(pref[1])))
        rel = obs.people - o
        near = np.argsort(np.hypot(*rel.T) - obs.people_radii, kind="stable")[
            :int(p["neighbours"])]
        for xy, r, v in zip(rel[near], obs.people_radii[near], v_people[near], strict=True):
            k = sim.add_agent((float(xy[0]), float(xy[1])), 0.0, 0, horizon, horizon / 2,
                              float(r), 1e3, (float(v[0]), float(v[1])))
            sim.set_agent_pref_velocity(k, (float(v[0]), float(v[1])))
        sim.do_step()
        u = np.array(sim.get_agent_velocity(me).to_tuple(), dtype=np.float64)
        return to_command(self.robot, u, obs, p, self.walls(obs, seen))


class SocialForce(Planner):
    """The social force model (Helbing & Molnar 1995) driving the robot: its acceleration is
    (u0 - v) / ``relaxation`` (u0 the goal field's velocity, v the robot's) plus, from every
    person j seen, the gradient of ``strength`` range exp((R + r_j - b_j) / ``range``) with
    the elliptical distance b_j = sqrt((|d| + |d - y|)^2 - |y|^2) / 2 of Johansson, Helbing &
    Shukla 2007 (d from j to the robot, y = (v_j - v) ``anticipation``: j's step relative to
    the robot, so that people closing in repel sooner; b = |d| for y = 0), weighted by
    lambda + (1 - lambda) (1 + cos phi_j) / 2 (lambda = ``anisotropy``, phi_j the angle between
    the robot's heading and the direction to j), a person ahead (cos phi_j > 0) pushing also
    ``side`` cos phi_j times as much to the robot's right; plus from every wall segment and
    circle obstacle seen ``wall_strength`` exp(-gap / ``wall_range``) along its normal (gap:
    surface to surface). v is the model's own velocity (the robot's at the first call), and
    the wished velocity v plus dt times that acceleration, at most max_speed, becomes the next
    v."""

    def __call__(self, obs: Observation) -> tuple[float, float, float]:
        pref = self.preferred(obs)
        v_people = self.tracker.update(obs.t, obs.people)
        if pref is None:
            self.u = np.zeros(2)
            return feasible(self.robot, (0.0, 0.0, 0.0), obs)
        p = self.params
        o = np.array(obs.pose[:2])
        # the model's own velocity, integrated from the robot's first velocity on (the robot
        # tracks it; a diff_drive robot lags it while it turns)
        v = world_velocity(obs) if self.u is None else self.u
        force = (pref - v) / p["relaxation"]
        if len(obs.people):
            force = force + self.people_force(obs, o, v, v_people)
        a, b = self.segments(obs)
        if len(a):  # from the nearest point of each wall segment to the robot
            rel, d = np.empty((len(a), 2)), np.empty(len(a))
            wall_offsets(float(o[0]), float(o[1]), a, b, rel, d)
            mag = p["wall_strength"] * elementary.exp_of(-(d - obs.radius) / p["wall_range"])
            force = force + scaled_sum(mag, rel, d)
        c, r = self.circles(obs)
        if len(c):
            rel = o - c
            d = np.maximum(np.hypot(*rel.T), 1e-9)
            mag = p["wall_strength"] * elementary.exp_of(-(d - r - obs.radius) / p["wall_range"])
            force = force + (mag[:, None] * rel / d[:, None]).sum(axis=0)
        step = obs.dt if obs.dt > 0 else DEFAULT_STEP
        u = v + step * force
        speed = float(np.hypot(*u))
        if speed > self.robot.max_speed:
            u = u * (self.robot.max_speed / speed)
        self.u = u
        return to_command(self.robot, u, obs, p, self.walls(obs, ((a, b), (c, r))))


    u: np.ndarray | None = None

    def reset(self) -> None:
        """Back to before its first call: no tracks, and its own velocity (m/s) taken from the
        robot's again at the next call."""
        super().reset()
        self.u = None

    def people_force(self, obs: Observation, o: np.ndarray, v: np.ndarray,
                     v_people: np.ndarray) -> np.ndarray:
        """(2,) m/s^2: the people's repulsion (class docstring) on the robot at ``o`` moving at
        ``v``; ``v_people`` (M, 2) the tracked velocities."""
        p = self.params
        d = o - obs.people  # (M, 2) from each person to the robot
        y = (v_people - v) * p["anticipation"]  # the person's step relative to the robot
        m = len(d)
        b, grad, n = np.empty(m), np.empty((m, 2)), np.empty((m, 2))
        people_terms(np.ascontiguousarray(d), np.ascontiguousarray(y), b, grad, n)
        hs, hc = elementary.sincos(obs.pose[2])
        cos_phi = -(n[:, 0] * hc + n[:, 1] * hs)
        lam = p["anisotropy"]
        w = lam + (1.0 - lam) * (1.0 + cos_phi) / 2.0
        mag = p["strength"] * elementary.exp_of((obs.radius + obs.people_radii - b) / p["range"]) * w
        # people ahead also push it to its right (the side convention that breaks the
        # head-on symmetry): the push turned by +90 degrees, weighted by side * max(0, cos phi)
        side = p["side"] * np.maximum(cos_phi, 0.0)
        out = np.zeros(2)
        pushes(grad, np.ascontiguousarray(mag, dtype=np.float64), side, out)
        return out


def controller_for(scene: Scene, robot: Robot) -> Controller | None:
    """The bundled controller the robot's ``controller:`` names (None for ``none``)."""
    if robot.controller == "pursuit":
        return Pursuit(scene, robot, **robot.params)
    if robot.controller == "orca":
        return Orca(scene, robot)
    if robot.controller == "social_force":
        return SocialForce(scene, robot)
    if robot.controller == "window":
        from sweep_core.numerics.robots.window import Window  # it builds on Planner

        return Window(scene, robot)
    return None


def controllers_of(scene: Scene) -> dict[str, Controller]:
    """The controllers the scene names, by robot name."""
    out = {}
    for r in scene.robots:
        c = controller_for(scene, r)
        if c is not None:
            out[r.name] = c
    return out
