"""Robots in the engine: exact kinematics, no overlap, prescribed motion against a pinned crowd,
weights in the projection, scans against an independent ray cast, refusals, recording and
replay. Few agents and short horizons (cheap)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from sweep_core import Scene, Simulator
from sweep_core.errors import SceneError

BOX = [{"kind": "polyline", "points": [[0, 0], [10, 0], [10, 6], [0, 6], [0, 0]]}]
FAST = {"max_acceleration": 1e6, "max_angular_acceleration": 1e6, "max_speed": 2.0,
        "max_angular_speed": 3.0}


def _scene(robot: dict, agents: dict | None = None, **extra) -> Scene:
    data = {"agents": agents or {"positions": [[8.0, 5.0]], "radius": 0.25},
            "walls": BOX, "robots": [{"name": "bot", "radius": 0.3, **robot}], **extra}
    return Scene.from_dict(data)


@pytest.mark.parametrize("kind, command", [("diff_drive", (0.8, 0.0, 0.7)),
                                           ("diff_drive", (1.1, 0.0, 0.0)),
                                           ("holonomic", (0.5, -0.4, -1.2))])
def test_odometry_follows_the_arc_exactly_in_free_space(kind, command):
    x0, y0, th0 = 3.0, 3.0, 0.4
    scene = _scene({"pose": [x0, y0, th0], "kinematics": {"type": kind, **FAST}})
    h, n = 0.02, 60
    sim = Simulator(scene, dt=h, seed=0)
    sim.robots.command("bot", command)
    vx, vy, w = command
    for k in range(1, n + 1):
        sim.step()
        st = sim.robots.state("bot")
        t = k * h
        # closed form: the body velocity turning at w, integrated from 0 to t
        if w == 0.0:
            dx = t * (math.cos(th0) * vx - math.sin(th0) * vy)
            dy = t * (math.sin(th0) * vx + math.cos(th0) * vy)
        else:
            s0, c0 = math.sin(th0), math.cos(th0)
            s1, c1 = math.sin(th0 + w * t), math.cos(th0 + w * t)
            dx = (vx * (s1 - s0) + vy * (c1 - c0)) / w
            dy = (vx * (c0 - c1) + vy * (s1 - s0)) / w
        assert st.pose[0] == pytest.approx(x0 + dx, abs=1e-12)
        assert st.pose[1] == pytest.approx(y0 + dy, abs=1e-12)
        assert st.pose[2] == pytest.approx(th0 + w * t, abs=1e-12)
        assert st.twist == st.command == command
    assert st.clipped == 0 and st.blocked == 0


def test_commands_are_clipped_and_counted():
    scene = _scene({"pose": [3, 3, 0], "kinematics": {"type": "diff_drive", "max_speed": 1.0,
                                                      "max_acceleration": 2.0}})
    sim = Simulator(scene, dt=0.05, seed=0)
    sim.robots.command("bot", (5.0, 1.0, 0.0))  # vy of a diff drive robot is dropped
    sim.step()
    st = sim.robots.state("bot")
    assert st.command == (0.1, 0.0, 0.0) and st.clipped == 1  # 2 m/s^2 x 0.05 s
    sim.step(30)
    assert st.command == (1.0, 0.0, 0.0) and st.clipped == 31


def _true_min_gap(q: np.ndarray, r: np.ndarray) -> float:
    """Smallest gap among the disks and to the box's four walls (independent of the engine)."""
    d = np.hypot(*(q[:, None, :] - q[None, :, :]).transpose(2, 0, 1))
    gap = d - r[:, None] - r[None, :]
    np.fill_diagonal(gap, np.inf)
    walls = np.minimum.reduce([q[:, 0], 10 - q[:, 0], q[:, 1], 6 - q[:, 1]]) - r
    return float(min(gap.min(), walls.min()))


@pytest.mark.parametrize("weight", ["inf", 1.0, 3.0])
def test_no_overlap_of_robot_people_walls(weight):
    agents = {"spawn": {"count": 25, "radius": 0.25, "seed": 4,
                        "region": {"kind": "rectangle", "min": [3, 1], "max": [7, 5]}}}
    scene = _scene({"pose": [0.5, 3.0, 0.0], "goal": [9.3, 3.0], "controller": "pursuit",
                    "weight": weight, "scan": {"rate": 10}},
                   agents, drift={"kind": "goal", "goal": [0.5, 3.0], "speed": 1.0},
                   noise={"sigma": 0.2})
    sim = Simulator(scene, dt=0.05, seed=2)
    r = np.concatenate([scene.radii(0), [0.3]])
    worst = np.inf
    touched = 0
    for _ in range(120):
        sim.step()
        st = sim.robots.state("bot")
        q = np.concatenate([sim.positions, [st.pose[:2]]])
        worst = min(worst, _true_min_gap(q, r))
        touched += len(st.contact_ids)
    assert worst >= -1e-9
    assert touched > 0  # the robot met people (the property was exercised)


