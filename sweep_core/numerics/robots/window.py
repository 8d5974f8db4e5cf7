"""The sampling planner ``window`` (docs/robots.md#controllers): a dynamic-window-style choice
among sampled velocities, scored against a Gaussian forecast of every person the robot sees.

What it sees: as :mod:`.planners` (its own pose and last command, the people whose disks come
within ``sensor_range`` m of its centre, their velocities from the :class:`.planners.Tracker`,
the walls through the goal field, and the wall segments and circle obstacles within
``sensor_range`` through the safety layer's :class:`.guard.Walls`). It also knows the
scene's ``crowd_reaction`` (how people step aside from a robot's commanded path: the model it
plans with, as a robot's designer knows how people react to it).

Candidates: the velocities u = s (cos phi, sin phi) with s in ``SPEEDS`` times max_speed and
phi the goal field's heading plus each of ``HEADINGS``, and u = 0. Each is held for the
forecast times t_k = k ``STEP`` (k = 1 .. horizon / STEP): the robot at p + u t_k; person j at
the mean m_j(t_k), integrated from m_j(0) = x_j in steps of STEP at the velocity v_j + w_j
(v_j tracked, w_j the avoid velocity that the command u gives a person at m_j when the robot
is at p + u t, zero without ``crowd_reaction: avoid``), with spread
sigma_k = ``spread`` sqrt(t_k) m per axis. The contact hazard of j is the largest over k of

    exp(-g_k^2 / (2 sigma_k^2)) (max(0, <u, e_k>) / max_speed + ``passive``)

(the exponential 1 at g_k <= 0; g_k the forecast edge-to-edge gap less ``hazard_margin``, e_k
the unit vector from the robot towards j's mean): a contact while the robot advances towards
a person is the robot's (docs/social_bench.md), moving sideways or away or standing still
never is; ``passive`` weighs the contacts the robot does not cause (a person walking into
a robot that stopped in their way). The score, highest wins (the first of equals), is

    <u, f> / max_speed^2 exp(-``hazard_weight`` sum_j hazard_j) - ``steadiness`` |u - u_last| /
    max_speed

(f the goal field's velocity, u_last the previous choice): progress along the field times
the chance of no contact (the hazards taken as independent rates), and a steady command
(the crowd's avoid lane forms ahead of a robot whose command does not change). The chosen u
becomes the command through :func:`.planners.to_command`: the safety layer of :mod:`.guard`
and the robot's kinematic limits. Candidates faster than the layer's wall bound along their own
direction (:meth:`Window.too_fast`) are never chosen.
"""
from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

from sweep_core.model import elementary
from sweep_core.model.elementary import exp
from sweep_core.model.robots import Robot
from sweep_core.model.scene import Scene
from sweep_core.numerics.robots.control import Observation, feasible
from sweep_core.numerics.robots.planners import Planner, to_command

#: heading offsets (rad) from the goal field's heading that are sampled
HEADINGS = np.radians(np.arange(-90.0, 91.0, 15.0))
#: sampled speeds, as shares of max_speed
SPEEDS = np.array([0.25, 0.5, 0.75, 1.0])
#: forecast time step (s)
STEP = 0.1
#: a person farther than FAR forecast spreads counts no hazard (e^(-FAR^2 / 2) < 1e-17)
FAR = 9.0
#: m: a bound on the forecast's rounding in the far-person test of :func:`hazards`
FAR_SLACK = 1e-6


def candidates(heading: float, max_speed: float) -> np.ndarray:
    """(K, 2) m/s: the sampled velocities round ``heading`` (rad), u = 0 last."""
    phi = heading + HEADINGS
    dirs = np.column_stack([elementary.cos_of(phi), elementary.sin_of(phi)])
    u = (SPEEDS[:, None, None] * max_speed * dirs[None, :, :]).reshape(-1, 2)
    return np.vstack([u, np.zeros((1, 2))])


