"""Social-navigation metrics (sweep_core.analysis.social) against values derived by hand."""
import math

import numpy as np
import pytest

from sweep_core.analysis import social


def test_time_to_collision_of_disks_at_constant_velocity():
    # robot at the origin at 1 m/s along +x, people standing; radii add up to 0.5 m
    robot_v = np.array([1.0, 0.0])
    people = np.array([[5.0, 0.0], [5.0, 0.3], [5.0, 0.6], [-5.0, 0.0], [0.3, 0.4]])
    ttc = social.time_to_collision(people, -robot_v[None, :], np.full(5, 0.5))
    # head on: the gap 5 - 0.5 closes at 1 m/s; offset 0.3: (5 - tau)^2 + 0.3^2 = 0.5^2;
    # offset 0.6 > 0.5: passes clear; behind: moving apart; at distance 0.5: touching
    assert ttc[0] == pytest.approx(4.5, abs=1e-12)
    assert ttc[1] == pytest.approx(5.0 - 0.4, abs=1e-12)
    assert ttc[2] == math.inf and ttc[3] == math.inf
    assert ttc[4] == 0.0
    # both moving: a person walking towards the robot at 0.5 m/s closes the 4.5 m at 1.5 m/s
    both = social.time_to_collision(np.array([[5.0, 0.0]]), np.array([[-1.5, 0.0]]),
                                    np.array([0.5]))
    assert both[0] == pytest.approx(3.0, abs=1e-12)
    # standing still, apart: never
    assert social.time_to_collision(np.array([[1.0, 0.0]]), np.zeros((1, 2)),
                                    np.array([0.5]))[0] == math.inf


def test_clearance_is_surface_to_surface():
    cl = social.clearance(np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([0.3, 0.2]),
                          np.array([[3.0, 4.0], [1.0, 1.0]]), np.array([0.25, 0.5]))
    assert cl == pytest.approx(np.array([[5.0 - 0.55, math.sqrt(2) - 0.8],
                                         [math.sqrt(20) - 0.45, 1.0 - 0.7]]), abs=1e-12)


def test_jerk_is_exact_for_cubic_motion_on_uneven_frames():
    t = np.array([0.0, 0.1, 0.25, 0.3, 0.7, 1.0])
    p = np.column_stack([2.0 * t**3 - t, 0.5 * t**2])  # x''' = 12, y''' = 0
    j = social.jerk(t, p)
    assert j.shape == (3, 2)
    assert j[:, 0] == pytest.approx(np.full(3, 12.0), rel=1e-9)
    assert j[:, 1] == pytest.approx(np.zeros(3), abs=1e-9)
    assert social.jerk(t[:3], p[:3]).shape == (0, 2)


def test_wrap_and_spl():
    assert social.wrap(np.array([3 * math.pi / 2, -3 * math.pi / 2, 0.1])) == pytest.approx(
        [-math.pi / 2, math.pi / 2, 0.1])
    assert social.spl(True, 12.0, 10.0) == pytest.approx(10.0 / 12.0)
    assert social.spl(True, 9.9, 10.0) == 1.0  # shorter than l (grid error): capped at 1
    assert social.spl(False, 10.0, 10.0) == 0.0
    assert social.spl(True, 1.0, None) is None


# -- a hand-built recording -------------------------------------------------------------------
# Robot r1 (radius 0.25 m) drives along y = 0 at 1 m/s: x = k / 10 at frame k (t = k / 10 s),
# k = 0 .. 120, towards its goal (10, 0) (goal radius 0.05 m): it reaches it at frame 100.
# Its yaw swings between pi - 0.05 and -pi + 0.05 (a change of 0.1 rad across +-pi every frame)
# while it moves along +x (a holonomic robot; the odometry twist is in its own frame).
# People (radius 0.25 m): 0 stands at (5, 1); 1 walks from (30, 0) towards it at 1 m/s;
# 2 stands far away at (0, -20), except with ``push`` at the frames TOUCH, where it is just
# ahead of the robot, touching it, with a contact impulse (0.003, 0.004) (|.| = 0.005).
DT, FRAMES, R = 0.1, 121, 0.25
TOUCH = [*range(20, 26), *range(28, 31)]


