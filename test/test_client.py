"""sweep_client and the node's verdicts on commands (command_result), end to end; the node's
start checks (use_sim_time, a second node of the same name); the client's argument checks.

The node runs from the installed package as in test_node.py (its fixtures are reused); every
wait is on an event (a message, a process exit) with a generous deadline.
"""
from __future__ import annotations

import re
import signal
import subprocess
import time

import pytest
import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped, Twist, Vector3
from std_srvs.srv import SetBool
from test_node import (  # noqa: F401 - installed and probe are fixtures
    DISCOVERY_S,
    DT,
    SCENE,
    Running,
    installed,
    probe,
    read_standard,
)

from sweep_ros import client as sweep_client
from sweep_ros import results


def client_runner(installed, tmp_path):  # noqa: F811 - the fixture's value
    """``python -m sweep_ros.client --timeout 180 ARGS`` with the installed package's
    interpreter."""
    exe, env = installed
    python = exe.read_text().splitlines()[0].removeprefix("#!").strip()

    def run(*args: str) -> subprocess.CompletedProcess:
        # a generous timeout: a first goal builds its field (and may compile the geodesic
        # kernels) on a machine whose two cores the rest of the suite keeps busy
        return subprocess.run([python, "-m", "sweep_ros.client", "--timeout", "180", *args],
                              env=env,
                              cwd=tmp_path, capture_output=True, text=True, timeout=240)
    return run


#: how long a node may take to start (its imports load numba's caches; a loaded 2-core machine)
START_S = 180.0


def connect(probe, node: Running) -> None:  # noqa: F811
    """Waits for the node's start line in its log (generously), then for discovery both ways
    and its first state."""
    end = time.monotonic() + START_S
    while "] [sweep_node]: scene '" not in node.log:
        if not node.alive():
            pytest.fail(f"sweep_node exited at start:\n{node.log}")
        if time.monotonic() > end:
            pytest.fail(f"sweep_node not started after {START_S:g} s:\n{node.log}")
        time.sleep(0.1)
    probe.connect(node)


def verdict_probe(probe) -> list[dict[str, str]]:  # noqa: F811
    """What a `ros2 topic echo /command_result` user sees, parsed."""
    got: list[dict[str, str]] = []

    def keep(msg: DiagnosticArray) -> None:
        parsed = results.parse(msg)
        if parsed is not None:
            got.append(parsed)
    probe.node.create_subscription(DiagnosticArray, "/command_result", keep, results.QOS)
    return got


def gid_of(probe, pub) -> str:  # noqa: F811
    """The DDS gid (hex) of one of the probe's publishers, as verdicts name it."""
    me = (probe.node.get_namespace(), probe.node.get_name())
    for e in probe.node.get_publishers_info_by_topic(pub.topic_name):
        if (e.node_namespace, e.node_name) == me:
            return results.gid_hex(e.endpoint_gid)
    raise AssertionError(f"the probe's publisher of {pub.topic_name} is not in the graph")


def test_client_reports_refusals_and_the_step_a_command_applies_from(installed, probe,  # noqa: F811
                                                                       tmp_path):
    """A goal in a wall, an over-speed cmd-vel and a goal for a group the scene does not have
    are refused with the node's reason (exit 1); an applied goal names the step it applies
    from, which is the step the recording's command record gives."""
    scene_path = tmp_path / "scene.yaml"
    scene_path.write_text(yaml.safe_dump(SCENE))
    record = tmp_path / "verdicts.mcap"
    node = Running(installed, tmp_path, {
        "scene": str(scene_path), "dt": DT, "rate_hz": 50.0, "steps_per_tick": 2,
        "record": str(record), "max_speed": 5.0, "publish_markers": False,
        "record_flush_interval_s": 0.2})
    client = client_runner(installed, tmp_path)
    try:
        connect(probe, node)
        done = client("goal", "0", "-20")  # on the wall segment from (-20, -20) to (20, -20)
        assert done.returncode == 1, done
        assert done.stdout.startswith(
            "refused: /goal: the goal refused: [0, -20] lies in or on walls[0]"), done
        assert "(fix: " in done.stdout, done
        done = client("cmd-vel", "20", "0")
        assert done.returncode == 1, done
        assert done.stdout.strip() == (
            "refused: /crowd/cmd_vel: speed 20 m/s exceeds max_speed 5 m/s (fix: send a slower "
            "field or raise the max_speed parameter)"), done
        done = client("goal", "14", "5", "--group", "left")
        assert done.returncode == 1, done
        assert done.stdout.strip() == (
            "refused: /goal/left: no group 'left': the scene has no agents.groups (fix: "
            "publish on /goal for every agent)"), done
        done = client("goal", "2", "15")
        assert done.returncode == 0, (done, node.log)
        applied = re.fullmatch(r"applied: goal \(2, 15\) m on /goal from step (\d+) "
                               r"\(t = (\S+) s\)", done.stdout.strip())
        assert applied is not None, done
        step = int(applied.group(1))
        assert float(applied.group(2)) == pytest.approx(step * DT)
    finally:
        code = node.stop(signal.SIGTERM)
    assert code == 0, node.log
    counts, meta = read_standard(record)  # rosbags reads command_result too
    commands = [meta[k] for k in sorted(meta) if k.startswith("command_")]
    assert len(commands) == 1 and commands[0]["topic"] == "/goal"
    assert commands[0]["step"] == str(step)
    assert counts["/command_result"] == 4  # three refused, one applied


