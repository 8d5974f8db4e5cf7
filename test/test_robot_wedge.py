"""Robots that can never wedge the engine: prescribed robots stop jointly, a failed step
leaves the whole state as before it, yaw wrapped, angular limits and scan values bounded, new
walls checked against the robots where they are, scans below range_min marked as REP 117 says,
controllers' non-finite commands refused, replay comparing the robots' odometry. Few agents and
short runs (cheap)."""
from __future__ import annotations

import math
import pickle

import numpy as np
import pytest

from sweep_core import InfeasibleError, Scene, Simulator
from sweep_core.errors import SceneError

BOX = [{"kind": "polyline", "points": [[0, 0], [10, 0], [10, 6], [0, 6], [0, 0]]}]
QUICK = {"max_acceleration": 100.0}


def _pair_at_a_wall() -> Scene:
    """The issue's case: a at (5.0, 5), b at (5.65, 5), r = 0.3, weight inf, a wall 0.05 m
    ahead of b (x = 6)."""
    robots = [{"name": "a", "radius": 0.3, "pose": [5.0, 5.0, 0.0], "kinematics": QUICK},
              {"name": "b", "radius": 0.3, "pose": [5.65, 5.0, 0.0], "kinematics": QUICK}]
    return Scene.from_dict({"agents": {"positions": [[1.0, 1.0]], "radius": 0.25},
                            "walls": [{"kind": "segment", "a": [6.0, 3.0], "b": [6.0, 7.0]}],
                            "robots": robots})


def test_two_prescribed_robots_at_a_wall_stop_jointly_and_never_wedge():
    sim = Simulator(_pair_at_a_wall(), dt=0.05, seed=0)
    for name in ("a", "b"):
        sim.robots.command(name, (1.0, 0.0, 0.0))
    sim.step(20)  # raised InfeasibleError at the third step, and at every step after it
    a, b = sim.robots.state("a"), sim.robots.state("b")
    assert sim.n_steps == 20
    # b touches the wall (x + r = 6) and a touches b: neither overlaps
    assert b.pose[0] == pytest.approx(5.7, abs=1e-12)
    assert b.pose[0] - a.pose[0] >= 0.6 - 1e-9
    assert a.stopped and b.stopped and a.blocked > 0 and b.blocked > 0


def test_a_failed_step_leaves_the_whole_state_as_before_it():
    """A controller that raises at its third call: the step fails; time, people, robots, the
    Brownian generator and the scheme are as before, so the run goes on exactly as a run
    that never failed."""
    scene = Scene.from_dict({"agents": {"positions": [[6.0, 3.0], [7.0, 2.0]], "radius": 0.25},
                             "noise": {"sigma": 0.3}, "walls": BOX,
                             "robots": [{"name": "bot", "radius": 0.3, "pose": [3, 3, 0]}]})
    calls = []

    def flaky(obs):
        calls.append(obs.t)
        if len(calls) == 3:
            raise ValueError("controller failure")
        return (0.5, 0.0, 0.4)

    sim, twin = Simulator(scene, dt=0.05, seed=3), Simulator(scene, dt=0.05, seed=3)
    sim.robots.controllers["bot"] = flaky
    twin.robots.controllers["bot"] = lambda obs: (0.5, 0.0, 0.4)
    sim.step(2)
    twin.step(2)
    before = (sim.t, sim.positions, sim.robots.state("bot").pose,
              sim.robots.state("bot").command, sim.robots.step_index)
    with pytest.raises(ValueError, match="controller failure"):
        sim.step()
    st = sim.robots.state("bot")
    assert (sim.t, st.pose, st.command, sim.robots.step_index) == (
        before[0], before[2], before[3], before[4])
    assert np.array_equal(sim.positions, before[1])
    sim.step(5)
    twin.step(5)
    assert np.array_equal(sim.positions, twin.positions)  # the same Brownian increments
    assert sim.robots.state("bot").pose == twin.robots.state("bot").pose