def test_prescribed_robot_against_a_pinned_person_stops_and_reports():
    # a person between the robot and a wall at x = 3: once pinned it cannot yield
    walls = [{"kind": "segment", "a": [3, -2], "b": [3, 2]}]
    scene = Scene.from_dict({"agents": {"positions": [[2.0, 0.0]], "radius": 0.25},
                             "walls": walls,
                             "robots": [{"name": "bot", "radius": 0.3, "pose": [0, 0, 0]}]})
    sim = Simulator(scene, dt=0.05, seed=0)
    sim.robots.command("bot", (1.0, 0.0, 0.0))
    sim.step(60)
    st = sim.robots.state("bot")
    assert st.stopped and st.blocked > 0 and st.command == (0.0, 0.0, 0.0)
    person = sim.positions[0]
    assert person[0] <= 3 - 0.25 + 1e-9
    assert person[0] - st.pose[0] >= 0.55 - 1e-9
    # the robot came to rest against the person: it advanced until it could not
    assert st.pose[0] == pytest.approx(3 - 0.25 - 0.55, abs=0.06)


def test_weight_one_robot_is_pushed_like_a_person():
    """A weight-1 robot moving straight is the same disk as an agent with that drift."""
    h = 0.05
    people = [[2.0, 3.0], [2.6, 3.05]]
    robot = _scene({"pose": [1.0, 3.0, 0.0], "weight": 1, "radius": 0.25,
                    "kinematics": {"type": "diff_drive", **FAST}},
                   {"positions": people, "radius": 0.25},
                   drift={"kind": "per_agent", "velocities": [[0.0, 0.0], [-0.5, 0.0]]})
    robot = Scene.from_dict({**robot.spec, "robots": [{**robot.spec["robots"][0],
                                                       "radius": 0.25}]})
    agent = Scene.from_dict({"agents": {"positions": people + [[1.0, 3.0]], "radius": 0.25},
                             "walls": BOX, "drift": {"kind": "per_agent", "velocities": [
                                 [0.0, 0.0], [-0.5, 0.0], [1.2, 0.0]]}})
    a, b = Simulator(robot, dt=h, seed=0), Simulator(agent, dt=h, seed=0)
    a.robots.command("bot", (1.2, 0.0, 0.0))
    pushed = 0
    for _ in range(30):
        a.step()
        b.step()
        st = a.robots.state("bot")
        np.testing.assert_allclose(a.positions, b.positions[:2], rtol=0, atol=1e-12)
        np.testing.assert_allclose(st.pose[:2], b.positions[2], rtol=0, atol=1e-12)
        pushed += len(st.contact_ids)
    assert pushed > 0


def test_weighted_projection_splits_the_push_by_weight():
    """Robot of weight 4 driving into a free, touching person: min 4 (x_r - d)^2 + x_p^2 with
    x_p >= x_r gives x_r = x_p = 4 d / 5."""
    h, v = 0.05, 1.0
    scene = _scene({"pose": [2.0, 3.0, 0.0], "weight": 4,
                    "kinematics": {"type": "diff_drive", **FAST}},
                   {"positions": [[2.55, 3.0]], "radius": 0.25})
    sim = Simulator(scene, dt=h, seed=0)
    sim.robots.command("bot", (v, 0.0, 0.0))
    sim.step()
    st = sim.robots.state("bot")
    assert st.pose[0] - 2.0 == pytest.approx(0.8 * v * h, abs=1e-12)
    assert sim.positions[0, 0] - 2.55 == pytest.approx(0.8 * v * h, abs=1e-12)
    # the step's bound is a proved duality gap: finite, within tol, and it covers the error
    bound = sim.last.projection.bound
    err = max(abs(st.pose[0] - 2.0 - 0.8 * v * h), abs(sim.positions[0, 0] - 2.55 - 0.8 * v * h))
    assert math.isfinite(bound) and err <= bound + 1e-15 and bound <= 1e-6
    # impulse: the multiplier lam = x_p (the person's reaction, weight 1) over h, along +x
    np.testing.assert_allclose(st.contact_impulse, [[0.8 * v, 0.0]], atol=1e-9)