def test_verdicts_on_command_result_for_topic_publishers(installed, probe, tmp_path):  # noqa: F811
    """A plain publisher (as `ros2 topic pub`) reads its commands' verdicts on the latched
    command_result topic, named by its publisher gid and sequence number: refused with the
    reason, applied with the step; while paused a command is accepted, a newer one supersedes
    it, and resume applies the newest."""
    scene_path = tmp_path / "scene.yaml"
    scene_path.write_text(yaml.safe_dump(SCENE))
    node = Running(installed, tmp_path, {
        "scene": str(scene_path), "dt": DT, "rate_hz": 50.0, "steps_per_tick": 2,
        "max_speed": 5.0, "publish_markers": False})
    verdicts = verdict_probe(probe)
    try:
        connect(probe, node)
        gid = gid_of(probe, probe.cmd_vel)

        def on(seq: int, final: bool = True):
            def find():
                for v in verdicts:
                    if (v["publisher_gid"] == gid and v["sequence"] == str(seq)
                            and (v["verdict"] in results.FINAL) == final):
                        return v
                return None
            return find
        probe.cmd_vel.publish(Twist(linear=Vector3(x=9.0)))
        v = probe.spin_until(on(1), DISCOVERY_S, "the verdict on cmd_vel 1", node)
        assert v["verdict"] == "refused" and v["topic"] == "/crowd/cmd_vel"
        assert v["message"].startswith("/crowd/cmd_vel: speed 9 m/s exceeds max_speed 5 m/s"), v
        assert v["command"] == f"{gid}:1" and v["node"] == "/sweep_node"
        probe.cmd_vel.publish(Twist(linear=Vector3(x=0.5)))
        v = probe.spin_until(on(2), DISCOVERY_S, "the verdict on cmd_vel 2", node)
        assert v["verdict"] == "applied" and int(v["step"]) >= 0, v
        assert v["message"] == f"applied from step {v['step']} (t = {float(v['t_s']):g} s)"

        # paused: accepted, then superseded by a newer command; resume applies the newest
        assert probe.call(SetBool, "/pause", SetBool.Request(data=True), node).success
        goal_gid = gid_of(probe, probe.goal)
        for k, x in enumerate((2.0, 3.0)):
            g = PointStamped()
            g.header.stamp.sec, g.header.stamp.nanosec = 7, 100 + k  # echoed as stamp_ns
            g.point.x, g.point.y = x, 15.0
            probe.goal.publish(g)

        def on_goal(seq: int, verdict: str):
            return lambda: next((v for v in verdicts if v["publisher_gid"] == goal_gid
                                 and v["sequence"] == str(seq) and v["verdict"] == verdict),
                                None)
        first = probe.spin_until(on_goal(1, "accepted"), DISCOVERY_S, "goal 1 accepted", node)
        assert first["stamp_ns"] == str(7 * 10**9 + 100) and first["paused"] == "true"
        first = probe.spin_until(on_goal(1, "superseded"), DISCOVERY_S, "goal 1 superseded",
                                 node)
        assert first["message"] == "superseded by a newer command on /goal before a step used it"
        probe.spin_until(on_goal(2, "accepted"), DISCOVERY_S, "goal 2 accepted", node)
        probe.cmd_vel.publish(Twist(linear=Vector3(x=-0.5)))  # a whole command: replaces both
        second = probe.spin_until(on_goal(2, "superseded"), DISCOVERY_S, "goal 2 superseded",
                                  node)
        assert second["message"].startswith("superseded by a newer command on /crowd/cmd_vel")
        probe.spin_until(on(3, final=False), DISCOVERY_S, "cmd_vel 3 accepted", node)
        assert probe.call(SetBool, "/pause", SetBool.Request(data=False), node).success
        v = probe.spin_until(on(3), DISCOVERY_S, "cmd_vel 3 applied", node)
        assert v["verdict"] == "applied", v
    finally:
        code = node.stop(signal.SIGTERM)
    assert code == 0, node.log