def test_yaw_stays_wrapped_while_spinning():
    scene = Scene.from_dict({"agents": {"positions": [[8.0, 5.0]], "radius": 0.25}, "walls": BOX,
                             "robots": [{"name": "bot", "radius": 0.3, "pose": [3, 3, 3.0],
                                         "kinematics": {"max_angular_speed": 1000.0,
                                                        "max_angular_acceleration": 1e7}}]})
    sim = Simulator(scene, dt=0.05, seed=0)
    sim.robots.place("bot", (3.0, 3.0, 1e6 * math.pi + 3.0), sim.t, sim.positions, sim.radii)
    assert -math.pi < sim.robots.state("bot").pose[2] <= math.pi
    sim.robots.place("bot", (3.0, 3.0, 3.0), sim.t, sim.positions, sim.radii)
    sim.robots.command("bot", (0.0, 0.0, 1000.0))
    yaws = []
    for _ in range(50):
        sim.step()
        yaws.append(sim.robots.state("bot").pose[2])
    assert all(-math.pi < y <= math.pi for y in yaws)
    # the exact angle modulo a turn: 3 + 1000 t
    t = 50 * 0.05
    assert math.cos(yaws[-1]) == pytest.approx(math.cos(3.0 + 1000.0 * t), abs=1e-9)


def test_robot_overlap_failure_names_the_robots_and_no_radii_fix():
    scene = Scene.from_dict({"agents": {"positions": [[8.0, 5.0]], "radius": 0.25}, "walls": BOX,
                             "robots": [{"name": "a", "radius": 0.3, "pose": [3, 3, 0]},
                                        {"name": "b", "radius": 0.3, "pose": [5, 3, 0]}]})
    sim = Simulator(scene, dt=0.05, seed=0)
    sim.robots.states["b"].pose = (3.5, 3.0, 0.0)  # forced into a, past every check
    with pytest.raises(InfeasibleError) as err:
        sim.step()
    text = str(err.value)
    assert "robot a and robot b overlap" in text and "smaller radii" not in text, text
    # an ensemble's worker pickles it for the client
    assert str(pickle.loads(pickle.dumps(err.value))) == text


def test_a_controller_returning_nan_is_refused_naming_robot_and_controller():
    scene = Scene.from_dict({"agents": {"positions": [[8.0, 5.0]], "radius": 0.25}, "walls": BOX,
                             "robots": [{"name": "bot", "radius": 0.3, "pose": [3, 3, 0]}]})
    sim = Simulator(scene, dt=0.05, seed=0)

    def wobbly(obs):
        return (float("nan"), 0.0, 0.0)

    sim.robots.controllers["bot"] = wobbly
    with pytest.raises(SceneError) as err:
        sim.step()
    text = str(err.value)
    assert "robot bot" in text and "wobbly" in text and "nan" in text and "\n" not in text, text
    assert sim.n_steps == 0
    sim.robots.controllers.clear()
    sim.step(3)
    assert sim.n_steps == 3


def test_returns_closer_than_range_min_are_minus_inf_with_and_without_noise():
    """REP 117: a detection too close to measure is -inf; every finite range lies within
    [range_min, range_max], noisy or not (the old scan published 0.15 m below range_min 0.3 m
    unchanged, and clipped noisy ones to range_min)."""
    for noise in (0.0, 0.02):
        scan = {"range_min": 0.5, "range_max": 4.0, "angle_min": -0.5, "angle_max": 0.5,
                "increment": 0.1, "noise_std": noise}
        scene = Scene.from_dict({"agents": {"positions": [[3.6, 3.0]], "radius": 0.25},
                                 "walls": BOX, "robots": [{"name": "bot", "radius": 0.3,
                                                           "pose": [3, 3, 0], "scan": scan}]})
        sim = Simulator(scene, dt=0.05, seed=0)
        ranges = sim.robots.state("bot").scan.ranges
        mid = len(ranges) // 2  # straight at the person, 0.35 m away
        assert ranges[mid] == -math.inf
        finite = ranges[np.isfinite(ranges)]
        assert np.all((finite >= 0.5) & (finite <= 4.0))


def test_weights_outside_their_range_are_refused_and_the_smallest_pushes():
    def scene(w: float) -> Scene:
        return Scene.from_dict({"agents": {"positions": [[2.55, 3.0]], "radius": 0.25},
                                "walls": BOX, "robots": [{"name": "bot", "radius": 0.3,
                                                          "pose": [2.0, 3.0, 0.0], "weight": w,
                                                          "kinematics": {
                                                              "max_acceleration": 1e6}}]})
    for w in (1e-16, 1e-300, 1e7):
        with pytest.raises(SceneError, match=r"robots\[0\]\.weight"):
            scene(w)
    w = 1e-6  # the smallest weight accepted (model/robots.py WEIGHT_RANGE)
    sim = Simulator(scene(w), dt=0.05, seed=0)
    sim.robots.command("bot", (1.0, 0.0, 0.0))
    sim.step()
    # min w (x_r - d)^2 + x_p^2 with x_p >= x_r: both move by w d / (1 + w), d = 0.05 m
    expect = w * 0.05 / (1 + w)
    bound = sim.last.projection.bound / math.sqrt(w) + 1e-12
    assert sim.robots.state("bot").pose[0] - 2.0 == pytest.approx(expect, abs=bound)
    assert sim.positions[0, 0] - 2.55 == pytest.approx(expect, abs=bound)