def _independent_ranges(o, angles, circles, segments, halfplanes, rmax):
    out = []
    for a in angles:
        u = np.array([math.cos(a), math.sin(a)])
        best = math.inf
        for c, r in circles:
            oc = np.asarray(o) - c
            b = float(u @ oc)
            disc = b * b - float(oc @ oc - r * r)
            if disc >= 0:
                s = -b - math.sqrt(disc)
                if s >= 0:
                    best = min(best, s)
        for p, q in segments:
            p, q = np.asarray(p, float), np.asarray(q, float)
            m = np.array([u, p - q]).T
            if abs(np.linalg.det(m)) < 1e-15:
                continue
            s, w = np.linalg.solve(m, p - np.asarray(o))
            if s >= 0 and 0 <= w <= 1:
                best = min(best, s)
        for n, c in halfplanes:
            dn = float(np.dot(n, u))
            if dn < 0:
                s = (c - float(np.dot(n, o))) / dn
                if s >= 0:
                    best = min(best, s)
        out.append(best if best <= rmax else math.inf)
    return np.array(out)


def test_scan_equals_an_independent_ray_cast():
    rng = np.random.default_rng(5)
    people = rng.uniform([1.5, 0.5], [8.5, 5.5], (40, 2))
    keep = [0]
    for i in range(1, len(people)):  # non-overlapping people, away from the robot
        if (np.hypot(*(people[keep] - people[i]).T).min() > 0.5
                and math.hypot(*(people[i] - [4.0, 3.0])) > 0.6):
            keep.append(i)
    people = people[keep]
    scene = Scene.from_dict({
        "agents": {"positions": people.tolist(), "radius": 0.25},
        "walls": BOX + [{"kind": "halfplane", "normal": [0.0, -1.0], "offset": -5.8}],
        "obstacles": [{"kind": "circle", "center": [1.0, 1.0], "radius": 0.3}],
        "robots": [{"name": "bot", "radius": 0.3, "pose": [4.0, 3.0, 0.3],
                    "scan": {"range_max": 8.0, "increment": 0.01}}]})
    sim = Simulator(scene, dt=0.05, seed=0)
    st = sim.robots.state("bot")
    spec = st.robot.scan
    angles = st.pose[2] + spec.angle_min + spec.increment * np.arange(spec.beams)
    box = [((0, 0), (10, 0)), ((10, 0), (10, 6)), ((10, 6), (0, 6)), ((0, 6), (0, 0))]
    want = _independent_ranges(st.pose[:2], angles,
                               [(p, 0.25) for p in people] + [(np.array([1.0, 1.0]), 0.3)],
                               box, [(np.array([0.0, -1.0]), -5.8)], spec.range_max)
    got = st.scan.ranges
    assert np.array_equal(np.isinf(got), np.isinf(want))
    assert np.isfinite(got).sum() > 100
    np.testing.assert_allclose(got[np.isfinite(got)], want[np.isfinite(want)], rtol=0,
                               atol=1e-6)


@pytest.mark.parametrize("change, field", [
    ({"radius": -1}, "robots[0].radius"),
    ({"pose": [1, 2]}, "robots[0].pose"),
    ({"pose": [8.0, 5.2, 0]}, "robots[0].pose"),  # on the person
    ({"pose": [0.1, 3, 0]}, "robots[0].pose"),  # through the wall
    ({"weight": 0}, "robots[0].weight"),
    ({"weight": "heavy"}, "robots[0].weight"),
    ({"kinematics": {"type": "ackermann"}}, "robots[0].kinematics.type"),
    ({"kinematics": {"max_speed": float("nan")}}, "robots[0].kinematics.max_speed"),
    ({"controller": "pursuit"}, "robots[0].goal"),
    ({"controller": "mpc", "goal": [1, 1]}, "robots[0].controller"),
    ({"scan": {"range_min": 5, "range_max": 1}}, "robots[0].scan.range_max"),
    ({"scan": {"increment": 1e-9}}, "robots[0].scan.increment"),
    ({"name": "Bot!"}, "robots[0].name"),
    ({"colour": "red"}, "robots[0]"),
])
def test_bad_robots_are_refused_by_field(change, field):
    robot = {"name": "bot", "radius": 0.3, "pose": [3, 3, 0], **change}
    with pytest.raises(SceneError) as err:
        Scene.from_dict({"agents": {"positions": [[8.0, 5.0]], "radius": 0.25},
                         "walls": BOX, "robots": [robot]})
    assert err.value.field == field
    assert "\n" not in str(err.value) and "fix" in str(err.value)


