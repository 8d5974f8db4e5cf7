"""The planners' safety layer (passive motion safety, sweep_core/numerics/robots/guard.py) on
hand-built observations: the bound's closed form, no advance into a person in contact, the
nearest safe velocity."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sweep_core import Scene
from sweep_core.numerics.robots.control import Observation
from sweep_core.numerics.robots.guard import nearest_safe, safe_speed, safe_speeds
from sweep_core.numerics.robots.planners import controller_for, to_command

LIMITS = {"max_speed": 1.0, "max_angular_speed": 1.5, "max_acceleration": 1.0,
          "max_angular_acceleration": 3.0}
EAST = np.array([1.0, 0.0])


def _robot(kind: str, controller: dict) -> tuple:
    scene = Scene.from_dict({
        "agents": {"positions": [[5.0, 2.0]], "radius": 0.25}, "noise": {"sigma": 0.0},
        "walls": [{"kind": "segment", "a": [-2.0, -3.0], "b": [12.0, -3.0]},
                  {"kind": "segment", "a": [-2.0, 3.0], "b": [12.0, 3.0]}],
        "robots": [{"name": "bot", "radius": 0.3, "pose": [0.0, 0.0, 0.0],
                    "kinematics": {"type": kind, **LIMITS}, "goal": [8.0, 0.0],
                    "goal_radius": 0.3, "controller": controller}]})
    return scene, scene.robots[0]


def _obs(people, speed: float) -> Observation:
    xy = np.array(people, dtype=np.float64).reshape(-1, 2)
    return Observation(0.0, (0.0, 0.0, 0.0), (speed, 0.0, 0.0), None, (8.0, 0.0), 0.3, 0.3,
                       xy, np.full(len(xy), 0.25), (speed, 0.0, 0.0), 0.01)


def test_the_bound_stops_the_robot_before_a_person_closing_in_can_reach_it():
    # a person straight ahead at gap 0.5 m; margin 0.1, a = 1, people close at 0.5 m/s
    v = safe_speed((0.0, 0.0, 0.0), EAST, 0.3, np.array([[1.05, 0.0]]), np.array([0.25]),
                   1.0, 0.1, 0.5)
    assert v == pytest.approx(2 * 0.4 / (0.5 + math.sqrt(0.25 + 0.8)), rel=1e-12)
    # at that speed, braking at a: its own advance v^2 / 2a and the person's v_h v / a fill
    # the gap less the margin exactly
    assert v * v / 2 + 0.5 * v == pytest.approx(0.4, rel=1e-12)
    # a person 60 degrees off the direction: the robot advances at v cos 60 towards them
    p = 1.05 * np.array([[math.cos(math.pi / 3), math.sin(math.pi / 3)]])
    v = safe_speed((0.0, 0.0, 0.0), EAST, 0.3, p, np.array([0.25]), 1.0, 0.1, 0.5)
    assert 0.5 * v * v / 2 + 0.5 * v == pytest.approx(0.4, rel=1e-12)
    # standing people (v_h = 0): the braking distance sqrt(2 a (g - g0))
    v = safe_speed((0.0, 0.0, 0.0), EAST, 0.3, np.array([[1.05, 0.0]]), np.array([0.25]),
                   1.0, 0.1, 0.0)
    assert v == pytest.approx(math.sqrt(0.8), rel=1e-12)


def test_no_advance_towards_a_person_in_contact_and_none_bound_by_people_behind():
    contact = np.array([[0.549, 0.0]])  # edge to edge: touching (1 mm overlap)
    dirs = np.array([[1.0, 0.0], [0.6, 0.8], [0.0, 1.0], [-1.0, 0.0]])
    v = safe_speeds((0.0, 0.0, 0.0), dirs, 0.3, contact, np.array([0.25]), 1.0, 0.0, 0.5)
    assert v[0] == 0.0 and v[1] == 0.0  # any direction with a component towards them
    assert math.isinf(v[2]) and math.isinf(v[3])  # sideways, away
    assert math.isinf(safe_speed((0.0, 0.0, 0.0), EAST, 0.3, np.empty((0, 2)), np.empty(0),
                                 1.0, 0.1, 0.5))


def test_the_nearest_safe_velocity_slides_past_a_person_in_contact():
    # touching a person 30 degrees to the left of the wished velocity: the nearest velocity
    # with no advance towards them is u less its component along e (sampled every 5 degrees)
    e = np.array([math.cos(math.pi / 6), math.sin(math.pi / 6)])
    u = np.array([1.0, 0.0])
    v = nearest_safe(u, (0.0, 0.0, 0.0), 0.3, 0.549 * e[None, :], np.array([0.25]), 1.0, 0.0,
                     0.5, directions=72)
    assert v @ e <= 1e-12
    assert v == pytest.approx(u - (u @ e) * e, abs=1e-12)  # -60 degrees is a sampled heading
    # head on, the nearest such velocity is rest
    assert nearest_safe(u, (0.0, 0.0, 0.0), 0.3, np.array([[0.549, 0.0]]), np.array([0.25]),
                        1.0, 0.0, 0.5) == pytest.approx([0.0, 0.0], abs=1e-12)


@pytest.mark.parametrize("controller", ["orca", "social_force"])
def test_planners_brake_for_a_person_who_may_close_in(controller):
    # moving at 0.5 m/s, a person 0.3 m ahead (edge to edge): with people closing at up to
    # 0.5 m/s the robot cannot be at rest in time at this speed, so it brakes as hard as it
    # may (0.5 - a dt); a planner that only brakes for people standing still keeps going
    scene, robot = _robot("diff_drive", {"kind": controller, "stop_margin": 0.1,
                                         "people_speed": 0.5})
    cmd = controller_for(scene, robot)(_obs([[0.85, 0.0]], 0.5))
    assert cmd[0] == pytest.approx(0.5 - 0.01, abs=1e-12)


@pytest.mark.parametrize("controller", ["orca", "social_force"])
def test_a_holonomic_robot_at_rest_never_advances_into_a_person_in_contact(controller):
    scene, robot = _robot("holonomic", {"kind": controller, "stop_margin": 0.05})
    for y in (-0.1, 0.0, 0.2):  # the person touching it, ahead and a little to the side
        p = np.array([[0.55, y]])
        p = p * 0.549 / np.hypot(*p[0])
        vx, vy, _ = controller_for(scene, robot)(_obs(p, 0.0))
        assert vx * p[0, 0] + vy * p[0, 1] <= 1e-12


def test_people_who_move_by_noise_reach_sqrt_t_farther_and_the_bound_keeps_it():
    # a person straight ahead at gap 0.5 m; margin 0.1, a = 1, v_h = 0.3 m/s, noise 0.3
    # m/sqrt(s): at the bound the robot's braking advance v^2 / 2a, the drift v_h v / a and
    # the noise's reach n sqrt(v / a) over its stopping time fill the gap less the margin
    for c, n in ((1.0, 0.3), (0.5, 0.3), (1.0, 0.05), (1.0, 2.0), (0.05, 0.3)):
        p = 1.05 * np.array([[c, math.sqrt(1.0 - c * c)]])
        v = safe_speed((0.0, 0.0, 0.0), EAST, 0.3, p, np.array([0.25]), 1.0, 0.1, 0.3, n)
        assert c * v * v / 2 + 0.3 * v + n * math.sqrt(v) == pytest.approx(0.4, rel=1e-12)
    # slower than the drift-only bound, and no drift: the noise alone
    drift = safe_speed((0.0, 0.0, 0.0), EAST, 0.3, np.array([[1.05, 0.0]]), np.array([0.25]),
                       1.0, 0.1, 0.3)
    noise = safe_speed((0.0, 0.0, 0.0), EAST, 0.3, np.array([[1.05, 0.0]]), np.array([0.25]),
                       1.0, 0.1, 0.3, 0.3)
    assert noise < drift
    v = safe_speed((0.0, 0.0, 0.0), EAST, 0.3, np.array([[1.05, 0.0]]), np.array([0.25]),
                   1.0, 0.1, 0.0, 0.3)
    assert v * v / 2 + 0.3 * math.sqrt(v) == pytest.approx(0.4, rel=1e-12)
    # within the margin, or in contact: no advance at all; sideways: no bound
    dirs = np.array([[1.0, 0.0], [0.0, 1.0]])
    for x in (0.549, 0.62):
        s = safe_speeds((0.0, 0.0, 0.0), dirs, 0.3, np.array([[x, 0.0]]), np.array([0.25]),
                        1.0, 0.1, 0.3, 0.3)
        assert s[0] == 0.0 and math.isinf(s[1])


@pytest.mark.parametrize("kind", ["diff_drive", "holonomic"])
def test_the_layer_brakes_for_a_person_whose_noise_may_bring_them_close(kind):
    # wishing to go on at 0.3 m/s, a person 0.25 m ahead (edge to edge), margin 0.1: people
    # closing in at 0.3 m/s allow 0.32 m/s, but one who moves by noise of 0.3 m/sqrt(s) may
    # cover 0.3 sqrt(0.3) = 0.16 m more in the 0.3 s it takes to stop: the robot brakes as
    # hard as it may (0.3 - a dt)
    u = np.array([0.3, 0.0])
    for noise, want in ((0.0, 0.3), (0.3, 0.3 - 0.01)):
        scene, robot = _robot(kind, {"kind": "orca", "stop_margin": 0.1, "people_speed": 0.3,
                                     "people_noise": noise})
        cmd = to_command(robot, u, _obs([[0.8, 0.0]], 0.3), robot.params)
        assert cmd[0] == pytest.approx(want, abs=1e-12) and abs(cmd[1]) <= 1e-12
