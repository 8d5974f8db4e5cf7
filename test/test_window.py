"""The sampling planner ``window`` (sweep_core/numerics/robots/window.py): its forecast
hazard, its choices with a person ahead, its parameters' refusals, and a run in an empty
hall."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sweep_core import Scene, Simulator
from sweep_core.errors import SceneError
from sweep_core.numerics.robots import window
from sweep_core.numerics.robots.control import Observation
from sweep_core.numerics.robots.planners import controller_for
from sweep_core.numerics.robots.window import STEP, candidates, hazards

LIMITS = {"type": "diff_drive", "max_speed": 1.0, "max_angular_speed": 1.5,
          "max_acceleration": 1.0, "max_angular_acceleration": 3.0}


def _scene(controller, people=((20.0, 9.0),), reaction=None, kinematics=LIMITS) -> Scene:
    data = {"agents": {"positions": [list(p) for p in people], "radius": 0.25},
            "walls": [{"kind": "polyline",
                       "points": [[0, -10], [21, -10], [21, 10], [0, 10], [0, -10]]}],
            "noise": {"sigma": 0.0}, "drift": {"kind": "none"},
            "robots": [{"name": "bot", "radius": 0.3, "pose": [1.0, 0.0, 0.0],
                        "kinematics": kinematics, "goal": [15.0, 0.0], "goal_radius": 0.5,
                        "controller": controller}]}
    if reaction:
        data["crowd_reaction"] = reaction
    return Scene.from_dict(data)


def _hazard(u, people, v_people=None, avoid=(1.0, 0.0, 0.0), spread=0.3, passive=0.0
            ) -> np.ndarray:
    u = np.array(u, dtype=np.float64).reshape(-1, 2)
    people = np.array(people, dtype=np.float64).reshape(-1, 2)
    v = np.zeros_like(people) if v_people is None else np.array(v_people, dtype=np.float64)
    out = np.empty(len(u))
    hazards(u, np.zeros(2), 0.3, people, np.full(len(people), 0.25), v, *avoid, spread, 0.1,
            passive, 2.0, STEP, 1.0, out)
    return out


def test_the_hazard_is_the_forecast_contact_probability_times_the_advance():
    # a person standing 1.55 m ahead (gap 1 m, 0.9 m beyond the margin); robot at 0.5 m/s
    # east: at t the gap left is 0.9 - 0.5 t (reached at 1.8 s), spread 0.3 sqrt(t)
    h = _hazard([[0.5, 0.0]], [[1.55, 0.0]])[0]
    n = int(2.0 / STEP + 0.5)
    expect = max((math.exp(-g * g / (2 * 0.09 * t)) if g > 0 else 1.0) * 0.5
                 for t in (STEP * k for k in range(1, n + 1)) for g in [0.9 - 0.5 * t])
    assert h == pytest.approx(expect, rel=1e-12)
    assert h == pytest.approx(0.5, rel=1e-12)  # the gap closes within the horizon
    # standing still, moving away or sideways past them: no advance towards them, no hazard
    assert _hazard([[0.0, 0.0], [-0.5, 0.0], [0.0, 0.5]], [[1.55, 0.0]]) == \
        pytest.approx([0.0, 0.0, 0.0], abs=1e-12)
    # a contact the robot does not advance into weighs ``passive``
    assert _hazard([[0.0, 0.0]], [[0.6, 0.0]], passive=0.25)[0] == pytest.approx(0.25)
    # the same person 3 m to the side is far less of a hazard than straight ahead
    assert _hazard([[0.5, 0.0]], [[1.55, 3.0]])[0] < 1e-3


def test_the_avoid_reaction_the_command_induces_clears_the_forecast():
    # a person 2.2 m ahead, 0.3 m off the robot's line: with the crowd stepping aside
    # (strength 0.6 m/s within 1.5 m of the robot's next second) the hazard is smaller
    people = [[2.2, 0.3]]
    without = _hazard([[1.0, 0.0]], people, spread=0.1)[0]
    with_avoid = _hazard([[1.0, 0.0]], people, avoid=(1.5, 1.0, 0.6), spread=0.1)[0]
    assert with_avoid < 0.5 * without


def test_skipping_people_out_of_reach_changes_no_hazard(monkeypatch):
    # the compiled forecast skips people too far to come within FAR spreads; the same
    # forecast in Python with the skip disabled (an infinite slack) integrates every one
    rng = np.random.default_rng(5)
    u = candidates(0.4, 1.0)
    people = rng.uniform(-14.0, 14.0, (40, 2))
    v = rng.normal(0.0, 0.8, (40, 2))
    v[:5] = -1.5 * people[:5] / np.hypot(*people[:5].T)[:, None]  # rushing at the robot
    args = (np.zeros(2), 0.3, people, np.full(40, 0.25), v, 1.5, 1.0, 0.6, 0.3, 0.1, 0.05,
            2.0, STEP, 1.0)
    fast, full = np.empty(len(u)), np.empty(len(u))
    hazards(u, *args, fast)
    monkeypatch.setattr(window, "FAR_SLACK", math.inf)
    hazards.py_func(u, *args, full)
    assert np.all(full > 0)
    np.testing.assert_allclose(fast, full, rtol=1e-12, atol=0)
    # a far person rushing in is not skipped: alone, they still weigh
    assert _hazard([[1.0, 0.0]], [[7.0, 0.0]], v_people=[[-2.5, 0.0]])[0] > 0.1
    assert _hazard([[1.0, 0.0]], [[7.0, 0.0]])[0] == 0.0


def test_candidates_span_the_half_plane_round_the_goal_heading():
    u = candidates(0.3, 1.0)
    assert np.all(u[:-1] @ np.array([math.cos(0.3), math.sin(0.3)]) >= -1e-12)
    assert np.all(np.hypot(*u.T) <= 1.0 + 1e-12) and np.all(u[-1] == 0.0)


def _obs(people, speed: float) -> Observation:
    xy = np.array(people, dtype=np.float64).reshape(-1, 2)
    return Observation(0.0, (1.0, 0.0, 0.0), (speed, 0.0, 0.0), None, (15.0, 0.0), 0.5, 0.3,
                       xy, np.full(len(xy), 0.25), (speed, 0.0, 0.0), 0.01)


def test_it_turns_or_slows_for_a_person_close_ahead_and_goes_straight_otherwise():
    scene = _scene("window")
    plan = controller_for(scene, scene.robots[0])
    assert plan is not None
    free = plan(_obs([], 1.0))
    assert free == pytest.approx((1.0, 0.0, 0.0), abs=1e-12)  # full speed along the field
    plan = controller_for(scene, scene.robots[0])
    assert plan is not None
    cmd = plan(_obs([[2.0, 0.0]], 1.0))  # a person 0.45 m ahead, edge to edge
    assert cmd[0] == pytest.approx(1.0 - 0.01, abs=1e-12)  # brakes at its limit
    # weighing the hazard above progress, it chooses to go round them instead
    scene = _scene({"kind": "window", "hazard_weight": 2.0})
    plan = controller_for(scene, scene.robots[0])
    assert plan is not None
    plan(_obs([[2.0, 0.0]], 1.0))
    choice = plan.last  # type: ignore[attr-defined]
    assert abs(choice[1]) > 0.3 and choice[0] < 0.9


def test_window_parameters_refused_in_one_line():
    with pytest.raises(SceneError) as err:
        _scene({"kind": "window", "horizon": 0})
    msg = str(err.value)
    assert err.value.field == "robots[0].controller.horizon" and "outside [0.1, 10]" in msg
    assert "\n" not in msg and "(fix:" in msg
    with pytest.raises(SceneError) as err:
        _scene({"kind": "window", "time_horizon": 2})
    assert "is not a parameter of controller window" in str(err.value)


@pytest.mark.parametrize("kind", ["diff_drive", "holonomic"])
def test_an_empty_hall_is_crossed_in_about_the_straight_line_time(kind):
    # 14 m at 1 m/s from rest at 1 m/s^2: 14.5 s at best; the goal is within 0.5 m at 14 s
    scene = _scene("window", kinematics={**LIMITS, "type": kind})
    sim = Simulator(scene, dt=0.05, seed=0)
    st = sim.robots.state("bot")
    for _ in range(400):
        sim.step()
        if st.goal_reached:
            break
    assert st.goal_reached and 13.5 <= sim.t <= 14.5 + 0.5
    assert abs(st.pose[1]) < 0.05


def test_runs_are_the_same_from_a_seed():
    scene = _scene("window", people=((4.0, 0.2), (6.0, -0.4), (8.0, 0.5)),
                   reaction={"kind": "avoid", "radius": 1.5, "horizon": 1.0,
                             "strength": 0.6})
    poses = []
    for _ in range(2):
        sim = Simulator(Scene.from_dict(scene.spec | {"noise": {"sigma": 0.3}}), dt=0.02,
                        seed=3)
        sim.step(200)
        poses.append(sim.robots.state("bot").pose)
    assert poses[0] == poses[1]