def test_two_robots_of_one_name_and_reaction_refused():
    robot = {"name": "bot", "radius": 0.3, "pose": [3, 3, 0]}
    with pytest.raises(SceneError, match="used twice"):
        Scene.from_dict({"agents": {"positions": [], "radius": 0.25},
                         "robots": [robot, {**robot, "pose": [5, 3, 0]}]})
    with pytest.raises(SceneError) as err:
        _scene({"pose": [3, 3, 0]}, crowd_reaction={"kind": "avoid", "radius": -2})
    assert err.value.field == "crowd_reaction.radius"


def test_a_reaction_strength_beyond_the_speed_bound_is_refused():
    """strength is a speed (m/s); before, 1e20 was accepted."""
    with pytest.raises(SceneError) as err:
        _scene({"pose": [3, 3, 0]}, crowd_reaction={"kind": "avoid", "strength": 1e20})
    assert err.value.field == "crowd_reaction.strength" and "10000 m/s" in str(err.value)


def test_placing_a_robot_on_someone_is_refused():
    scene = _scene({"pose": [3, 3, 0]})
    sim = Simulator(scene, dt=0.05, seed=0)
    with pytest.raises(SceneError, match="overlaps agent 0") as err:
        sim.robots.place("bot", (8.2, 5.0, 0.0), sim.t, sim.positions, sim.radii)
    assert err.value.field == "initialpose"
    with pytest.raises(SceneError, match="walls"):
        sim.robots.place("bot", (9.9, 3.0, 0.0), sim.t, sim.positions, sim.radii)
    assert sim.robots.state("bot").pose == (3.0, 3.0, 0.0)
    sim.robots.place("bot", (5.0, 2.0, 1.0), sim.t, sim.positions, sim.radii)
    assert sim.robots.state("bot").pose == (5.0, 2.0, 1.0)


def test_avoid_reaction_keeps_people_farther_from_the_robot():
    agents = {"positions": [[5.0, 3.0 + dy] for dy in (-0.6, 0.05, 0.7)], "radius": 0.25}
    clear = []
    for kind in ("none", "avoid"):
        scene = _scene({"pose": [1.0, 3.0, 0.0], "kinematics": {"type": "diff_drive", **FAST}},
                       agents, crowd_reaction={"kind": kind})
        sim = Simulator(scene, dt=0.05, seed=0)
        sim.robots.command("bot", (1.0, 0.0, 0.0))
        worst = np.inf
        for _ in range(100):
            sim.step()
            st = sim.robots.state("bot")
            worst = min(worst, float((np.hypot(*(sim.positions - st.pose[:2]).T) - 0.55).min()))
        clear.append(worst)
    assert clear[0] <= 1e-9 < 0.1 < clear[1]


def test_recording_read_by_rosbags_and_replayed_bit_for_bit(tmp_path: Path):
    rosbags = pytest.importorskip("rosbags.highlevel")
    from sweep_core.analysis.replay import replay
    from sweep_core.cli import main

    scene = tmp_path / "robot.yaml"
    scene.write_text(
        "agents:\n  spawn: {count: 12, radius: 0.25, seed: 1,\n"
        "          region: {kind: rectangle, min: [3, 1], max: [7, 5]}}\n"
        "walls:\n  - {kind: polyline, points: [[0, 0], [10, 0], [10, 6], [0, 6], [0, 0]]}\n"
        "noise: {sigma: 0.2}\n"
        "robots:\n  - {name: bot, radius: 0.3, pose: [0.6, 3, 0], goal: [9.3, 3],\n"
        "     controller: pursuit, scan: {rate: 10, noise_std: 0.01}}\n"
        "crowd_reaction: {kind: avoid}\n")
    out = tmp_path / "run.mcap"
    assert main(["run", str(scene), "--t-end", "2", "--dt", "0.05", "--out", str(out),
                 "--quiet", "--record-every", "2"]) == 0
    counts: dict[str, int] = {}
    odom = None
    with rosbags.AnyReader([out]) as reader:
        for conn, _, raw in reader.messages():
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == "/bot/odom":
                odom = msg
            if conn.topic == "/tf":
                assert msg.transforms[0].child_frame_id == "base_link"
            if conn.topic == "/bot/scan":
                assert len(msg.ranges) == 360
    assert counts["/bot/odom"] == counts["/poses"] == counts["/tf"] == 21
    assert counts["/bot/cmd_vel"] == 41  # every step, for the replay
    assert counts["/bot/scan"] == 21 and counts["/tf_static"] == 1
    assert counts["/bot/status"] == counts["/bot/contacts"] == 21
    assert odom.header.frame_id == "odom" and odom.pose.pose.position.x > 1.0
    res = replay(out)
    assert res.identical and res.frames_compared == 21