def robot_scene(robots: bool = True) -> dict:
    spec = {"name": "hand_built", "agents": {"positions": [[5, 1], [30, 0], [0, -20]],
                                             "radius": R},
            "drift": {"kind": "none"}, "noise": {"sigma": 0.0}}
    if robots:
        spec["robots"] = [{"name": "r1", "radius": R, "pose": [0.0, 0.0, 0.0],
                           "goal": [10.0, 0.0], "goal_radius": 0.05}]
    return spec


def write_recording(path, push: bool) -> None:
    from sweep_core.io import cdr
    from sweep_core.io.recording import Recorder
    from sweep_core.model.scene import Scene

    scene = Scene.from_dict(robot_scene())
    meta = {"scene": scene.to_yaml(), "seed": "0", "dt": repr(DT), "t_end": repr(12.0),
            "record_every": "1", "scheme": "projected_euler"}
    with Recorder(path, metadata=meta, flush_interval_s=None) as rec:
        for topic, msgtype in (("/poses", cdr.POSE_ARRAY), ("/agents", cdr.POINT_CLOUD2),
                               ("/r1/odom", cdr.ODOMETRY), ("/r1/contacts", cdr.POINT_CLOUD2)):
            rec.add_channel(topic, msgtype)
        for k in range(FRAMES):
            ns, x = k * 100_000_000, k / 10
            touching = push and k in TOUCH
            q = np.array([[5.0, 1.0], [30.0 - x, 0.0],
                          [x + 2 * R, 0.0] if touching else [0.0, -20.0]])
            v = np.array([[0.0, 0.0], [-1.0, 0.0], [1.0, 0.0] if touching else [0.0, 0.0]])
            rec.write("/poses", ns, cdr.encode_pose_array(ns, "map", q))
            rec.write("/agents", ns, cdr.encode_point_cloud2(ns, "map", {
                "id": np.arange(3.0), "x": q[:, 0], "y": q[:, 1], "radius": np.full(3, R),
                "vx": v[:, 0], "vy": v[:, 1], "reaction_x": np.zeros(3),
                "reaction_y": np.zeros(3)}))
            yaw = math.pi - 0.05 if k % 2 == 0 else -math.pi + 0.05
            # the map velocity (1, 0) in the robot's frame
            twist = [math.cos(yaw), -math.sin(yaw), 0.0]
            rec.write("/r1/odom", ns, cdr.encode_odometry(ns, "odom", "base_link",
                                                           [x, 0.0, yaw], twist))
            ids = [2.0] if touching else []
            rec.write("/r1/contacts", ns, cdr.encode_point_cloud2(ns, "map", {
                "id": np.array(ids), "x": np.full(len(ids), x + 2 * R),
                "y": np.zeros(len(ids)), "impulse_x": np.full(len(ids), 0.003),
                "impulse_y": np.full(len(ids), 0.004)}))


