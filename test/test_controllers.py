"""The bundled local planners (orca, social_force, beside pursuit): the ``controller:`` key's
refusals, the kinematic limits, what they see (nothing beyond the sensor range), steering
round a person walking head-on where pursuit collides, the split of contacts by cause, and
``sweep bench social`` on a tiny configuration. Small deterministic scenes (sigma 0)."""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from sweep_core import Scene, Simulator
from sweep_core.analysis.causes import ContactLog, robot_shares
from sweep_core.bench.social_runs import Run, simulate
from sweep_core.cli import main
from sweep_core.errors import SceneError
from sweep_core.model.scene import load_scene
from sweep_core.numerics.robots.control import observe
from sweep_core.numerics.robots.planners import controller_for

WALLS = [{"kind": "segment", "a": [-2.0, -3.0], "b": [12.0, -3.0]},
         {"kind": "segment", "a": [-2.0, 3.0], "b": [12.0, 3.0]}]
LIMITS = {"type": "diff_drive", "max_speed": 1.0, "max_angular_speed": 1.5,
          "max_acceleration": 1.0, "max_angular_acceleration": 3.0}


def _robot(controller, **extra) -> dict:
    return {"name": "bot", "radius": 0.3, "pose": [0.0, 0.0, 0.0], "kinematics": LIMITS,
            "goal": [8.0, 0.0], "goal_radius": 0.3, "controller": controller} | extra


def _scene(controller, people=((5.0, 0.0),), drift=None, **extra) -> Scene:
    return Scene.from_dict({
        "agents": {"positions": [list(p) for p in people], "radius": 0.25},
        "walls": WALLS, "noise": {"sigma": 0.0},
        "drift": drift or {"kind": "none"}, "robots": [_robot(controller, **extra)]})


@pytest.mark.parametrize("controller, field, words", [
    ("rrt", "robots[0].controller", "unknown controller 'rrt'"),
    ({"kind": "dwa"}, "robots[0].controller.kind", "unknown controller 'dwa'"),
    ({"time_horizon": 2}, "robots[0].controller.kind", "missing"),
    ({"kind": "orca", "horizon": 2}, "robots[0].controller.horizon",
     "is not a parameter of controller orca"),
    ({"kind": "orca", "time_horizon": 0}, "robots[0].controller.time_horizon",
     "outside [0.1, 20]"),
    ({"kind": "orca", "time_horizon": float("nan")}, "robots[0].controller.time_horizon",
     "must be finite"),
    ({"kind": "social_force", "strength": "big"}, "robots[0].controller.strength",
     "must be a number"),
    ({"kind": "orca", "neighbours": 2.5}, "robots[0].controller.neighbours",
     "whole number"),
    ({"kind": "pursuit", "sensor_range": 3}, "robots[0].controller.sensor_range",
     "is not a parameter of controller pursuit"),
    (7, "robots[0].controller", "must be a controller name or a mapping"),
])
def test_controller_spec_refused_in_one_line(controller, field, words):
    with pytest.raises(SceneError) as err:
        _scene(controller)
    msg = str(err.value)
    assert err.value.field == field and words in msg and "\n" not in msg
    assert "(fix:" in msg


def test_controller_needs_a_goal_and_keeps_its_parameters():
    data = _robot("orca")
    del data["goal"]
    with pytest.raises(SceneError) as err:
        Scene.from_dict({"agents": {"positions": [[5, 0]], "radius": 0.25}, "robots": [data]})
    assert err.value.field == "robots[0].goal" and "controller orca" in str(err.value)
    scene = _scene({"kind": "orca", "time_horizon": 3},
                   scan={"range_max": 4.0, "angle_min": -1.0, "angle_max": 1.0})
    robot = scene.robots[0]
    assert robot.controller == "orca" and robot.params["time_horizon"] == 3.0
    assert robot.params["sensor_range"] == 4.0  # the scan's range_max
    assert scene.spec["robots"][0]["controller"] == {"kind": "orca", "time_horizon": 3.0}
    again = Scene.from_dict(scene.spec)  # the normalised spec loads to the same robot
    assert again.robots[0] == robot
    assert _scene("social_force").spec["robots"][0]["controller"] == "social_force"


@pytest.mark.parametrize("kind", ["diff_drive", "holonomic"])
@pytest.mark.parametrize("controller", ["orca", "social_force", "window"])
def test_commands_respect_the_limits_and_the_fleet_never_clips_them(controller, kind):
    scene = _scene(controller, people=((2.0, 0.4), (3.0, -0.5), (4.0, 0.2)),
                   kinematics={**LIMITS, "type": kind})
    sim = Simulator(scene, dt=0.02, seed=0)
    robot = scene.robots[0]
    st = sim.robots.state("bot")
    last = (0.0, 0.0, 0.0)
    for _ in range(150):
        sim.step()
        v, vy, w = st.command
        assert math.hypot(v, vy) <= robot.max_speed + 1e-12
        assert vy == 0.0 or kind == "holonomic"
        assert abs(w) <= robot.max_angular_speed + 1e-12
        for k in (0, 1):
            assert abs(st.command[k] - last[k]) <= robot.max_acceleration * 0.02 + 1e-12
        assert abs(w - last[2]) <= robot.max_angular_acceleration * 0.02 + 1e-12
        last = st.command
    assert st.clipped == 0  # the controller's own commands were feasible as given
    assert st.pose[0] > 1.0  # and it went somewhere


