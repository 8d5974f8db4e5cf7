"""Robots' commands in sweep_node over DDS: a command is applied for ``cmd_vel_timeout`` s of
simulated time after it arrives and the robot then stops (the parameter changed live too); two
robots in one scene each follow their own ``NAME/cmd_vel``, publish their own ``NAME/odom``,
and have frames prefixed with their names.

Every wait is on an event (a message, a reply) with a generous deadline; what is checked is
counted in simulated time, in the node's recording, so it does not depend on how fast the node
steps.
"""
from __future__ import annotations

import signal

import numpy as np
import pytest
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from robot_node import editable_installation, robot_probe, stamp_ns, start
from test_node import WAIT_S, diag_value, read_standard

from sweep_core.io import cdr
from sweep_core.io.recording import read_recording

DT = 0.01
#: a 10 x 6 m room, the robot in its west half facing east, two people standing far east;
#: accelerations large enough that every command is applied unclipped in one step
SCENE = {
    "name": "robot_commands",
    "agents": {"positions": [[8.0, 1.0], [8.0, 5.0]], "radius": 0.25},
    "walls": [{"kind": "polyline", "points": [[0, 0], [10, 0], [10, 6], [0, 6], [0, 0]]}],
    "noise": {"sigma": 0.0},
    "robots": [{
        "name": "bot", "radius": 0.3, "pose": [2.0, 3.0, 0.0],
        "kinematics": {"type": "diff_drive", "max_speed": 1.0, "max_angular_speed": 1.5,
                       "max_acceleration": 200.0, "max_angular_acceleration": 200.0},
        "weight": "inf"}],
}


@pytest.fixture(scope="module")
def installed():
    return editable_installation()


def nonzero_runs(commands: list[tuple[int, np.ndarray]]) -> list[list[tuple[int, np.ndarray]]]:
    """The maximal runs of consecutive recorded commands that are not zero."""
    runs: list[list[tuple[int, np.ndarray]]] = []
    previous_zero = True
    for ns, c in commands:
        if c.any():
            if previous_zero:
                runs.append([])
            runs[-1].append((ns, c))
        previous_zero = not c.any()
    return runs


def test_a_robot_stops_once_its_command_is_older_than_the_timeout(installed, tmp_path):
    """One command, then silence: the robot drives for cmd_vel_timeout s of simulated time
    (0.255 s: not a whole number of steps, so 25 or 26 steps whatever the step the command
    lands in) and then stands still; after a live change to 0.505 s, the next single command
    drives it for 50 or 51 steps. Without the timeout the first command would drive it on
    until the node stops."""
    timeouts = (0.255, 0.505)
    speeds = (0.8, 0.4)
    record = tmp_path / "commands.mcap"
    with robot_probe() as probe:
        node = start(installed, tmp_path, probe, SCENE, {
            "dt": DT, "rate_hz": 50.0, "steps_per_tick": 2, "record": str(record),
            "record_flush_interval_s": 0.2, "publish_markers": False,
            "cmd_vel_timeout": timeouts[0]})
        try:
            for k, (timeout, v) in enumerate(zip(timeouts, speeds)):
                if k:
                    request = SetParameters.Request(parameters=[
                        Parameter("cmd_vel_timeout", value=timeout).to_parameter_msg()])
                    res = probe.call(SetParameters, "/sweep_node/set_parameters", request, node)
                    assert res.results[0].successful, res.results[0].reason
                seen = len(probe.odom)
                probe.drive(v, 0.0)  # once, and never again
                moving = probe.spin_until(
                    lambda s=seen, v=v: next((o for o in probe.odom[s:]
                                              if o.twist.twist.linear.x == v), None),
                    WAIT_S, f"the robot driving at {v} m/s", node)
                # a second of simulated time past the timeout
                until = stamp_ns(moving) + round((timeout + 1.0) * 1e9)
                probe.spin_until(lambda u=until: stamp_ns(probe.odom[-1]) >= u, WAIT_S,
                                 f"odometry {timeout + 1.0:g} s after the robot started", node)
                last = probe.odom[-1].twist.twist
                assert (last.linear.x, last.linear.y, last.angular.z) == (0.0, 0.0, 0.0), \
                    f"the robot still moves {timeout + 1.0:g} s after its only command: {last}"
        finally:
            code = node.stop(signal.SIGINT)
    assert code == 0, node.log
    assert "Traceback" not in node.log, node.log

    read_standard(record)
    commands = [(m.log_time_ns, np.concatenate([t.linear, t.angular]))
                for m in read_recording(record, ["/bot/cmd_vel"])
                for t in [cdr.decode_twist_stamped(m.data)]]
    odom = {m.log_time_ns: cdr.decode_odometry(m.data)
            for m in read_recording(record, ["/bot/odom"])}
    # the command applied at every step: two runs of the commanded velocity, zero otherwise
    steps = [ns for ns, _ in commands]
    assert all(b - a == round(DT * 1e9) for a, b in zip(steps, steps[1:]))
    runs = nonzero_runs(commands)
    assert len(runs) == 2, [(len(r), r[0][1]) for r in runs]
    x = 2.0
    for run, timeout, v in zip(runs, timeouts, speeds):
        assert all(list(c) == [v, 0.0, 0.0, 0.0, 0.0, 0.0] for _, c in run), run
        assert abs(len(run) * DT - timeout) < DT, (len(run), timeout)
        # the robot drove exactly that far, and no farther, up to the next command
        x += v * DT * len(run)
        end = run[-1][0]
        after = [o for ns, o in odom.items() if ns > end]
        after = after[:next((i for i, o in enumerate(after) if o.linear[0] != 0.0), len(after))]
        assert len(after) > 10
        for o in after:
            assert abs(o.position[0] - x) < 1e-9 and o.position[1] == 3.0, (o.position, x)