def test_metrics_of_a_robot_passing_a_standing_person(tmp_path):
    from sweep_core.analysis import metrics

    path = tmp_path / "pass.mcap"
    write_recording(path, push=False)
    an = metrics.analyze(path)
    m = an.summary["robots"]["r1"]
    # the episode: frames 0 .. 100 (x = 10 reaches the goal; x = 9.9 is 0.1 m away)
    assert m["frames"] == 101
    assert m["reached_goal"] and m["success"] and not m["collided"]
    assert m["time_to_goal_s"] == pytest.approx(10.0, abs=1e-12)
    assert m["path_length_m"] == pytest.approx(10.0, abs=1e-12)
    # no walls: the shortest way is the straight 10 m, which the 0.1 m grid overestimates by
    # at most its metrication (2.75 %) and about a cell
    geo = m["geodesic_m"]
    assert 10.0 - 1e-9 <= geo <= 10.0 * 1.0275 + 0.1
    assert m["path_length_ratio"] == pytest.approx(10.0 / geo, rel=1e-12)
    assert m["spl"] == pytest.approx(min(1.0, geo / 10.0), rel=1e-12)
    # clearance to person 0, the nearest at every frame: sqrt((x - 5)^2 + 1) - 0.5
    x = np.arange(101) / 10
    c0 = np.hypot(x - 5.0, 1.0) - 2 * R
    assert m["clearance"]["min_m"] == pytest.approx(0.5, abs=1e-12)  # at x = 5
    assert m["clearance"]["mean_m"] == pytest.approx(c0.mean(), rel=1e-12)
    # zones: personal while sqrt((x - 5)^2 + 1) < 1.7, |x - 5| < 1.375: x = 3.7 .. 6.3, 27
    # frames; social while it is < 4.1, |x - 5| < 3.976: x = 1.1 .. 8.9, 79 frames, 52 of them
    # not personal; public: the other 22; never closer than 0.5 m
    assert m["zones"] == pytest.approx({"intimate": 0.0, "personal": 27 / 101,
                                        "social": 52 / 101, "public": 22 / 101}, abs=1e-15)
    assert m["discomfort_frequency"] == 0.0
    assert m["contact"] == {"frames": 0, "events": 0, "people": 0, "impulse_total": 0.0,
                             "impulse_max": 0.0}
    # person 1 closes at 2 m/s: at frame k their clearance is 30 - 2 x - 0.5, smallest
    # (9.5 m, 4.75 s) at the last frame; person 0 is passed 1 m off (more than 0.5 m): never
    assert m["min_ttc_s"] == pytest.approx(4.75, abs=1e-9)
    # the yaw changes by 0.1 rad (across +-pi) at each of the 100 steps of the episode
    assert m["heading_change_rad"] == pytest.approx(10.0, abs=1e-9)
    assert m["heading_change_per_m"] == pytest.approx(1.0, abs=1e-9)
    # constant velocity: no jerk (up to the rounding of k / 10 over 0.1^3)
    assert m["jerk"]["max_m_per_s3"] == pytest.approx(0.0, abs=1e-9)
    # the frames of the episode in RUN.robots.csv's table, the velocity turned into map frame
    assert an.robots.shape == (101, 11)
    assert an.robots[:, 5] == pytest.approx(np.ones(101), abs=1e-12)
    assert an.robots[:, 6] == pytest.approx(np.zeros(101), abs=1e-12)


def test_metrics_of_a_robot_pushing_someone(tmp_path):
    from sweep_core.analysis import metrics

    path = tmp_path / "push.mcap"
    write_recording(path, push=True)
    m = metrics.analyze(path).summary["robots"]["r1"]
    assert m["reached_goal"] and m["collided"] and not m["success"]
    assert m["spl"] == 0.0 and m["time_to_goal_s"] == pytest.approx(10.0, abs=1e-12)
    # contacts at frames 20 .. 25 and 28 .. 30: 9 frames, begun twice, one person
    c = m["contact"]
    assert (c["frames"], c["events"], c["people"]) == (9, 2, 1)
    assert c["impulse_total"] == pytest.approx(9 * 0.005, rel=1e-6)  # float32 components
    assert c["impulse_max"] == pytest.approx(0.005, rel=1e-6)
    # touching at those 9 frames: clearance 0, intimate, discomfort, time to collision 0
    assert m["clearance"]["min_m"] == pytest.approx(0.0, abs=1e-12)
    assert m["zones"]["intimate"] == pytest.approx(9 / 101, abs=1e-15)
    assert m["zones"]["social"] == pytest.approx((52 - 9) / 101, abs=1e-15)
    assert m["discomfort_frequency"] == pytest.approx(9 / 101, abs=1e-15)
    assert m["min_ttc_s"] == 0.0


def test_a_time_limit_ends_the_episode_before_the_goal(tmp_path):
    from sweep_core.analysis import metrics

    path = tmp_path / "pass.mcap"
    write_recording(path, push=False)
    m = metrics.analyze(path, time_limit=5.0).summary["robots"]["r1"]
    assert m["frames"] == 51 and not m["reached_goal"] and not m["success"]
    assert m["time_to_goal_s"] is None and m["path_length_ratio"] is None
    assert m["spl"] == 0.0
    assert m["path_length_m"] == pytest.approx(5.0, abs=1e-12)
    # the minimum clearance is reached at x = 5, the last frame of this episode
    assert m["clearance"]["min_m"] == pytest.approx(0.5, abs=1e-12)