def test_use_sim_time_keeps_diagnostics(installed, probe, tmp_path):  # noqa: F811
    """use_sim_time: true (no clock published): diagnostics go on, and status answers."""
    scene_path = tmp_path / "scene.yaml"
    scene_path.write_text(yaml.safe_dump(SCENE))
    node = Running(installed, tmp_path, {
        "scene": str(scene_path), "dt": DT, "rate_hz": 50.0, "use_sim_time": True,
        "publish_markers": False})
    try:
        connect(probe, node)
        probe.spin_until(lambda: len(probe.diagnostics) >= 2, DISCOVERY_S + 20.0,
                         "two diagnostics messages", node)
        done = client_runner(installed, tmp_path)("status")
        assert done.returncode == 0, done
        assert done.stdout.startswith("sweep_node: simulation: "), done
    finally:
        code = node.stop(signal.SIGTERM)
    assert code == 0, node.log


def test_second_node_of_the_same_name(installed, probe, tmp_path, capsys):  # noqa: F811
    """A second /sweep_node refuses to start (one line, exit 2). One started without the
    check runs beside the first: its diagnostics say so, and the client reports two nodes
    answering a service (exit 1)."""
    scene_path = tmp_path / "scene.yaml"
    scene_path.write_text(yaml.safe_dump(SCENE))
    base = {"scene": str(scene_path), "dt": DT, "rate_hz": 50.0, "publish_markers": False}
    first = Running(installed, tmp_path, base, name="first")
    second = third = None
    rclpy.init()
    client = None
    try:
        connect(probe, first)
        # the check watches the graph for up to 60 s and stops as soon as it sees the first
        second = Running(installed, tmp_path, {**base, "name_check_s": 60.0}, name="second")
        assert second.proc.wait(timeout=START_S + 60.0) == 2, second.log
        assert "sweep_node: error: another node named /sweep_node is running on this ROS " \
               "domain" in second.log and "Traceback" not in second.log, second.log
        third = Running(installed, tmp_path, {**base, "name_check_s": 0.0}, name="third")
        probe.spin_until(lambda: any(
            d.status[0].message.startswith("2 nodes named /sweep_node on this ROS domain")
            for d in probe.diagnostics), START_S, "the duplicate in diagnostics", first)
        client = sweep_client.Client("", 60.0)
        probe.spin_until(lambda: client.node.count_services("/pause") == 2
                         and client.commanders("/crowd/cmd_vel", "/command_result") == 2,
                         START_S, "both nodes seen by the client", third)
        args = sweep_client.build_parser().parse_args(["pause"])
        assert sweep_client.run(args, client) == 1
        err = capsys.readouterr().err
        assert "warning: 2 nodes answer pause" in err, err
    finally:
        if client is not None:
            client.node.destroy_node()
        rclpy.try_shutdown()
        codes = [n.stop(signal.SIGTERM) for n in (first, second, third) if n is not None]
    assert codes[0] == 0, first.log