def test_goal_refusals_name_existing_keys_and_the_robot():
    robots = [{"name": "off", "radius": 0.3, "pose": [1, 1, 0], "enabled": False},
              {"name": "bot", "radius": 0.3, "pose": [2, 3, 0], "goal": [20.0, 3.0],
               "controller": "pursuit"}]
    scene = Scene.from_dict({"agents": {"positions": [[8.0, 5.0]], "radius": 0.25},
                             "walls": BOX, "robots": robots})
    with pytest.raises(SceneError) as err:
        Simulator(scene, dt=0.05)
    e = err.value
    text = str(e)
    assert e.field == "robots[1].goal", text  # its place in the scene's list, not the enabled
    assert "robot bot" in text and "agent 0" not in text, text
    for key in ("goal.cell", "goal.wall_buffer", "goal.goal"):
        assert key not in text, text


def _map_spec(blocked: list[tuple[int, int]]) -> dict:
    """A 10 m x 6 m map of 0.5 m cells (20 x 12), free but for ``blocked`` (column, row)."""
    from sweep_core.model.maps import OccupancyMap

    data = np.zeros((12, 20), dtype=np.int8)
    for c, r in blocked:
        data[r, c] = 100
    return OccupancyMap.from_occupancy_grid(data.ravel(), 20, 12, 0.5, (0.0, 0.0, 0.0)).to_spec()


def test_a_new_scene_that_cuts_or_encloses_a_robot_is_refused_and_the_run_goes_on():
    from sweep_core.model.maps import replace_map

    base = {"agents": {"positions": [[8.0, 5.0]], "radius": 0.25}, "walls": BOX,
            "robots": [{"name": "bot", "radius": 0.3, "pose": [1.0, 1.0, 0.0],
                        "goal": [8.0, 1.0]}]}
    sim = Simulator(Scene.from_dict(base), dt=0.05, seed=0)
    sim.robots.command("bot", (0.0, 0.0, 0.0))
    sim.robots.place("bot", (3.0, 3.0, 0.0), sim.t, sim.positions, sim.radii)
    # a blocked cell [3, 3.5] x [3, 3.5] under the robot's current disk (not its scene pose)
    cut = Scene.from_dict(replace_map(base, _map_spec([(6, 6)])))
    with pytest.raises(SceneError, match="robot bot at") as err:
        sim.set_scene(cut)
    assert "\n" not in str(err.value)
    # a ring of cells round the robot at (3, 3): no way to its goal (8, 1)
    ring = [(c, r) for c in range(4, 9) for r in range(4, 9) if c in (4, 8) or r in (4, 8)]
    with pytest.raises(SceneError, match="no way to its goal"):
        sim.set_scene(Scene.from_dict(replace_map(base, _map_spec(ring))))
    sim.step(3)
    assert sim.n_steps == 3


def test_a_placement_is_checked_against_the_map_of_the_new_scene():
    """After set_scene, placements see the new map's blocked cells (they saw the old map's):
    the middle of a blocked 2 m x 2 m block, clear of its boundary walls, is refused; a cell
    blocked in the old map and free in the new one is taken."""
    from sweep_core.model.maps import replace_map

    base = {"agents": {"positions": [[8.0, 5.0]], "radius": 0.25}, "walls": BOX,
            "robots": [{"name": "bot", "radius": 0.3, "pose": [1.0, 1.0, 0.0]}]}
    old = [(c, r) for c in range(14, 18) for r in range(2, 6)]  # [7, 9] x [1, 3]
    sim = Simulator(Scene.from_dict(replace_map(base, _map_spec(old))), dt=0.05, seed=0)
    new = [(c, r) for c in range(6, 10) for r in range(6, 10)]  # [3, 5] x [3, 5]
    sim.set_scene(Scene.from_dict(replace_map(base, _map_spec(new))))
    with pytest.raises(SceneError, match="blocked"):
        sim.robots.place("bot", (4.0, 4.0, 0.0), sim.t, sim.positions, sim.radii)
    assert sim.robots.state("bot").pose == (1.0, 1.0, 0.0)
    sim.robots.place("bot", (8.0, 2.0, 0.0), sim.t, sim.positions, sim.radii)
    assert sim.robots.state("bot").pose == (8.0, 2.0, 0.0)