@pytest.mark.parametrize("controller", ["orca", "social_force", "window"])
def test_a_person_beyond_the_sensor_range_changes_nothing(controller):
    scene = _scene({"kind": controller, "sensor_range": 3.0}, people=((1.5, 0.3),))
    sim = Simulator(scene, dt=0.05, seed=0)
    st = sim.robots.state("bot")
    near = np.array([[1.5, 0.3]])
    far = np.array([[1.5, 0.3], [3.4, 0.0]])  # its disk 3.15 m from the robot's centre
    radii = np.array([0.25, 0.25])
    a, b = controller_for(scene, scene.robots[0]), controller_for(scene, scene.robots[0])
    for k in range(5):
        t = 0.05 * k
        obs_far = observe(st, t, far + 0.01 * k, radii, 0.05)
        assert len(obs_far.people) == 1
        assert a(observe(st, t, near + 0.01 * k, radii[:1], 0.05)) == b(obs_far)
    # within range it does see the second person
    assert len(observe(st, 0.0, far - [[0, 0], [0.2, 0]], radii, 0.05).people) == 2


def _head_on(controller: str) -> tuple[bool, int, float]:
    """A person walking west at 1 m/s straight at a robot driving east to its goal: whether
    the robot reached its goal, contact steps, and the smallest clearance (m)."""
    scene = _scene(controller, people=((6.0, 0.0),),
                   drift={"kind": "goal", "goal": [-10.0, 0.0], "speed": 1.0})
    sim = Simulator(scene, dt=0.02, seed=0)
    st = sim.robots.state("bot")
    contacts, least = 0, math.inf
    for _ in range(1000):
        sim.step()
        contacts += int(len(st.contact_ids) > 0)
        d = math.hypot(*(np.array(st.pose[:2]) - sim.positions[0])) - 0.55
        least = min(least, d)
        if st.goal_reached:
            break
    return st.goal_reached, contacts, least


def test_pursuit_collides_head_on():
    reached, contacts, least = _head_on("pursuit")
    assert contacts > 0 and least <= 1e-6


@pytest.mark.parametrize("controller", ["orca", "social_force", "window"])
def test_planners_steer_round_a_person_walking_head_on(controller):
    reached, contacts, least = _head_on(controller)
    assert reached and contacts == 0 and least > 1e-6


def test_robot_share_of_a_contact_is_its_advance_along_the_normal():
    h = 0.1
    imp = np.array([[0.5, 0.0], [0.0, -0.2], [0.3, 0.4]])  # lam = 0.05, 0.02, 0.05 m
    d = np.array([0.03, 0.01])
    share = robot_shares(imp, d, h)
    # advance along e: 0.03 (< lam 0.05), -0.01 (moving away: 0), 0.6*0.03+0.8*0.01=0.026
    assert share == pytest.approx([0.03, 0.0, 0.026], abs=1e-15)
    assert robot_shares(imp, np.array([1.0, 0.0]), h)[0] == pytest.approx(0.05)  # capped
    log = ContactLog()
    log.add(np.array([2]), imp[:1], np.array([0.02, 0.5]), h)  # share 0.02 < lam / 2: person's
    assert (log.robot_events, log.person_events) == (0, 1)
    log = ContactLog()
    log.add(np.array([4]), imp[1:2], d, h)  # person-on-robot event starts
    log.add(np.array([4]), imp[:1], d, h)  # same event, robot pushes later: robot's event
    log.add(np.array([7]), imp[1:2], d, h)  # 4 ends; 7 starts, robot moving away
    assert (log.robot_events, log.person_events) == (1, 1)
    assert log.robot_impulse == pytest.approx(0.03 / h)


def test_bench_social_runs_a_tiny_configuration(tmp_path, capsys):
    out = tmp_path / "b"
    assert main(["bench", "social", "--seeds", "1", "--scenes", "crowdnav", "--controllers",
                 "orca", "pursuit", "--t-end", "0.3", "--workers", "1", "--out",
                 str(out)]) == 0
    printed = capsys.readouterr().out
    assert "robot_contacts" in printed and "wall time" in printed
    rows = list(csv.DictReader((out / "runs.csv").open()))
    assert [(r["scene"], r["controller"], r["seed"]) for r in rows] == [
        ("crowdnav", "orca", "0"), ("crowdnav", "pursuit", "0")]
    assert all(r["reached"] == "False" and float(r["sim_s"]) == pytest.approx(0.3)
               for r in rows)
    summary = list(csv.DictReader((out / "summary.csv").open()))
    assert [r["controller"] for r in summary] == ["pursuit", "orca"]
    assert (out / "social.png").stat().st_size > 0


