"""A robot in sweep_node over DDS: a test controller drives it with TwistStamped through a crowd
(odometry follows the commanded kinematics exactly in free space, never an overlap between the
robot and people or walls in the recording, TF readable by rosbags, the recording replays bit
for bit); initialpose refused with the reason, or applied.

One node process per test, run from this checkout's own installation (``pip install -e``:
its numba caches are warm, so no test waits for a build); every wait is on an event (a message,
a verdict, a process exit) with a generous deadline, never on how fast the node steps.
"""
from __future__ import annotations

import math
import signal
from pathlib import Path

import numpy as np
import pytest
import yaml
from robot_node import editable_installation, robot_probe, start, verdict_on
from test_node import WAIT_S, Running, diag_value, read_standard

from sweep_core.io import cdr
from sweep_core.io.recording import read_recording

DT = 0.01
RADIUS = 0.3
#: a 14 x 6 m room; the robot starts in its west half facing east; ten people stand in a block
#: across its way at x = 7..7.6 (no drift: they move only when the robot pushes through)
PEOPLE = [[7.0 + 0.6 * (k % 2), 1.6 + 0.7 * (k // 2)] for k in range(10)]
SPEED = 1.5
SCENE = {
    "name": "robot_through_a_crowd",
    "agents": {"positions": PEOPLE, "radius": 0.25, "speed": 1.0},
    "walls": [{"kind": "polyline", "points": [[0, 0], [14, 0], [14, 6], [0, 6], [0, 0]]}],
    "noise": {"sigma": 0.0},
    "robots": [{
        "name": "bot", "radius": RADIUS, "pose": [2.0, 3.0, 0.0],
        "kinematics": {"type": "diff_drive", "max_speed": SPEED, "max_angular_speed": 1.5,
                       "max_acceleration": 2.0, "max_angular_acceleration": 4.0},
        "weight": "inf",
        "scan": {"range_min": 0.05, "range_max": 8.0, "angle_min": -1.5, "angle_max": 1.5,
                 "increment": 0.05, "rate": 10.0, "noise_std": 0.0}}],
}


@pytest.fixture(scope="module")
def installed():
    """The sweep_node of this checkout's editable installation, and the DDS isolation."""
    return editable_installation()


@pytest.fixture
def probe():
    with robot_probe() as p:
        yield p


def arc(pose: np.ndarray, v: float, w: float, h: float) -> np.ndarray:
    """The exact unicycle motion over h s from pose (x, y, yaw) at (v, w)."""
    x, y, th = pose
    if w == 0.0:
        return np.array([x + v * h * math.cos(th), y + v * h * math.sin(th), th])
    return np.array([x + v / w * (math.sin(th + w * h) - math.sin(th)),
                     y - v / w * (math.cos(th + w * h) - math.cos(th)), th + w * h])


def wall_distance(p: np.ndarray) -> float:
    return min(p[0], 14.0 - p[0], p[1], 6.0 - p[1])


def test_a_controller_drives_the_robot_through_a_crowd(installed, probe, tmp_path):
    record = tmp_path / "robot.mcap"
    node = start(installed, tmp_path, probe, SCENE, {
        "dt": DT, "seed": 5, "rate_hz": 50.0, "steps_per_tick": 2, "record": str(record),
        "record_flush_interval_s": 0.2, "publish_markers": False})
    try:
        # initialpose: onto a person, into a wall: refused with the reason; the state stays
        probe.place(7.0, 1.6, 0.0)
        v = verdict_on(probe, 1, node)
        assert v["verdict"] == "refused" and "overlap" in v["message"], v
        assert "agent" in v["message"], v
        probe.place(0.1, 3.0, 0.0)
        v = verdict_on(probe, 2, node)
        assert v["verdict"] == "refused" and "wall" in v["message"], v
        # a free place: applied (and recorded, so that replay places it there too)
        probe.place(1.5, 2.8, 0.1)
        v = verdict_on(probe, 3, node)
        assert v["verdict"] == "applied" and "placed at (1.5, 2.8)" in v["message"], v
        probe.spin_until(lambda: probe.odom[-1].pose.pose.position.y == 2.8, WAIT_S,
                         "the robot at its new place", node)
        # drive east in a gentle arc, then straight on through the people
        x = lambda: probe.odom[-1].pose.pose.position.x  # noqa: E731
        yaw = lambda: 2 * math.atan2(probe.odom[-1].pose.pose.orientation.z,  # noqa: E731
                                     probe.odom[-1].pose.pose.orientation.w)
        probe.drive_until(SPEED, 0.5, lambda: yaw() > 0.3, "the robot turned left", node)
        probe.drive_until(SPEED, -0.5, lambda: yaw() < 0.0, "the robot turned back", node)
        probe.drive_until(SPEED, 0.0, lambda: x() > 9.0, "the robot through the crowd, past "
                          "x = 9 m", node)
        # on to the east wall (and whoever is pushed against it): the robot stops, and says so
        probe.drive_until(SPEED, 0.0, lambda: probe.diagnostics and "stopped instead of moving"
                          in probe.diagnostics[-1].status[0].message, "a stop reported", node)
        assert int(diag_value(probe, "robot_blocked_steps")) > 0
    finally:
        code = node.stop(signal.SIGINT)
    assert code == 0, node.log
    assert "Traceback" not in node.log, node.log
    check_recording(record)


def check_recording(record: Path) -> None:
    counts, meta = read_standard(record)  # mcap's reader and rosbags' read every message
    assert counts["/bot/odom"] == counts["/poses"] > 100
    assert counts["/bot/cmd_vel"] > counts["/bot/odom"]  # after every step, odom at ticks
    assert counts["/bot/scan"] >= 1 and counts["/tf"] == counts["/bot/odom"]
    assert counts["/tf_static"] == 1 and counts["/bot/status"] == counts["/bot/odom"]

    odom = {m.log_time_ns: cdr.decode_odometry(m.data)
            for m in read_recording(record, ["/bot/odom"])}
    cmds = {m.log_time_ns: cdr.decode_twist_stamped(m.data)
            for m in read_recording(record, ["/bot/cmd_vel"])}
    people = {m.log_time_ns: cdr.decode_pose_array(m.data)[2]
              for m in read_recording(record, ["/poses"])}
    assert set(odom) == set(people)

    # never an overlap: robot and people, robot and walls, at every recorded state
    for ns, o in odom.items():
        p = o.position[:2]
        gaps = np.hypot(*(people[ns] - p).T) - (RADIUS + 0.25)
        assert gaps.min() >= -1e-9, (ns, gaps.min())
        assert wall_distance(p) - RADIUS >= -1e-9, (ns, p)

    # odometry follows the applied commands exactly while the robot is far from everyone:
    # from one recorded state to the next, the arcs of the commands applied at each step
    times = sorted(odom)
    step_ns = round(DT * 1e9)
    placed = int(meta["robot_pose_000001"]["log_time_ns"])  # the robot was moved there
    checked = 0
    for a, b in zip(times, times[1:]):
        oa, ob = odom[a], odom[b]
        if a <= placed <= b:
            # the placement lands between these two states (after a's publication: the node
            # publishes a tick's state before it lets a command in), so this is not an arc
            continue
        if np.hypot(*(people[a] - oa.position[:2]).T).min() < 3.0:
            break  # near the people: the crowd yields, but the test of exactness stops here
        pose = np.array([oa.position[0], oa.position[1], oa.yaw])
        for t in range(a + step_ns, b + 1, step_ns):
            c = cmds[t]
            assert c.linear[1] == 0.0  # diff drive
            pose = arc(pose, c.linear[0], c.angular[2], DT)
        assert np.abs(pose[:2] - ob.position[:2]).max() < 1e-9, (b, pose, ob.position)
        assert abs(math.remainder(pose[2] - ob.yaw, 2 * math.pi)) < 1e-9
        checked += 1
    assert checked > 20
    # the placement moved the robot: the first state after it lies within what the robot can
    # drive from (1.5, 2.8) since (at most SPEED m/s)
    first = min(t for t in times if t > placed)
    moved = math.hypot(odom[first].position[0] - 1.5, odom[first].position[1] - 2.8)
    assert moved <= SPEED * (first - placed) * 1e-9 + 1e-9, (moved, first, placed)
    # the commands reached the robot (accelerating, then cruising at full speed), and it
    # pushed its way through: people touched it and moved out of its way
    assert max(c.linear[0] for c in cmds.values()) == SPEED
    touched = [cdr.decode_point_cloud2(m.data) for m in read_recording(record, ["/bot/contacts"])]
    assert sum(len(c.fields["id"]) for c in touched) > 0
    moved = np.hypot(*(people[times[-1]] - np.array(PEOPLE)).T)
    assert moved.max() > 0.1 and (moved == 0.0).any()  # only the people in its way
    assert "robot_pose_000002" not in meta

    # TF in the recording: rosbags reads odom -> base_link, equal to the odometry
    from rosbags.highlevel import AnyReader
    with AnyReader([record]) as bag:
        static = [c for c in bag.connections if c.topic == "/tf_static"]
        (conn, _, raw), = list(bag.messages(connections=static))
        tf = bag.deserialize(raw, conn.msgtype).transforms[0]
        assert (tf.header.frame_id, tf.child_frame_id) == ("map", "odom")
        assert tf.transform.rotation.w == 1.0 and tf.transform.translation.x == 0.0
        dynamic = [c for c in bag.connections if c.topic == "/tf"]
        for conn, log_ns, raw in bag.messages(connections=dynamic):
            tf = bag.deserialize(raw, conn.msgtype).transforms[0]
            assert (tf.header.frame_id, tf.child_frame_id) == ("odom", "base_link")
            o = odom[log_ns]
            assert (tf.transform.translation.x, tf.transform.translation.y) == \
                (o.position[0], o.position[1])

    # the recording replays bit for bit (the applied commands re-applied)
    from sweep_core.analysis import replay
    res = replay.replay(record)
    assert res.identical, replay.format_replay(res)


def test_the_bundled_controller_drives_the_robot_to_its_goal(installed, probe, tmp_path):
    """sweep_robot_controller (a second process) drives the robot over its topics to the
    scene's goal for it (short of the people: it slows for the scan's nearest return), at
    the node's own pace; both on unstamped Twist (enable_stamped_cmd_vel: false), the other
    test having driven the node with TwistStamped."""
    goal = [5.5, 4.5]
    scene = dict(SCENE, robots=[dict(SCENE["robots"][0], goal=goal, goal_radius=0.3)])
    scene_path = tmp_path / "goal.yaml"
    scene_path.write_text(yaml.safe_dump(scene))
    node = Running(installed, tmp_path, {
        "scene": str(scene_path), "dt": DT, "rate_hz": 50.0, "steps_per_tick": 2,
        "publish_markers": False, "enable_stamped_cmd_vel": False})
    exe, env = installed
    controller = None
    try:  # the node is stopped whatever happens from here, the controller's start included
        controller = Running((exe.with_name("sweep_robot_controller"), env), tmp_path,
                             {"scene": str(scene_path), "robot": "bot",
                              "enable_stamped_cmd_vel": False}, name="controller")
        probe.connect(node)

        def arrived():
            p = probe.odom[-1].pose.pose.position if probe.odom else None
            return p is not None and math.hypot(p.x - goal[0], p.y - goal[1]) <= 0.3
        probe.spin_until(arrived, WAIT_S, "the robot at its goal", controller)
        assert node.alive()
        probe.spin_until(lambda: diag_value(probe, "robot_commands_received") not in
                         (None, "0"), WAIT_S, "diagnostics counting the commands", node)
        assert diag_value(probe, "robot_commands_refused") == "0"
    finally:
        if controller is not None:
            controller.stop(signal.SIGINT)
        code = node.stop(signal.SIGINT)
    assert controller is not None
    assert code == 0, node.log
    assert "Traceback" not in node.log + controller.log, node.log + controller.log