@numba.njit(cache=True)
def hazards(u: np.ndarray, robot_xy: np.ndarray, radius: float, people: np.ndarray,
            radii: np.ndarray, v_people: np.ndarray, avoid_radius: float, avoid_time: float,
            avoid_strength: float, spread: float, margin: float, passive: float,
            horizon: float, step: float, max_speed: float, out: np.ndarray
            ) -> None:  # pragma: no cover
    """out (K,): the summed contact hazard (module docstring) of each candidate velocity u
    (K, 2) m/s of the robot at ``robot_xy`` (2,) m with ``radius`` m among ``people`` (M, 2) m
    of ``radii`` (M,) m moving at ``v_people`` (M, 2) m/s; the avoid reaction's radius m,
    horizon s and strength m/s (strength 0: none); spread m/sqrt(s), margin m, passive the
    weight of a contact without advance, horizon and step s, max_speed m/s."""
    n = int(horizon / step + 0.5)
    # the forecast's last time and spread (the largest of every step's: both grow with t)
    t_n = n * step
    far_n = FAR * spread * math.sqrt(t_n)
    sigs = np.empty(n + 1)  # the spread at each forecast time t_i = i step
    for i in range(1, n + 1):
        sigs[i] = spread * math.sqrt(i * step)
    for k in range(u.shape[0]):
        ux, uy = u[k, 0], u[k, 1]
        total = 0.0
        wx, wy = avoid_time * ux, avoid_time * uy
        length2 = wx * wx + wy * wy
        speed_u = math.hypot(ux, uy)
        for j in range(people.shape[0]):
            # j's mean relative to the robot, integrated over the forecast steps
            rx, ry = people[j, 0] - robot_xy[0], people[j, 1] - robot_xy[1]
            reach = radius + radii[j] + margin
            # a person too far to come within FAR spreads at any forecast step counts no
            # hazard (0 at every step, as below): per step the relative mean moves by at most
            # (|v_j| + strength + |u|) step, the avoid velocity being at most the strength;
            # FAR_SLACK m covers the rounding of the integration (NaN is never skipped)
            closing = (math.hypot(v_people[j, 0], v_people[j, 1]) + abs(avoid_strength)
                       + speed_u) * t_n
            if math.hypot(rx, ry) - reach - closing - FAR_SLACK > max(far_n, 0.0):
                continue
            worst = 0.0
            for i in range(1, n + 1):
                ax, ay = 0.0, 0.0
                if avoid_strength > 0.0:  # the avoid velocity u gives j (reaction.avoidance)
                    s = 0.0
                    if length2 > 0.0:
                        s = min(max((rx * wx + ry * wy) / length2, 0.0), 1.0)
                    bx, by = rx - s * wx, ry - s * wy
                    d = math.hypot(bx, by)
                    if d < avoid_radius:
                        gain = avoid_strength * (1.0 - d / avoid_radius)
                        if d > 1e-12:
                            ax, ay = gain * bx / d, gain * by / d
                        elif length2 > 0.0:  # on the path: to the robot's left
                            ln = math.sqrt(length2)
                            ax, ay = -gain * wy / ln, gain * wx / ln
                rx += (v_people[j, 0] + ax - ux) * step
                ry += (v_people[j, 1] + ay - uy) * step
                dist = math.hypot(rx, ry)
                gap = dist - reach
                sig = sigs[i]
                if gap > 0.0 and not (sig > 0.0 and gap < FAR * sig):
                    continue  # beyond FAR spreads the hazard is below 1e-17 of a contact's: 0
                toward = max((ux * rx + uy * ry) / max(dist, 1e-12) / max_speed, 0.0)
                if gap <= 0.0:
                    h = toward + passive
                else:
                    h = exp(-gap * gap / (2.0 * sig * sig)) * (toward + passive)
                worst = max(worst, h)
            total += worst
        out[k] = total


def _avoid(scene: Scene) -> tuple[float, float, float]:
    """The scene's avoid reaction (radius m, horizon s, strength m/s); strength 0 without."""
    r = scene.reaction
    return (r.radius, r.horizon, r.strength) if r.kind == "avoid" else (1.0, 0.0, 0.0)


class Window(Planner):
    """The sampling planner of the module docstring."""

    def __init__(self, scene: Scene, robot: Robot) -> None:
        super().__init__(scene, robot)  # its reset sets the last choice
        self.avoid = _avoid(scene)

    def rescene(self, scene: Scene, field: Any) -> None:
        super().rescene(scene, field)
        self.avoid = _avoid(scene)

    def reset(self) -> None:
        """Back to before its first call: no tracks, and no last choice (m/s) to keep to."""
        super().reset()
        self.last = np.zeros(2)

    def __call__(self, obs: Observation) -> tuple[float, float, float]:
        pref = self.preferred(obs)
        v_people = self.tracker.update(obs.t, obs.people)
        if pref is None:
            self.last = np.zeros(2)
            return feasible(self.robot, (0.0, 0.0, 0.0), obs)
        p = self.params
        vmax = self.robot.max_speed
        u = candidates(elementary.atan2(pref[1], pref[0]), vmax)
        risk = np.zeros(len(u))
        if len(obs.people):
            hazards(u, np.array(obs.pose[:2], dtype=np.float64), float(obs.radius),
                    np.ascontiguousarray(obs.people, dtype=np.float64),
                    np.ascontiguousarray(obs.people_radii, dtype=np.float64),
                    np.ascontiguousarray(v_people, dtype=np.float64), *self.avoid,
                    p["spread"], p["hazard_margin"], p["passive"], p["horizon"], STEP, vmax, risk)
        ahead = u[:, 0] * pref[0] + u[:, 1] * pref[1]  # x-then-y, not BLAS
        score = ahead / (vmax * vmax) * elementary.exp_of(-p["hazard_weight"] * risk) \
            - p["steadiness"] * np.hypot(*(u - self.last).T) / vmax
        walls = self.walls(obs)
        score[self.too_fast(obs, u, walls)] = -np.inf
        best = u[int(np.argmax(score))]
        self.last = best
        return to_command(self.robot, best, obs, p, walls)

    def too_fast(self, obs: Observation, u: np.ndarray, walls: Any) -> np.ndarray:
        """(K,) bool: the candidates u (K, 2) m/s faster than ``walls`` (:meth:`Planner.walls
        <.planners.Planner.walls>`) allows along their own directions (u = 0 never is)."""
        speed = np.hypot(*u.T)
        moving = speed > 0.0
        out = np.zeros(len(u), dtype=np.bool_)
        if moving.any():
            out[moving] = speed[moving] > walls.speeds(u[moving] / speed[moving, None])
        return out