def test_bench_social_runs_a_scene_file_as_its_bundled_twin(tmp_path, capsys):
    from sweep_core.model.gallery import resolve_scene_path
    mine = tmp_path / "my_corridor.yaml"
    mine.write_text(resolve_scene_path("crowdnav").read_text())
    rows = {}
    for scene in ("crowdnav", str(mine)):
        out = tmp_path / Path(scene).stem
        assert main(["bench", "social", "--seeds", "1", "--scenes", scene, "--controllers",
                     "orca", "--t-end", "0.5", "--workers", "1", "--out", str(out)]) == 0
        (rows[scene],) = csv.DictReader((out / "runs.csv").open())
    assert str(mine) in capsys.readouterr().out
    assert rows[str(mine)].pop("scene") == str(mine)
    assert rows["crowdnav"].pop("scene") == "crowdnav"
    for r in rows.values():
        r.pop("wall_s")
    assert rows[str(mine)] == rows["crowdnav"]


def test_bench_social_refuses_a_scene_file_without_a_robot(tmp_path, capsys):
    (tmp_path / "empty.yaml").write_text("agents: {positions: [[1, 1]], radius: 0.25}\n")
    assert main(["bench", "social", "--scenes", str(tmp_path / "empty.yaml"), "--out",
                 str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--scenes" in err[0] and "has no robot" in err[0]


@pytest.mark.parametrize("args, option", [
    (["--seeds", "0"], "--seeds"), (["--scenes", "bottleneck"], "--scenes"),
    (["--scenes", "nowhere"], "--scenes"), (["--controllers", "rrt"], "--controllers"),
    (["--dt", "0"], "--dt"), (["--workers", "0"], "--workers"),
    (["--t-end", "-1"], "--t-end")])
def test_bench_social_refuses_bad_options(args, option, tmp_path, capsys):
    assert main(["bench", "social", "--out", str(tmp_path / "o"), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and option in err[0]
    assert not (tmp_path / "o").exists()


def test_the_analysis_figure_draws_the_robot(tmp_path):
    import matplotlib.pyplot as plt

    from sweep_core.analysis import metrics, plots
    from sweep_core.analysis.robot_plots import ROBOT_COLOUR
    scene = tmp_path / "s.yaml"
    scene.write_text(
        "agents: {positions: [[2.0, 0.0]], radius: 0.25}\n"
        "walls: [{kind: segment, a: [-2, -3], b: [12, -3]}, {kind: segment, a: [-2, 3], "
        "b: [12, 3]}]\nnoise: {sigma: 0.0}\n"
        "robots: [{name: bot, radius: 0.3, pose: [0, 0, 0], goal: [8, 0], controller: none}]\n")
    out = tmp_path / "r.mcap"
    assert main(["run", str(scene), "--t-end", "1.0", "--dt", "0.05", "--out", str(out),
                 "--quiet"]) == 0
    an = metrics.analyze(str(out))
    fig = plots.analysis_figure(an)
    ax = next(a for a in fig.axes if a.get_title().startswith("trajectories"))
    robot_lines = [ln for ln in ax.get_lines() if ln.get_color() == ROBOT_COLOUR]
    assert any(ln.get_label() == "robot bot" for ln in robot_lines)  # its path
    assert any(ln.get_marker() == "*" for ln in robot_lines)  # its goal
    assert len(ax.collections) >= 2  # the heading arrows beside the people's tracks
    plt.close(fig)


def test_bench_social_says_a_goal_reached_at_the_start_was_reached(tmp_path, capsys):
    from robot_scenes import with_robot

    from sweep_core.model.yaml_files import dump_yaml
    scene = tmp_path / "at_goal.yaml"
    scene.write_text(dump_yaml(with_robot({"goal": [0.5, 1.5]})))
    assert main(["bench", "social", "--seeds", "1", "--scenes", str(scene), "--controllers",
                 "pursuit", "--t-end", "0.1", "--workers", "1",
                 "--out", str(tmp_path / "o")]) == 0
    (row,) = csv.DictReader((tmp_path / "o" / "runs.csv").open())
    assert row["reached"] == "True" and float(row["time_to_goal_s"]) == 0.0
    printed = capsys.readouterr().out
    assert "goal at 0.00 s" in printed and "goal not reached" not in printed, printed


def test_robot_crowd_reaches_its_goal_without_robot_contact_and_in_time():
    """The bundled robot_crowd with its own controller, as `sweep bench social` runs it (dt
    0.01 s, the scene's horizon), seeds 0-9: at least 9 reach the goal with no robot-on-person
    contact, and the mean time to goal is within 1.5 times the straight-line time at the
    robot's top speed. Runs are the same bits on every CPU (test_cpu_bits), so this is the
    measured table of docs/social_bench.md, not a sample of it."""
    robot = load_scene("robot_crowd").robots[0]
    rows = [simulate(Run("robot_crowd", robot.controller, seed, 0.01, None)) for seed in range(10)]
    seen = [(r["seed"], r["reached"], r["robot_contacts"], r["time_to_goal_s"]) for r in rows]
    assert sum(bool(r["success"]) for r in rows) >= 9, seen
    straight = math.dist(robot.goal, robot.pose[:2]) / robot.max_speed
    times = [r["time_to_goal_s"] for r in rows if r["reached"]]
    assert np.mean(times) <= 1.5 * straight, seen