def test_a_placement_that_leaves_the_goal_out_of_reach_is_refused():
    """Outside the closed box, or walled off from the goal, the robot could never reach it:
    refused in one line (it used to be taken, the goal then out of reach for good). A robot
    without a goal may go anywhere free; one placed inside its goal radius needs no way."""
    goal = {"agents": {"positions": [[8.0, 5.0]], "radius": 0.25}, "walls": BOX,
            "robots": [{"name": "bot", "radius": 0.3, "pose": [1.0, 1.0, 0.0],
                        "goal": [9.0, 1.0]}]}
    sim = Simulator(Scene.from_dict(goal), dt=0.05, seed=0)
    for outside in ((20.0, 3.0, 0.0), (-5.0, -5.0, 1.0)):
        with pytest.raises(SceneError, match=r"robot bot at \[.*\] would have no way to its "
                           r"goal \[9, 1\] .*where its goal can be reached"):
            sim.robots.place("bot", outside, sim.t, sim.positions, sim.radii)
        assert sim.robots.state("bot").pose == (1.0, 1.0, 0.0)
    sim.robots.place("bot", (5.0, 3.0, 0.0), sim.t, sim.positions, sim.radii)
    assert sim.robots.state("bot").pose == (5.0, 3.0, 0.0)
    sim.step(2)
    free = {**goal, "robots": [{"name": "bot", "radius": 0.3, "pose": [1.0, 1.0, 0.0]}]}
    sim = Simulator(Scene.from_dict(free), dt=0.05, seed=0)
    sim.robots.place("bot", (20.0, 3.0, 0.0), sim.t, sim.positions, sim.radii)
    assert sim.robots.state("bot").pose == (20.0, 3.0, 0.0)

CORRIDOR = [{"kind": "segment", "a": [-2.0, 0.0], "b": [14.0, 0.0]},
            {"kind": "segment", "a": [-2.0, 6.0], "b": [14.0, 6.0]}]


@pytest.mark.parametrize("controller", ["pursuit", "orca", "social_force", "window"])
def test_a_failed_step_leaves_the_bundled_planners_as_before_it(controller):
    """Robot b's Python controller returns NaN once: that step fails after robot a's planner
    has already updated its tracks and choices; undone, a's run is the run that never
    failed."""
    scene = Scene.from_dict({
        "agents": {"positions": [[4.0, 3.2], [6.0, 2.5], [8.0, 3.5]], "radius": 0.25},
        "drift": {"kind": "goal", "goal": [-1.0, 3.0], "speed": 1.0}, "noise": {"sigma": 0.05},
        "walls": CORRIDOR,
        "robots": [{"name": "a", "radius": 0.3, "pose": [1.0, 3.0, 0.0], "goal": [11.0, 3.0],
                    "controller": controller},
                   {"name": "b", "radius": 0.3, "pose": [1.0, 5.0, 0.0]}]})

    def run(fail_at: int) -> Simulator:
        sim, calls = Simulator(scene, dt=0.01, seed=0), []

        def b(obs):
            calls.append(obs.t)
            return (math.nan, 0.0, 0.0) if len(calls) == fail_at else (0.0, 0.0, 0.0)

        sim.robots.controllers["b"] = b
        while sim.n_steps < 150:
            try:
                sim.step()
            except SceneError:
                assert len(calls) == fail_at
        return sim

    once, never = run(40), run(-1)
    assert once.robots.state("a").pose == never.robots.state("a").pose
    assert np.array_equal(once.positions, never.positions)


@pytest.mark.parametrize("controller", ["pursuit", "orca"])
def test_planners_plan_round_the_walls_of_a_new_scene(controller):
    """A wall across most of the corridor, given by set_scene on the way: the robot's planner
    takes the gap (its goal field is the new scene's), as in a run begun in the new scene."""
    spec = {"agents": {"positions": [[13.0, 5.5]], "radius": 0.25}, "walls": CORRIDOR,
            "robots": [{"name": "bot", "radius": 0.3, "pose": [1.0, 3.0, 0.0],
                        "goal": [11.0, 3.0], "controller": controller}]}
    walled = {**spec, "walls": CORRIDOR + [{"kind": "segment", "a": [5.0, 0.0],
                                            "b": [5.0, 4.5]}]}
    sim = Simulator(Scene.from_dict(spec), dt=0.02, seed=0)
    sim.step(25)
    sim.set_scene(Scene.from_dict(walled))
    fresh = Simulator(Scene.from_dict(walled), dt=0.02, seed=0)
    for s in (sim, fresh):
        s.step(1250)
        st = s.robots.state("bot")
        assert st.goal_reached and st.blocked == 0
