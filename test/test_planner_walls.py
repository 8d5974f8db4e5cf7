"""The safety layer's walls: how far a robot's disk can run along a direction before it
touches a wall segment or a circle obstacle (:func:`guard.free_run`, against hand-computed
distances and a march along the ray), the braking speed that keeps it able to stop short of
them, and the bundled planners never wedging a robot against a wall or a pillar."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sweep_core import Scene, Simulator
from sweep_core.numerics.robots.guard import Walls, free_run

NONE2 = np.empty((0, 2))


def _run(xy, radius, direction, seg=None, circle=None) -> float:
    a, b = (np.array([seg[0]], dtype=float), np.array([seg[1]], dtype=float)) if seg \
        else (NONE2, NONE2)
    c, r = (np.array([circle[0]], dtype=float), np.array([circle[1]], dtype=float)) if circle \
        else (NONE2, np.empty(0))
    e = np.array([direction], dtype=float)
    e /= np.hypot(*e.T)[:, None]
    out = np.empty(1)
    free_run(float(xy[0]), float(xy[1]), radius, e, a, b, c, r, out)
    return float(out[0])


WALL = ((-5.0, 1.0), (5.0, 1.0))  # the line y = 1 from x = -5 to 5


@pytest.mark.parametrize("xy, direction, seg, circle, expected", [
    ((0, 0), (0, 1), WALL, None, 0.7),                       # straight at the wall
    ((0, 0), (1, 1), WALL, None, 0.7 * math.sqrt(2)),        # at 45 degrees
    ((0, 0), (0, -1), WALL, None, math.inf),                 # away from it
    ((0, 0), (1, 0), WALL, None, math.inf),                  # along it
    ((0, 0.2), (1, 0), ((1, -1), (1, 0)), None, 1 - math.sqrt(0.05)),  # its end (0.3^2-0.2^2)
    ((0, 0.5), (1, 0), ((1, -1), (1, 0)), None, math.inf),   # passing its end 0.5 m off
    ((0, 0), (1, 0), None, ((2, 0), 0.5), 1.2),              # a pillar of radius 0.5
    ((0, 0), (1, 0), None, ((2, 0.9), 0.5), math.inf),       # passing it 0.1 m clear
    ((0, 0.7), (1, 1), WALL, None, 0.0),                     # touching, into it
    ((0, 0.7), (0, -1), WALL, None, math.inf),               # touching, leaving it
    ((0, 0.7), (1, 0), WALL, None, math.inf),                # touching, sliding along it
    ((1.2, 0), (1, 0), None, ((2, 0), 0.5), 0.0),            # touching the pillar
])
def test_free_run_by_hand(xy, direction, seg, circle, expected):
    got = _run(xy, 0.3, direction, seg, circle)
    if math.isinf(expected):
        assert math.isinf(got) and got > 0
    else:
        assert got == pytest.approx(expected, abs=1e-12)


def _gap(p, a, b, c, r, radius) -> float:
    """The smallest gap (m) from a disk at p to the segments and circles (numpy)."""
    gaps = [np.inf]
    for sa, sb in zip(a, b):
        d = sb - sa
        s = np.clip(np.dot(p - sa, d) / np.dot(d, d), 0.0, 1.0)
        gaps.append(np.hypot(*(p - sa - s * d)) - radius)
    for cc, rr in zip(c, r):
        gaps.append(np.hypot(*(p - cc)) - rr - radius)
    return float(min(gaps))


def test_free_run_is_where_a_march_along_the_ray_first_touches():
    """Random segments and circles (seed 0): the disk moved by the free run touches
    something (gap 0 to 1e-9 m), and at 400 points before it touches nothing."""
    rng = np.random.default_rng(0)
    for _ in range(200):
        a = rng.uniform(-4, 4, (3, 2))
        b = a + rng.uniform(-2, 2, (3, 2))
        c, r = rng.uniform(-4, 4, (2, 2)), rng.uniform(0.1, 0.8, 2)
        p, radius = rng.uniform(-1, 1, 2), 0.3
        if _gap(p, a, b, c, r, radius) <= 0.0:
            continue
        dirs = rng.normal(size=(16, 2))
        dirs /= np.hypot(*dirs.T)[:, None]
        out = np.empty(16)
        free_run(float(p[0]), float(p[1]), radius, dirs, a, b, c, r, out)
        for e, d in zip(dirs, out):
            if math.isinf(d):
                ts = np.linspace(0.0, 20.0, 400)
            else:
                assert abs(_gap(p + d * e, a, b, c, r, radius)) <= 1e-9
                ts = np.linspace(0.0, d, 400, endpoint=False)
            assert min(_gap(p + t * e, a, b, c, r, radius) for t in ts) > -1e-12


def test_walls_speeds_are_the_braking_bound():
    w = Walls(np.zeros(2), 0.3, np.array([WALL[0]], dtype=float),
              np.array([WALL[1]], dtype=float), NONE2, np.empty(0), 2.0, 0.1)
    up, away = np.array([[0.0, 1.0]]), np.array([[0.0, -1.0]])
    assert w.speeds(up)[0] == pytest.approx(math.sqrt(2 * 2.0 * (0.7 - 0.1)), rel=1e-15)
    assert math.isinf(w.speeds(away)[0])
    close = Walls(np.array([0.0, 0.65]), 0.3, np.array([WALL[0]], dtype=float),
                  np.array([WALL[1]], dtype=float), NONE2, np.empty(0), 2.0, 0.1)
    assert close.speeds(up)[0] == 0.0  # within the margin: no speed towards it
    unbounded = Walls(np.array([0.0, 0.65]), 0.3, np.array([WALL[0]], dtype=float),
                      np.array([WALL[1]], dtype=float), NONE2, np.empty(0), math.inf, 0.1)
    assert unbounded.speeds(up)[0] == 0.0
    nothing = Walls(np.zeros(2), 0.3, NONE2, NONE2, NONE2, np.empty(0), 2.0, 0.1)
    assert math.isinf(nothing(up[0]))


def _wedge_scene(controller: str, obstacle: dict) -> Scene:
    """A diff-drive robot touching a wall (or a pillar) with its heading 60 degrees into it;
    its goal lies along the wall, so its planner must turn before it can drive (one person,
    far away and still)."""
    return Scene.from_dict({
        "agents": {"positions": [[9.0, -2.0]], "radius": 0.25}, "noise": {"sigma": 0.0},
        "drift": {"kind": "none"},
        **obstacle,
        "robots": [{"name": "bot", "radius": 0.3, "pose": [0.0, 0.7 - 1e-6, math.pi / 3],
                    "kinematics": {"type": "diff_drive", "max_speed": 1.0,
                                   "max_angular_speed": 1.5, "max_acceleration": 1.0,
                                   "max_angular_acceleration": 3.0},
                    "goal": [6.0, 0.0], "goal_radius": 0.3, "controller": controller}]})


WEDGES = {"wall": {"walls": [{"kind": "segment", "a": [-3.0, 1.0], "b": [10.0, 1.0]},
                             {"kind": "segment", "a": [-3.0, -3.0], "b": [10.0, -3.0]}]},
          "pillar": {"walls": [{"kind": "segment", "a": [-3.0, -3.0], "b": [10.0, -3.0]}],
                     "obstacles": [{"kind": "circle", "centre": [0.0, 1.5], "radius": 0.5}]}}


@pytest.mark.parametrize("where", sorted(WEDGES))
@pytest.mark.parametrize("controller", ["orca", "social_force", "window"])
def test_planners_turn_away_from_a_wall_they_touch(controller, where):
    """Before the safety layer knew walls, each planner drove the robot into the wall at
    every step (the fleet stopped it, and the turn with it) and it never left."""
    sim = Simulator(_wedge_scene(controller, WEDGES[where]), dt=0.05, seed=0)
    sim.step(200)
    st = sim.robots.state("bot")
    assert st.blocked == 0
    assert math.hypot(st.pose[0] - 6.0, st.pose[1]) <= 0.3 + 0.05