def test_geodesic_distance_goes_round_a_wall():
    from sweep_core.analysis.social import geodesic_distance
    from sweep_core.model.scene import Scene

    # a wall from (2, -1) to (2, 1) between start (0, 0) and goal (4, 0): a disk of radius
    # 0.25 m passes its end at (2, 1.25): 2 sqrt(2^2 + 1.25^2) = 4.717 m
    scene = Scene.from_dict({"name": "wall", "agents": {"positions": [[0, 5]], "radius": 0.2},
                             "walls": [{"kind": "segment", "a": [2, -1], "b": [2, 1]}],
                             "drift": {"kind": "none"}})
    d, why = geodesic_distance(scene, np.array([0.0, 0.0]), np.array([4.0, 0.0]), 0.25)
    exact = 2 * math.hypot(2.0, 1.25)
    assert why is None and exact - 1e-9 <= d <= exact * 1.0275 + 0.2


def test_a_recorded_run_is_read_as_the_engine_stepped_it(tmp_path):
    """sweep run's recording of a pursuing robot meeting people: analyze's per-frame robot
    table equals the engine's states (pose exactly, clearance computed here independently,
    contacts and impulses to float32)."""
    from robot_scenes import small_scene

    from sweep_core.analysis import metrics
    from sweep_core.io.metadata import run_metadata
    from sweep_core.io.recording import runs
    from sweep_core.model.scene import Scene
    from sweep_core.numerics.simulator import Simulator

    spec = small_scene(sigma=0.05)
    spec["robots"][0]["controller"] = "pursuit"
    spec["robots"][0]["goal"] = [6.5, 1.5]
    scene = Scene.from_dict(spec)
    sim = Simulator(scene, dt=0.05, seed=2)
    seen = []

    def collect(s) -> None:
        st = s.robots.state("bot")
        d = np.hypot(*(s.positions - np.asarray(st.pose[:2])).T) - 0.3 - s.radii
        seen.append((*st.pose, d.min(), len(st.contact_ids),
                     np.hypot(*np.asarray(st.contact_impulse).reshape(-1, 2).T).sum()))

    out = tmp_path / "run.mcap"
    done = runs.record_run(sim, 4.0, out, run_metadata(scene, sim, 4.0, 1), on_state=collect)
    assert done.status == "completed"
    an = metrics.analyze(out, goal_radius=0.01)  # the goal is not reached: every frame counts
    want = np.array(seen)
    got = an.robots
    assert got.shape[0] == len(want) == 81
    assert np.array_equal(got[:, 2:5], want[:, 0:3])  # x, y, yaw: float64, as stepped
    assert got[:, 7] == pytest.approx(want[:, 3], abs=1e-12)
    assert np.array_equal(got[:, 9], want[:, 4]) and want[:, 4].sum() > 0  # they met
    assert got[:, 10] == pytest.approx(want[:, 5], rel=1e-6)
    m = an.summary["robots"]["bot"]
    assert m["collided"] and m["contact"]["frames"] == int(np.count_nonzero(want[:, 4]))
    assert m["clearance"]["min_m"] == pytest.approx(want[:, 3].min(), abs=1e-12)