def test_a_later_node_of_the_same_name_stops_however_slow_discovery_is(  # noqa: F811
        installed, probe, tmp_path):  # noqa: F811
    """A second /sweep_node whose start-up watch ends before discovery shows it the first
    (a window of 10 ms here; discovery took 0.3-2.4 s on a loaded machine, longer than the
    default 1 s window in 4 of 6 tries) still stops, in one line (exit 2), once discovery joins
    them: each node announces its start on a latched topic of its name, and the later one
    stops. The first runs on and logs the later one. Before: both ran, and pause was answered
    by either."""
    scene_path = tmp_path / "scene.yaml"
    scene_path.write_text(yaml.safe_dump(SCENE))
    base = {"scene": str(scene_path), "dt": DT, "rate_hz": 50.0, "publish_markers": False}
    first = Running(installed, tmp_path, base, name="first")
    second = None
    try:
        connect(probe, first)
        second = Running(installed, tmp_path, {**base, "name_check_s": 0.01}, name="second")
        assert second.proc.wait(timeout=START_S + 60.0) == 2, second.log
        errors = [ln for ln in second.log.splitlines() if ln.startswith("sweep_node: error:")]
        assert len(errors) == 1 and "another node named /sweep_node is running on this ROS " \
            "domain" in errors[0] and "Traceback" not in second.log, second.log
        assert first.alive(), first.log
    finally:
        codes = [n.stop(signal.SIGTERM) for n in (first, second) if n is not None]
    assert codes[0] == 0, first.log


def test_of_two_nodes_of_one_name_started_together_exactly_one_runs(  # noqa: F811
        installed, tmp_path):  # noqa: F811
    """Two /sweep_node started together see each other in the graph at once: each waits for
    the other's start announcement, and the later of the two stops (one line, exit 2) while
    the earlier runs on. Before: each refused on seeing the other, and neither ran."""
    scene_path = tmp_path / "scene.yaml"
    scene_path.write_text(yaml.safe_dump(SCENE))
    base = {"scene": str(scene_path), "dt": DT, "rate_hz": 50.0, "publish_markers": False,
            "name_check_s": 5.0}
    nodes = [Running(installed, tmp_path, base, name=name) for name in ("a", "b")]
    try:
        # one of them stops; the other must still run once the stopped one is gone
        end = time.monotonic() + START_S + 60.0
        while time.monotonic() < end and all(n.proc.poll() is None for n in nodes):
            time.sleep(0.2)
        stopped = [n for n in nodes if n.proc.poll() is not None]
        assert len(stopped) == 1, [n.log for n in nodes]
        assert stopped[0].proc.returncode == 2, stopped[0].log
        errors = [ln for ln in stopped[0].log.splitlines()
                  if ln.startswith("sweep_node: error:")]
        assert len(errors) == 1 and "another node named /sweep_node is running" in errors[0], \
            stopped[0].log
        running = next(n for n in nodes if n is not stopped[0])
        time.sleep(2.0)  # the running one is still running a little later
        assert running.alive(), running.log
    finally:
        codes = [n.stop(signal.SIGTERM) for n in nodes]
    assert sorted(codes) == [0, 2], (codes, [n.log for n in nodes])