#: two robots in the room: alpha (diff drive) in the south half, beta (holonomic) in the north
TWO = dict(SCENE, name="two_robots", robots=[
    dict(SCENE["robots"][0], name="alpha", pose=[2.0, 1.5, 0.0]),
    dict(SCENE["robots"][0], name="beta", pose=[2.0, 4.5, 0.0],
         kinematics=dict(SCENE["robots"][0]["kinematics"], type="holonomic"))])


def test_two_robots_have_their_own_topics_and_frames(installed, tmp_path):
    """Each robot follows its own NAME/cmd_vel only, publishes its own NAME/odom, and its
    frames are prefixed with its name (NAME/odom -> NAME/base_link, one tree per robot under
    map): a command stamped with the unprefixed base_link is refused."""
    timeout = 0.255
    record = tmp_path / "two.mcap"
    with robot_probe(("alpha", "beta")) as probe:
        node = start(installed, tmp_path, probe, TWO, {
            "dt": DT, "rate_hz": 50.0, "steps_per_tick": 2, "record": str(record),
            "record_flush_interval_s": 0.2, "publish_markers": False,
            "cmd_vel_timeout": timeout})
        try:
            for name in ("alpha", "beta"):
                o = probe.odoms[name][-1]
                assert (o.header.frame_id, o.child_frame_id) == (f"{name}/odom",
                                                                  f"{name}/base_link")
            # base_link is no robot's frame here: refused, and counted
            probe.drive(0.5, 0.0, "alpha", frame="base_link")
            probe.spin_until(lambda: diag_value(probe, "robot_commands_refused") == "1",
                             WAIT_S, "the refusal counted in diagnostics", node)
            # one command each, in turn: alpha east at 0.5 m/s, then beta north at 0.3 m/s
            for name, vx, vy, frame in (("alpha", 0.5, 0.0, "alpha/base_link"),
                                        ("beta", 0.0, 0.3, "")):
                odom = probe.odoms[name]
                seen = len(odom)
                probe.drive(vx, 0.0, name, frame=frame, vy=vy)
                moving = probe.spin_until(
                    lambda o=odom, s=seen, vx=vx, vy=vy: next(
                        (m for m in o[s:] if (m.twist.twist.linear.x, m.twist.twist.linear.y)
                         == (vx, vy)), None), WAIT_S, f"{name} moving", node)
                until = stamp_ns(moving) + round((timeout + 0.5) * 1e9)
                probe.spin_until(lambda o=odom, u=until: stamp_ns(o[-1]) >= u, WAIT_S,
                                 f"{name}'s odometry {timeout + 0.5:g} s later", node)
        finally:
            code = node.stop(signal.SIGINT)
    assert code == 0, node.log
    assert "Traceback" not in node.log, node.log
    assert "command refused" in node.log and "'alpha/base_link'" in node.log, node.log

    counts, _ = read_standard(record)
    assert counts["/alpha/odom"] == counts["/beta/odom"] == counts["/tf"] == counts["/poses"]
    assert counts["/tf_static"] == 1
    steps = {}
    for name, v, start_xy in (("alpha", [0.5, 0.0], (2.0, 1.5)),
                              ("beta", [0.0, 0.3], (2.0, 4.5))):
        commands = [(m.log_time_ns, np.concatenate([t.linear, t.angular]))
                    for m in read_recording(record, [f"/{name}/cmd_vel"])
                    for t in [cdr.decode_twist_stamped(m.data)]]
        assert {cdr.decode_twist_stamped(m.data).frame_id
                for m in read_recording(record, [f"/{name}/cmd_vel"])} == {f"{name}/base_link"}
        run, = nonzero_runs(commands)  # its own command only, applied for the timeout
        assert all(list(c) == [*v, 0.0, 0.0, 0.0, 0.0] for _, c in run), run
        assert abs(len(run) * DT - timeout) < DT, (name, len(run))
        steps[name] = (run[0][0], run[-1][0])
        last = cdr.decode_odometry(list(read_recording(record, [f"/{name}/odom"]))[-1].data)
        expected = np.array(start_xy) + np.array(v) * DT * len(run)
        assert np.abs(last.position[:2] - expected).max() < 1e-9, (name, last.position)
        assert (last.frame_id, last.child_frame_id) == (f"{name}/odom", f"{name}/base_link")
    assert steps["alpha"][1] < steps["beta"][0]  # one after the other, as sent
    # /tf: both robots' odom -> base_link in every message; /tf_static: map -> each odom
    static, = [cdr.decode_tf_message(m.data) for m in read_recording(record, ["/tf_static"])]
    assert sorted((t.frame_id, t.child_frame_id) for t in static) == [
        ("map", "alpha/odom"), ("map", "beta/odom")]
    for m in read_recording(record, ["/tf"]):
        assert sorted((t.frame_id, t.child_frame_id) for t in cdr.decode_tf_message(m.data)) \
            == [("alpha/odom", "alpha/base_link"), ("beta/odom", "beta/base_link")]