def test_cli_prints_the_robots_and_writes_their_frames(tmp_path, capsys):
    import json

    from sweep_core.cli import main

    path = tmp_path / "pass.mcap"
    write_recording(path, push=False)
    assert main(["analyze", str(path), "--json", "--quiet", "--no-plots"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["robots"]["r1"]["success"] is True
    frames = np.genfromtxt(summary["outputs"]["robots_csv"], delimiter=",", names=True)
    assert len(frames) == 101 and frames.dtype.names[:3] == ("robot", "t_s", "x_m")
    assert main(["analyze", str(path), "--quiet", "--no-plots"]) == 0
    text = capsys.readouterr().out
    assert "robots.r1.spl" in text and "robots.r1.contact.frames" in text
    assert main(["analyze", str(path), "--quiet", "--no-plots", "--time-limit", "-1"]) == 2
    err = capsys.readouterr().err
    assert "--time-limit" in err and "Traceback" not in err


def test_nearest_is_the_minimum_of_clearance_and_time_to_collision_bit_for_bit() -> None:
    """nearest (one compiled pass) gives the bits of clearance(...).min() and of
    time_to_collision(...).min() over the people of finite velocity, on random scenes with
    unknown velocities, overlaps and people moving apart."""
    import math

    from sweep_core.analysis.social import clearance, nearest, time_to_collision

    rng = np.random.default_rng(17)
    for _ in range(3000):
        m = int(rng.integers(1, 15))
        pos, vel = rng.normal(size=2) * 3, rng.normal(size=2)
        people, radii = rng.normal(size=(m, 2)) * 3, rng.uniform(0.1, 0.5, m)
        v = rng.normal(size=(m, 2))
        if rng.random() < 0.3:
            v[rng.integers(0, m)] = np.nan
        if rng.random() < 0.1:
            v[:] = np.nan
        if rng.random() < 0.2:
            people[0] = pos + 0.1  # overlapping: a time to collision of 0
        known = np.all(np.isfinite(v), axis=1)
        ttc = time_to_collision(people[known] - pos, v[known] - vel, 0.3 + radii[known])
        want = (float(clearance(pos[None], np.array([0.3]), people, radii)[0].min()),
                float(ttc.min()) if len(ttc) else math.nan)
        got = nearest(pos, vel, 0.3, people, radii, v)
        assert np.array(got).tobytes() == np.array(want).tobytes()


@pytest.mark.parametrize("option, value, unit, example", [
    ("--goal-radius", "0", "metres", "0.5"), ("--time-limit", "nan", "seconds", "30")])
def test_cli_refuses_a_bad_goal_radius_or_time_limit_with_a_fix(
        tmp_path, capsys, option: str, value: str, unit: str, example: str) -> None:
    from sweep_core.cli import main

    path = tmp_path / "pass.mcap"
    write_recording(path, push=False)
    assert main(["analyze", str(path), "--quiet", "--no-plots", option, value]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith(f"sweep: error: {option}: must be a positive "
                                              f"number of {unit}, got "), err
    assert f"(fix: e.g. {option} {example}, or leave it out" in err, err


def test_cli_refuses_a_goal_radius_beyond_a_scenes_bound(tmp_path, capsys) -> None:
    """--goal-radius 1e300 would count every frame as at the goal; a scene's goal_radius is
    bounded by 1e4 m, and so is the option."""
    from sweep_core.cli import main

    path = tmp_path / "pass.mcap"
    write_recording(path, push=False)
    assert main(["analyze", str(path), "--quiet", "--no-plots", "--goal-radius", "1e300"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith("sweep: error: --goal-radius: 1e+300 m is beyond"
                                              ), err
    assert "(fix: --goal-radius 10000 or less)" in err, err
    assert main(["analyze", str(path), "--quiet", "--no-plots", "--goal-radius", "1e4"]) == 0


@pytest.mark.parametrize("option", ["--time-limit", "--goal-radius"])
def test_cli_refuses_a_robot_option_for_a_recording_without_robots(tmp_path, capsys, option):
    """--time-limit and --goal-radius set a robot's episode; on a crowd without robots they
    would change nothing (a --time-limit 2 does not cut the crowd's metrics to 2 s), so they
    are refused in one line with the fix."""
    from sweep_core.cli import main
    from sweep_core.model.scene import Scene

    scene = tmp_path / "crowd.yaml"
    scene.write_text(Scene.from_dict({"name": "crowd", "agents": {
        "positions": [[0.0, 0.0], [2.0, 0.0]], "radius": 0.2},
        "drift": {"kind": "uniform", "velocity": [1.0, 0.0]}}).to_yaml())
    out = tmp_path / "crowd.mcap"
    assert main(["run", str(scene), "--t-end", "1", "--dt", "0.05", "--out", str(out),
                 "--quiet"]) == 0
    capsys.readouterr()
    assert main(["analyze", str(out), "--quiet", "--no-plots", option, "2"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith(f"sweep: error: {option} 2: the recording's "
                                              "scene has no robot"), err
    assert "(fix: leave it out" in err, err
    assert main(["analyze", str(out), "--quiet", "--no-plots"]) == 0