def test_bundled_robot_scene_loads_and_steps():
    from importlib import resources

    path = Path(str(resources.files("sweep_core") / "scenes" / "robot_crowd.yaml"))
    scene = Scene.from_yaml(path)
    assert scene.n_agents == 100 and [r.name for r in scene.robots] == ["robot"]
    sim = Simulator(scene, dt=0.05, seed=0)
    assert "robot" in sim.robots.controllers
    sim.step(3)
    assert sim.robots.state("robot").pose[0] > 1.0


def test_a_disabled_robot_leaves_the_crowd_as_without_robots():
    """enabled: false (what --vary robots.0.enabled=true,false pairs) is the scene without the
    robot, bit for bit, on the same seed; enabled: true changes the crowd's path."""
    agents = {"positions": [[4.0, 3.0], [5.0, 3.2]], "radius": 0.25}
    base = {"agents": agents, "walls": BOX, "drift": {"kind": "goal", "goal": [1, 3],
                                                      "speed": 1.0}, "noise": {"sigma": 0.3}}
    robot = {"name": "bot", "radius": 0.3, "pose": [2.0, 3.0, 0.0], "goal": [9, 3],
             "controller": "pursuit"}
    runs = []
    for scene in (base, {**base, "robots": [{**robot, "enabled": False}]},
                  {**base, "robots": [{**robot, "enabled": "true"}]}):
        sim = Simulator(Scene.from_dict(scene), dt=0.05, seed=3)
        sim.step(40)
        runs.append(sim.positions)
    assert Simulator(Scene.from_dict({**base, "robots": [{**robot, "enabled": False}]}),
                     dt=0.05).robots is None
    assert np.array_equal(runs[0], runs[1])
    assert not np.array_equal(runs[0], runs[2])


def test_two_prescribed_robots_head_on_stop_without_overlap():
    from sweep_core.io import robot_topics

    robots = [{"name": "a", "radius": 0.3, "pose": [3.0, 3.0, 0.0]},
              {"name": "b", "radius": 0.3, "pose": [5.0, 3.0, math.pi]}]
    scene = Scene.from_dict({"agents": {"positions": [[8.0, 5.0]], "radius": 0.25},
                             "walls": BOX, "robots": robots})
    assert robot_topics.frames(scene, "b") == ("b/odom", "b/base_link")
    sim = Simulator(scene, dt=0.05, seed=0)
    for name in ("a", "b"):
        sim.robots.command(name, (1.0, 0.0, 0.0))
    closest = np.inf
    for _ in range(40):
        sim.step()
        pa, pb = sim.robots.state("a").pose, sim.robots.state("b").pose
        closest = min(closest, math.hypot(pa[0] - pb[0], pa[1] - pb[1]))
    assert 0.6 - 1e-9 <= closest < 0.7
    assert sim.robots.state("a").blocked > 0 and sim.robots.state("b").stopped


def test_a_blocked_robot_replays_bit_for_bit(tmp_path: Path):
    """Pursuit without a scan drives the robot into a person it pins against the east wall
    (no noise, all on one line, so the person cannot slide aside): its steps are refused
    (blocked, recorded in /NAME/status) and the replay is identical."""
    from sweep_core.analysis.replay import replay
    from sweep_core.cli import main
    from sweep_core.io.recording import read_recording

    scene = tmp_path / "pin.yaml"
    scene.write_text(
        "agents: {positions: [[8.0, 3.0]], radius: 0.25}\n"
        "walls:\n  - {kind: polyline, points: [[0, 0], [10, 0], [10, 6], [0, 6], [0, 0]]}\n"
        "robots:\n  - {name: bot, radius: 0.3, pose: [6.0, 3, 0], goal: [9.5, 3],\n"
        "     goal_radius: 0.1, controller: pursuit}\n")
    out = tmp_path / "pin.mcap"
    assert main(["run", str(scene), "--t-end", "6", "--dt", "0.05", "--out", str(out),
                 "--quiet"]) == 0
    from sweep_core.io import cdr

    last = [cdr.decode_point_cloud2(m.data) for m in read_recording(out, ["/bot/status"])][-1]
    assert last.fields["blocked"][0] > 0
    res = replay(out)
    assert res.identical and res.frames_compared == 121