@pytest.mark.parametrize("argv, message", [
    (["--namespace", "bad//ns", "pause"],
     "argument --namespace: --namespace = 'bad//ns' is not a ROS namespace: namespace must "
     "not contain repeated '/' (fix: give the node's namespace, e.g. /crowd)"),
    (["--namespace", "/9lives", "pause"], "--namespace = '/9lives' is not a ROS namespace"),
    (["--timeout", "-1", "pause"],
     "argument --timeout: --timeout = '-1' is not > 0 (fix: give the seconds to wait, e.g. 10)"),
    (["--timeout", "0", "status"], "--timeout = '0' is not > 0"),
    (["--timeout", "nan", "status"], "--timeout = 'nan' is not a finite number"),
    (["--timeout", "inf", "status"], "--timeout = 'inf' is not a finite number"),
])
def test_client_refuses_bad_options(argv, message, capsys):
    """Bad --namespace and --timeout values: one error line, exit 2, before any DDS."""
    with pytest.raises(SystemExit) as exit_:
        sweep_client.build_parser().parse_args(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert message in err.strip().splitlines()[-1], err
    assert "Traceback" not in err


def test_command_id_and_parse_round_trip():
    """A verdict names the command by the sample info's gid and sequence, and the header
    stamp when the message has one."""
    info = {"publication_sequence_number": 3,
            "publisher_gid": {"implementation_identifier": "x", "data": bytes(range(16))}}
    g = PointStamped()
    g.header.stamp.sec, g.header.stamp.nanosec = 2, 5
    ident = results.command_id(info, g)
    assert ident == results.CommandId(bytes(range(16)).hex(), 3, 2 * 10**9 + 5)
    assert results.command_id(None, Twist()) == results.CommandId() and \
        results.CommandId().text == "unknown"
    sent: list[bytes] = []
    recorded: list[tuple] = []

    class Pub:
        topic_name = "/command_result"

        def publish(self, data: bytes) -> None:
            sent.append(data)
    out = results.CommandResults(Pub(), "/sweep_node", lambda *a: recorded.append(a))
    out.verdict("refused", "/goal", ident, "/goal: no", 4, 0.04, 40_000_000, 123, paused=False)
    from rclpy.serialization import deserialize_message

    msg = deserialize_message(sent[0], DiagnosticArray)
    v = results.parse(msg)
    assert v is not None and v["verdict"] == "refused" and v["message"] == "/goal: no"
    assert (v["command"], v["step"], v["stamp_ns"], v["paused"]) == (
        ident.text, "4", str(2 * 10**9 + 5), "false")
    assert msg.header.stamp.nanosec == 40_000_000 and recorded == [("/command_result", 123,
                                                                    sent[0])]


def test_client_names_a_subscriber_of_another_type():
    """A topic taken by a node of another message type: the client's error says so instead of
    only blaming the domain (no sweep_node runs here)."""
    from rclpy.node import Node
    from std_msgs.msg import String

    context = rclpy.Context()
    rclpy.init(context=context)
    other = Node("string_taker", context=context)
    other.create_subscription(String, "/crowd/cmd_vel", lambda m: None, 10)
    rclpy.init()
    client = sweep_client.Client("", 1.0)
    try:
        end = time.monotonic() + DISCOVERY_S + 20.0
        while (not client.node.get_subscriptions_info_by_topic("/crowd/cmd_vel")
               and time.monotonic() < end):
            time.sleep(0.02)
        with pytest.raises(sweep_client.ClientError) as err:
            client.command(Twist, "crowd/cmd_vel", Twist())
        assert str(err.value).endswith(
            "; /crowd/cmd_vel is subscribed to as std_msgs/msg/String (not geometry_msgs/msg/Twist) "
            "by /string_taker"), err.value
    finally:
        client.node.destroy_node()
        rclpy.try_shutdown()
        other.destroy_node()
        rclpy.shutdown(context=context)


def test_status_is_the_node_now_consistent_with_pause_step_and_reset(installed, probe,  # noqa: F811
                                                                      tmp_path):
    """status is answered by the node between two steps: right after pause it says paused at
    the step pause named, after step the next step, after reset step 0; step while running
    names the client's pause command."""
    scene_path = tmp_path / "scene.yaml"
    scene_path.write_text(yaml.safe_dump(SCENE))
    node = Running(installed, tmp_path, {
        "scene": str(scene_path), "dt": DT, "rate_hz": 50.0, "publish_markers": False})
    client = client_runner(installed, tmp_path)

    def status() -> dict[str, str]:
        done = client("status")
        assert done.returncode == 0, done
        head, *rest = done.stdout.strip().splitlines()
        values = dict(line.strip().split(": ", 1) for line in rest)
        values["head"] = head
        return values
    try:
        connect(probe, node)
        done = client("step")
        assert done.returncode == 1, done
        assert "sweep_client pause" in done.stdout, done
        done = client("pause")
        assert done.returncode == 0, done
        paused_at = int(re.match(r"paused at step (\d+)", done.stdout).group(1))
        now = status()
        # the level is OK unless the machine's load made timer overruns (WARN, said first)
        assert re.fullmatch(r"sweep_node: simulation: (OK paused|WARN .+)", now["head"]), now
        assert now["paused"] == "true" and int(now["steps"]) == paused_at, (now, paused_at)
        assert client("step", "2").returncode == 0
        now = status()
        assert int(now["steps"]) == paused_at + 2, (now, paused_at)
        assert client("reset").returncode == 0
        now = status()
        assert int(now["steps"]) == 0 and now["paused"] == "true", now
        assert client("resume").returncode == 0
        now = status()
        assert now["paused"] == "false", now
        assert re.fullmatch(r"sweep_node: simulation: (OK running|WARN .+)", now["head"]), now
    finally:
        code = node.stop(signal.SIGTERM)
    assert code == 0, node.log
