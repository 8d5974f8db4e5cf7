"""sweep_node end to end: the installed executable, real rclpy, DDS on this machine only.

The package is built once per module into a temporary prefix with colcon (the file ``ros2 run``
execs is ``<install>/sweep_ros/lib/sweep_ros/sweep_node``); each test starts that file as a
subprocess with a params file, talks to it from this process over DDS, and reads its MCAP.
"""
from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped, PoseArray, Twist, Vector3
from rcl_interfaces.srv import SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from scenes import hex_jam
from sensor_msgs.msg import PointCloud2, PointField
from std_srvs.srv import SetBool, Trigger

from sweep_core.io import cdr, topics
from sweep_core.io.recording import read_recording, scan_recording

REPO = Path(__file__).resolve().parents[1]
# deadlines of waits for an event (discovery, a state, a reply, motion): a waiting test
# returns as soon as the event comes, so they only bound a failure; generous for a loaded
# 2-core machine. No test's verdict depends on how fast the node steps.
DISCOVERY_S = 180.0
WAIT_S = 120.0
DT = 0.01
# 20 agents in open space (a far wall and obstacle only for the walls topic); a little noise
POSITIONS = [[1.0 * (k % 5), 1.0 * (k // 5)] for k in range(20)]
SCENE = {
    "name": "test_open_20",
    "agents": {"positions": POSITIONS, "radius": 0.2, "speed": 1.3},
    "walls": [{"kind": "segment", "a": [-20.0, -20.0], "b": [20.0, -20.0]}],
    "obstacles": [{"kind": "circle", "center": [-10.0, 10.0], "radius": 0.5}],
    "noise": {"sigma": 0.02},
}


def ros_env() -> dict[str, str]:
    """The DDS isolation of this test process, passed on explicitly."""
    return {"ROS_AUTOMATIC_DISCOVERY_RANGE": os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"],
            "ROS_DOMAIN_ID": os.environ["ROS_DOMAIN_ID"]}


# ---------------------------------------------------------------------------------------------
# the installed executable
# ---------------------------------------------------------------------------------------------


def build_prefix(base: Path, use_colcon: bool) -> Path:
    """Builds and installs the package under base; returns the package's install prefix.

    With colcon: ``colcon build --paths REPO`` (the repository root is the package; --paths
    keeps colcon from crawling a .venv inside it). Without: the setuptools command colcon's
    ament_python build runs, which installs to the same layout (setup.cfg puts the scripts in
    lib/sweep_ros)."""
    build, install = base / "build", base / "install"
    build.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, **ros_env())
    if use_colcon:
        colcon = shutil.which("colcon") or str(Path(sys.executable).with_name("colcon"))
        cmd = [colcon, "--log-base", str(base / "log"), "build", "--paths", str(REPO),
               "--build-base", str(build), "--install-base", str(install)]
        prefix, cwd = install / "sweep_ros", base
    else:
        prefix, cwd = install, REPO
        cmd = [sys.executable, "setup.py", "-q", "egg_info", "--egg-base", str(build), "build",
               "--build-base", str(build / "build"), "install", "--prefix", str(prefix),
               "--record", str(build / "install.log"), "--single-version-externally-managed",
               "install_data"]
    done = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    return prefix


def has_colcon() -> bool:
    return bool(shutil.which("colcon")) or Path(sys.executable).with_name("colcon").exists()


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """Builds the package into a fresh prefix; returns (executable, environment)."""
    start = time.monotonic()
    use_colcon = has_colcon() and os.environ.get("SWEEP_TEST_BUILD") != "setuptools"
    prefix = build_prefix(tmp_path_factory.mktemp("install"), use_colcon)
    print(f"built with {'colcon' if use_colcon else 'setup.py'} in "
          f"{time.monotonic() - start:.1f} s")
    exe = prefix / "lib" / "sweep_ros" / "sweep_node"
    assert exe.is_file() and os.access(exe, os.X_OK), f"{exe} missing"
    assert (prefix / "share" / "sweep_ros" / "config" / "sweep_node.yaml").is_file()
    assert (prefix / "share" / "sweep_ros" / "launch" / "sweep.launch.py").is_file()
    assert (prefix / "share" / "ament_index" / "resource_index" / "packages" /
            "sweep_ros").is_file()
    site = prefix / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}" / \
        "site-packages"
    # what sourcing the underlay (this venv) and then install/setup.bash does
    env = dict(os.environ, **ros_env(), PYTHONPATH=str(site),
               AMENT_PREFIX_PATH=os.pathsep.join([str(prefix), sys.prefix]))
    # the executable's interpreter imports the installed copy, not the source tree
    shebang = exe.read_text().splitlines()[0].removeprefix("#!").strip()
    where = subprocess.run([shebang, "-c", "import sweep_ros.node as n; print(n.__file__)"],
                           env=env, capture_output=True, text=True, timeout=60, cwd=site)
    assert where.stdout.strip().startswith(str(site)), where.stdout + where.stderr
    # numba compiles the engine's kernels into the fresh prefix's caches at the first steps
    # (tens of seconds on a loaded machine): do it once here, not inside a test's timeout
    warm = subprocess.run([shebang, "-c", WARM_UP], env=env, capture_output=True, text=True,
                          timeout=600, cwd=site)
    assert warm.returncode == 0, warm.stdout + warm.stderr
    print(f"built and warmed up in {time.monotonic() - start:.1f} s")
    return exe, env


#: compiles every kernel of the installed copy into its cache, as a node does before ready
WARM_UP = "from sweep_core.numerics import kernels; kernels.warm_up()"


class Running:
    """A sweep_node subprocess; its output goes to a log file read on failure."""

    def __init__(self, installed, tmp_path: Path, overrides: dict, name: str = "run",
                 extra_env: dict[str, str] | None = None):
        exe, env = installed
        env = dict(env, **(extra_env or {}))
        self.params = tmp_path / f"{name}.yaml"
        self.params.write_text(yaml.safe_dump({"/**": {"ros__parameters": overrides}}))
        self.log_path = tmp_path / f"{name}.log"
        self._log = open(self.log_path, "w")
        self.proc = subprocess.Popen([str(exe), "--ros-args", "--params-file", str(self.params)],
                                     env=env, cwd=tmp_path, stdout=self._log,
                                     stderr=subprocess.STDOUT)

    @property
    def log(self) -> str:
        if not self._log.closed:
            self._log.flush()
        return self.log_path.read_text()

    def alive(self) -> bool:
        return self.proc.poll() is None

    def stop(self, sig: int = signal.SIGINT, timeout: float = 60.0) -> int:
        if self.alive():
            self.proc.send_signal(sig)
        try:
            return self.proc.wait(timeout=timeout)
        finally:
            if self.alive():
                self.proc.kill()
                self.proc.wait()
            self._log.close()


# ---------------------------------------------------------------------------------------------
# the test side of DDS
# ---------------------------------------------------------------------------------------------


class Probe:
    """A node in this process: subscriptions that keep what arrives, publishers, clients."""

    def __init__(self, context):
        self.node = Node("sweep_test_probe", context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        qos = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
        self.poses: list[PoseArray] = []
        self.agents: list[PointCloud2] = []
        self.diagnostics: list[DiagnosticArray] = []
        self.node.create_subscription(PoseArray, "/poses", self.poses.append, qos)
        self.node.create_subscription(PointCloud2, "/agents", self.agents.append, qos)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self.diagnostics.append,
                                      qos)
        self.cmd_vel = self.node.create_publisher(Twist, "/crowd/cmd_vel", qos)
        self.goal = self.node.create_publisher(PointStamped, "/goal", qos)
        self.field = self.node.create_publisher(PointCloud2, "/velocity_field", qos)

    def spin_until(self, pred, timeout: float, what: str, proc: Running | None = None):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.02)
            value = pred()
            if value:
                return value
            if proc is not None and not proc.alive():
                pytest.fail(f"sweep_node exited while waiting for {what}:\n{proc.log}")
        last = self.diagnostics[-1].status[0] if self.diagnostics else None
        pytest.fail(f"timed out after {timeout:g} s waiting for {what} (last diagnostics: "
                    f"{last})"
                    + (f"\n{proc.log}" if proc is not None else ""))

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.02)

    def call(self, srv_type, name: str, request, proc: Running):
        client = self.node.create_client(srv_type, name)
        self.spin_until(lambda: client.service_is_ready(), DISCOVERY_S, f"service {name}", proc)
        future = client.call_async(request)
        self.spin_until(future.done, WAIT_S, f"reply of {name}", proc)
        self.node.destroy_client(client)
        return future.result()

    def connect(self, proc: Running) -> None:
        """Waits for discovery both ways and the first state."""
        for pub in (self.cmd_vel, self.goal, self.field):
            self.spin_until(lambda p=pub: p.get_subscription_count() > 0, DISCOVERY_S,
                            f"sweep_node subscribing {pub.topic_name}", proc)
        self.spin_until(lambda: self.agents and self.poses, DISCOVERY_S, "first state", proc)

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()


@pytest.fixture
def probe():
    context = rclpy.Context()
    rclpy.init(context=context)
    p = Probe(context)
    yield p
    p.close()
    rclpy.shutdown(context=context)


def mean_velocity(cloud: PointCloud2) -> np.ndarray:
    names = [f.name for f in cloud.fields]
    assert names == list(topics.AGENT_FIELDS)
    cols = np.frombuffer(bytes(cloud.data), "<f4").reshape(cloud.width, len(names))
    return cols[:, [names.index("vx"), names.index("vy")]].mean(axis=0)


def stamp(msg) -> int:
    return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


def heading_is(probe: Probe, direction, speed: float, since_ns: int):
    """Predicate: the newest agents cloud after since_ns moves along direction at ~speed."""
    d = np.asarray(direction, float) / np.linalg.norm(direction)

    def check():
        if not probe.agents or stamp(probe.agents[-1]) <= since_ns:
            return False
        v = mean_velocity(probe.agents[-1])
        return abs(np.linalg.norm(v) - speed) < 0.2 * speed and v @ d > 0.95 * np.linalg.norm(v)
    return check


def grid_cloud(x, y, vx, vy, fields=("x", "y", "vx", "vy")) -> PointCloud2:
    X, Y = np.meshgrid(np.asarray(x, float), np.asarray(y, float))
    cols = np.stack([X, Y, np.full_like(X, vx), np.full_like(X, vy)], axis=-1).astype("<f4")
    m = PointCloud2(height=len(y), width=len(x), is_bigendian=False, point_step=16,
                    row_step=16 * len(x), is_dense=True)
    m.fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                for i, n in enumerate(fields)]
    m.data = cols.tobytes()
    return m


def diag_value(probe: Probe, key: str):
    if not probe.diagnostics:
        return None
    return {kv.key: kv.value for kv in probe.diagnostics[-1].status[0].values}.get(key)


# ---------------------------------------------------------------------------------------------
# tests
# ---------------------------------------------------------------------------------------------


def test_commands_services_parameters_and_recording(installed, probe, tmp_path):
    scene_path = tmp_path / "scene.yaml"
    scene_path.write_text(yaml.safe_dump(SCENE))
    record = tmp_path / "run.mcap"
    node = Running(installed, tmp_path, {
        "scene": str(scene_path), "dt": DT, "seed": 7, "rate_hz": 50.0, "steps_per_tick": 2,
        "record": str(record), "max_speed": 5.0, "marker_rate_hz": 5.0, "publish_clock": True,
        "record_flush_interval_s": 0.2})
    try:
        probe.connect(node)
        first = probe.poses[0]
        assert first.header.frame_id == "map" and len(first.poses) == 20

        # 1. cmd_vel: uniform +x
        probe.cmd_vel.publish(Twist(linear=Vector3(x=1.0, y=0.0)))
        t0 = stamp(probe.agents[-1])
        probe.spin_until(heading_is(probe, [1, 0], 1.0, t0), WAIT_S, "motion along +x", node)
        # 2. goal in +y: goal-directed at the scene's speed 1.3 m/s (a geodesic field: the
        # scene has a wall and an obstacle)
        g = PointStamped()
        g.header.frame_id = "map"
        g.point.x, g.point.y = 2.0, 15.0
        probe.goal.publish(g)
        t1 = stamp(probe.agents[-1])
        probe.spin_until(heading_is(probe, [0, 1], 1.3, t1), WAIT_S, "motion towards the goal",
                         node)
        # 3. a valid grid: uniform -x at 0.8 m/s over the whole scene (clamped outside)
        probe.field.publish(grid_cloud([-50.0, 0.0, 50.0], [-50.0, 50.0], -0.8, 0.0))
        t2 = stamp(probe.agents[-1])
        probe.spin_until(heading_is(probe, [-1, 0], 0.8, t2), WAIT_S, "motion along the grid",
                         node)

        # 4. malformed commands: refused, node alive, engine untouched
        nan_twist = Twist()
        nan_twist.linear.x = float("nan")
        inf_twist = Twist()
        inf_twist.linear.y = float("inf")
        fast_twist = Twist()
        fast_twist.linear.x = 100.0
        bad_goal = PointStamped()
        bad_goal.point.x = float("nan")
        wrong_fields = grid_cloud([0.0, 1.0], [0.0, 1.0], 1.0, 0.0, fields=("x", "y", "u", "v"))
        short = grid_cloud([0.0, 1.0, 2.0], [0.0, 1.0], 1.0, 0.0)
        short.data = bytes(short.data)[:-16]
        irregular = grid_cloud([0.0, 1.0, 3.0], [0.0, 1.0], 1.0, 0.0)
        nan_grid = grid_cloud([0.0, 1.0], [0.0, 1.0], float("nan"), 0.0)
        for pub, msg in [(probe.cmd_vel, nan_twist), (probe.cmd_vel, inf_twist),
                         (probe.cmd_vel, fast_twist), (probe.goal, bad_goal),
                         (probe.field, wrong_fields), (probe.field, short),
                         (probe.field, irregular), (probe.field, nan_grid)]:
            pub.publish(msg)
            probe.spin_for(0.05)
        probe.spin_until(lambda: diag_value(probe, "commands_refused") == "8", WAIT_S,
                         "diagnostics counting 8 refused commands", node)
        assert diag_value(probe, "commands_applied") == "3"
        assert diag_value(probe, "commands_received") == "11"
        assert diag_value(probe, "drift") == "grid"
        t3 = stamp(probe.agents[-1])
        probe.spin_until(heading_is(probe, [-1, 0], 0.8, t3), WAIT_S, "grid motion still", node)
        assert "command refused" in node.log

        # 5. live parameters: rate_hz changes, dt is refused with a reason
        set_params = SetParameters.Request(parameters=[
            Parameter("rate_hz", value=40.0).to_parameter_msg()])
        res = probe.call(SetParameters, "/sweep_node/set_parameters", set_params, node)
        assert res.results[0].successful, res.results[0].reason
        set_params = SetParameters.Request(parameters=[
            Parameter("dt", value=0.02).to_parameter_msg()])
        res = probe.call(SetParameters, "/sweep_node/set_parameters", set_params, node)
        assert not res.results[0].successful and "restart" in res.results[0].reason
        # real-time-factor mode, switched on live: simulated time runs at twice wall time
        set_params = SetParameters.Request(parameters=[
            Parameter("real_time_factor", value=2.0).to_parameter_msg()])
        res = probe.call(SetParameters, "/sweep_node/set_parameters", set_params, node)
        assert res.results[0].successful, res.results[0].reason
        probe.spin_until(lambda: 1.8 < float(diag_value(probe, "real_time_factor") or 0) < 2.2,
                         WAIT_S, "real-time factor 2 in diagnostics", node)

        # 6. pause, then exactly one step
        assert probe.call(SetBool, "/pause", SetBool.Request(data=True), node).success
        probe.spin_for(0.5)
        n_before, last = len(probe.poses), stamp(probe.poses[-1])
        k = round(last / (DT * 1e9))
        res = probe.call(Trigger, "/step", Trigger.Request(), node)
        assert res.success, res.message
        probe.spin_until(lambda: len(probe.poses) > n_before, WAIT_S, "the stepped state", node)
        probe.spin_for(0.5)
        assert [stamp(m) for m in probe.poses[n_before:]] == [topics.stamp_ns((k + 1) * DT)]
        # 7. reset: initial poses again (while paused), at t = 0
        n_before = len(probe.poses)
        assert probe.call(Trigger, "/reset", Trigger.Request(), node).success
        probe.spin_until(lambda: len(probe.poses) > n_before, WAIT_S, "the reset state", node)
        again = probe.poses[-1]
        assert stamp(again) == 0
        got = np.array([[p.position.x, p.position.y] for p in again.poses])
        np.testing.assert_array_equal(got, np.array(POSITIONS))
        # stepping is refused once running again
        assert probe.call(SetBool, "/pause", SetBool.Request(data=False), node).success
        assert not probe.call(Trigger, "/step", Trigger.Request(), node).success
        probe.spin_until(lambda: stamp(probe.poses[-1]) > 0, WAIT_S, "running after reset", node)
        assert node.alive()
    finally:
        code = node.stop(signal.SIGINT)
    assert code == 0, node.log
    assert "Traceback" not in node.log, node.log

    _check_recording(record)


def _check_recording(record: Path) -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.highlevel import AnyReader

    info = scan_recording(record)
    assert not info.truncated and info.profile == "ros2"
    counts = {t: c.message_count for t, c in info.channels.items()}
    assert counts["/crowd/cmd_vel"] == 1 and counts["/goal"] == 1 and counts["/velocity_field"] == 1
    assert counts["/poses"] == counts["/agents"] == counts["/clock"] > 20
    assert counts["/walls"] >= 1 and counts["/markers"] >= 2 and counts["/diagnostics"] >= 1
    assert counts["/navigation_field"] == 2  # the goal's geodesic field, then none (grid)
    meta = info.metadata
    run = meta["sweep_ros"]
    assert run["seed"] == "7" and yaml.safe_load(run["scene"])["name"] == "test_open_20"
    assert yaml.safe_load(run["parameters"])["rate_hz"] == 50.0 and "versions" in run
    commands = [meta[k] for k in sorted(meta) if k.startswith("command_")]
    assert [c["topic"] for c in commands] == ["/crowd/cmd_vel", "/goal", "/velocity_field"]
    assert [yaml.safe_load(c["field"])["kind"] for c in commands] == ["uniform", "geodesic",
                                                                       "grid"]
    assert all(int(c["step"]) * DT == pytest.approx(float(c["t"])) for c in commands)
    assert "reset_000001" in meta and meta["summary"]["commands_refused"] == "8"
    assert meta["sweep_status"]["status"] == "interrupted"
    assert meta["sweep_status"]["error"] == "SIGINT"

    # mcap_ros2 decodes every message of every channel
    seen: dict[str, int] = {}
    last_log: dict[str, int] = {}
    with open(record, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _schema, channel, message, msg in reader.iter_decoded_messages(log_time_order=False):
            seen[channel.topic] = seen.get(channel.topic, 0) + 1
            assert message.log_time >= last_log.get(channel.topic, 0), channel.topic
            last_log[channel.topic] = message.log_time
            if channel.topic == "/crowd/cmd_vel":
                assert msg.linear.x == 1.0
            if channel.topic == "/markers" and msg.markers[0].action == 0:
                assert len(msg.markers) == 20 and msg.markers[0].type == 3
    assert seen == counts
    # command log time = the simulated time of the step it applies to
    pose_times = [m.log_time_ns for m in read_recording(record, ["/poses"])]
    assert pose_times == sorted(pose_times) and len(set(pose_times)) == len(pose_times)

    # rosbags reads the same file
    with AnyReader([record]) as reader:
        n = 0
        for conn, _, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == "/poses":
                assert len(msg.poses) == 20
            n += 1
        assert n == sum(counts.values())


def test_sigkill_leaves_readable_recording(installed, probe, tmp_path):
    record = tmp_path / "killed.mcap"
    node = Running(installed, tmp_path, {
        "rate_hz": 20.0, "steps_per_tick": 1, "record": str(record),
        "record_flush_interval_s": 0.1, "publish_markers": False})
    try:
        probe.spin_until(lambda: len(probe.poses) >= 15, WAIT_S, "15 states", node)
        received = len(probe.poses)
        probe.spin_for(0.3)  # at least one flush after those
    finally:
        code = node.stop(signal.SIGKILL)
    assert code == -signal.SIGKILL
    reader = read_recording(record)
    poses = [m for m in reader if m.topic == "/poses"]
    assert reader.truncated is True
    assert len(poses) >= received - 2  # all but what arrived within the last flush interval
    assert reader.metadata["sweep_ros"]["seed"] == "0"
    for i, m in enumerate(poses):
        t, frame, q = cdr.decode_pose_array(m.data)
        assert frame == "map" and q.shape == (200, 2) and t == topics.stamp_ns(i * DT)


def test_infeasible_step_pauses_and_reports(installed, probe, tmp_path):
    """A disk growing between two walls: at t = 0.21 s no placement exists. The node pauses,
    reports ERROR, never publishes a state past t = 0.20 s, and resumes after reset."""
    scene_path = tmp_path / "squeeze.yaml"
    scene_path.write_text(yaml.safe_dump({
        "agents": {"positions": [[0.5, 0.0]], "radius": 0.3,
                   "radius_law": {"kind": "linear", "rate": 1.0}},
        "walls": [{"kind": "halfplane", "normal": [1, 0], "offset": 0.0},
                  {"kind": "halfplane", "normal": [-1, 0], "offset": -1.0}]}))
    node = Running(installed, tmp_path, {"scene": str(scene_path), "rate_hz": 20.0,
                                         "steps_per_tick": 1})
    try:
        probe.spin_until(lambda: probe.diagnostics and
                         probe.diagnostics[-1].status[0].level == b"\x02", DISCOVERY_S + 5,
                         "ERROR diagnostics", node)
        status = probe.diagnostics[-1].status[0]
        assert "infeasible" in status.message and diag_value(probe, "paused") == "true"
        last_ok = topics.stamp_ns(0.20)
        assert all(stamp(m) <= last_ok for m in probe.poses)  # what arrived after discovery
        res = probe.call(Trigger, "/step", Trigger.Request(), node)
        assert not res.success and "no feasible configuration" in res.message
        probe.spin_for(0.3)
        assert all(stamp(m) <= last_ok for m in probe.poses)
        assert probe.call(Trigger, "/reset", Trigger.Request(), node).success
        probe.spin_until(lambda: stamp(probe.poses[-1]) == 0, WAIT_S, "the reset state", node)
        assert node.alive()
    finally:
        code = node.stop(signal.SIGINT)
    assert code == 0, node.log
    assert "simulation paused" in node.log


def test_diagnostics_count_the_people_present(installed, probe, tmp_path):
    """With flows, people leave at sinks: diagnostics report how many are present, not how
    many the scene started with (two of three start in the sink and leave at the first
    step)."""
    scene_path = tmp_path / "sink.yaml"
    scene_path.write_text(yaml.safe_dump({
        "agents": {"positions": [[0.5, 0.0], [3.0, 0.0], [3.0, 1.0]], "radius": 0.2},
        "drift": {"kind": "uniform", "velocity": [0.5, 0.0]}, "noise": {"sigma": 0.0},
        "flows": {"sinks": [{"kind": "rectangle", "min": [2.0, -2.0], "max": [5.0, 2.0]}]}}))
    node = Running(installed, tmp_path, {"scene": str(scene_path), "rate_hz": 20.0,
                                         "steps_per_tick": 1})
    try:
        probe.spin_until(lambda: diag_value(probe, "steps") not in (None, "0"),
                         DISCOVERY_S + 5, "diagnostics after a step", node)
        assert diag_value(probe, "agents") == "1"
    finally:
        code = node.stop(signal.SIGINT)
    assert code == 0, node.log


@pytest.mark.parametrize("overrides,names", [
    ({"dt": -1.0}, "dt"),
    ({"rate_hz": 5}, "rate_hz"),                   # an int where a double is declared
    ({"frame_id": "/map", "noise_sigma": -0.5}, "frame_id|noise_sigma"),
    ({"scene": "/no/such/scene.yaml"}, "scene"),
    ({"solver_eps_abs": 1e-15, "solver_max_iter": 0}, "solver_max_iter"),
    ({"map_topic": "my map"}, "map_topic"),
])
def test_bad_parameters_refused_at_start(installed, tmp_path, overrides, names):
    node = Running(installed, tmp_path, overrides)
    try:
        code = node.proc.wait(timeout=30)
    finally:
        node.stop(signal.SIGKILL)
    log = node.log
    assert code == 2, log
    for name in names.split("|"):
        assert f"sweep_node: error: parameter {name}" in log, log


def test_broken_params_file_is_one_line_error(installed, tmp_path):
    # a YAML syntax error in --params-file: the file, line and column and a fix, exit 2, no
    # rclpy traceback (it was "RCLError: ... Couldn't parse params file")
    exe, env = installed
    bad = tmp_path / "broken.yaml"
    bad.write_text("/**:\n  ros__parameters:\n    dt: [0.01,\n    seed: 1\n")
    done = subprocess.run([str(exe), "--ros-args", "--params-file", str(bad)], env=env,
                          cwd=tmp_path, capture_output=True, text=True, timeout=60)
    out = done.stdout + done.stderr
    assert done.returncode == 2, out
    assert f"params file {bad} line" in out and "fix:" in out and "Traceback" not in out, out


def read_standard(record: Path) -> tuple[dict, dict[str, dict[str, str]]]:
    """What the standard readers see: mcap's seeking reader (summary section, metadata) and
    rosbags' AnyReader when it is installed. Returns (message counts per topic, metadata)."""
    from mcap.reader import make_reader

    with open(record, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None, f"{record}: no summary section (not closed cleanly)"
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        counts = {summary.channels[c].topic: n
                  for c, n in summary.statistics.channel_message_counts.items()}
    try:
        from rosbags.highlevel import AnyReader
    except ImportError:
        return counts, meta
    with AnyReader([record]) as bag:
        seen: dict[str, int] = {}
        for conn, _, raw in bag.messages():
            bag.deserialize(raw, conn.msgtype)
            seen[conn.topic] = seen.get(conn.topic, 0) + 1
    assert seen == {t: n for t, n in counts.items() if n}
    return counts, meta


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_signal_closes_recording_with_status(installed, probe, tmp_path, sig):
    """SIGTERM takes SIGINT's clean path: the recording gets its summary section and footer
    (mcap's seeking reader and rosbags read it) and a final status record."""
    record = tmp_path / "stopped.mcap"
    node = Running(installed, tmp_path, {"rate_hz": 20.0, "steps_per_tick": 1,
                                         "record": str(record), "publish_markers": False})
    try:
        probe.spin_until(lambda: len(probe.poses) >= 10, WAIT_S, "10 states", node)
    finally:
        code = node.stop(sig)
    assert code == 0, node.log
    assert "Traceback" not in node.log and "never retrieved" not in node.log, node.log
    counts, meta = read_standard(record)
    assert counts["/poses"] >= 10
    status = meta["sweep_status"]
    assert status["status"] == "interrupted" and status["error"] == sig.name, status
    assert int(status["steps"]) >= 9 and status["simulation_error"] == ""
    assert int(meta["summary"]["steps"]) == int(status["steps"])


def test_command_burst_latest_wins_and_counted(installed, probe, tmp_path):
    """300 cmd_vel in a burst: every one the node took is counted once (received = applied +
    superseded + refused), the publisher's count is known from the DDS sequence numbers
    (received + lost = 300), and the last command is the one in effect."""
    scene_path = tmp_path / "scene.yaml"
    scene_path.write_text(yaml.safe_dump(SCENE))
    record = tmp_path / "burst.mcap"
    node = Running(installed, tmp_path, {
        "scene": str(scene_path), "dt": DT, "rate_hz": 50.0, "steps_per_tick": 2,
        "record": str(record), "publish_markers": False, "record_flush_interval_s": 0.2})
    n, bad = 300, {10, 20, 30}
    last = (-0.6, 0.8)
    try:
        probe.connect(node)
        for k in range(n):
            x, y = (float("nan"), 0.0) if k in bad else (0.5 + 0.001 * k, 0.0)
            if k == n - 1:
                x, y = last
            probe.cmd_vel.publish(Twist(linear=Vector3(x=x, y=y)))
        t0 = stamp(probe.agents[-1])

        def settled():
            d = {kv.key: kv.value for kv in probe.diagnostics[-1].status[0].values} \
                if probe.diagnostics else {}
            return (d.get("commands_pending") == "0" and d.get("commands_lost", "x").isdigit()
                    and int(d["commands_received"]) + int(d["commands_lost"]) == n and d)
        d = probe.spin_until(settled, WAIT_S, f"diagnostics accounting for {n} commands", node)
        received, applied = int(d["commands_received"]), int(d["commands_applied"])
        superseded, refused = int(d["commands_superseded"]), int(d["commands_refused"])
        assert received == applied + superseded + refused, d
        assert d["commands_published"] == str(n), d
        assert applied >= 1 and superseded >= 1 and refused <= len(bad), d
        assert 0.0 <= float(d["command_latency_last_ms"]) <= float(d["command_latency_max_ms"])
        probe.spin_until(heading_is(probe, last, 1.0, t0), WAIT_S, "motion along the last command",
                         node)
    finally:
        code = node.stop(signal.SIGTERM)
    assert code == 0, node.log
    counts, meta = read_standard(record)
    commands = [meta[k] for k in sorted(meta) if k.startswith("command_")]
    assert len(commands) == applied == counts["/crowd/cmd_vel"]
    assert yaml.safe_load(commands[-1]["field"])["velocity"] == pytest.approx(list(last))
    assert sum(int(c["superseded_before"]) for c in commands) <= superseded
    summary = meta["summary"]
    assert [summary[k] for k in ("commands_received", "commands_applied",
                                 "commands_superseded", "commands_refused")] == \
        [str(received), str(applied), str(superseded), str(refused)]


def _timed_call(probe: Probe, srv_type, name: str, request, proc: Running,
                timeout: float = WAIT_S):
    """(response, seconds from the request to the reply), the service discovered first."""
    client = probe.node.create_client(srv_type, name)
    probe.spin_until(lambda: client.service_is_ready(), DISCOVERY_S, f"service {name}", proc)
    start = time.monotonic()
    future = client.call_async(request)
    probe.spin_until(future.done, timeout, f"reply of {name}", proc)
    elapsed = time.monotonic() - start
    probe.node.destroy_client(client)
    return future.result(), elapsed


def test_pause_answers_between_steps_of_a_long_tick(installed, probe, tmp_path):
    """96 jammed agents, 10000 steps per tick: one tick takes minutes. pause answers at the
    next step boundary (before: after the tick), no state past the step it names is
    published, and step and reset work between steps."""
    scene_path = tmp_path / "jam.yaml"
    scene_path.write_text(yaml.safe_dump(hex_jam(8, 12)))
    node = Running(installed, tmp_path, {
        "scene": str(scene_path), "dt": DT, "rate_hz": 20.0, "steps_per_tick": 10000,
        "publish_markers": False})
    try:
        # discovery both ways (the initial state is not latched: the next one comes only
        # when the tick ends), then let the first tick run
        probe.spin_until(lambda: probe.cmd_vel.get_subscription_count() > 0
                         and probe.node.count_publishers("/poses") > 0, DISCOVERY_S,
                         "discovery of sweep_node", node)
        probe.spin_for(1.5)
        res, latency = _timed_call(probe, SetBool, "/pause", SetBool.Request(data=True), node)
        assert res.success, res.message
        k = int(res.message.split("at step ")[1].split(",")[0])
        # inside the first tick (steps 1 to 10000), not after it: it answered between steps
        assert 0 < k < 10000, res.message
        # the tick publishes the state it stopped at, and nothing after it
        probe.spin_until(lambda: probe.poses and stamp(probe.poses[-1]) == topics.stamp_ns(
            k * DT), WAIT_S, f"the state of step {k}", node)
        probe.spin_for(1.0)
        assert stamp(probe.poses[-1]) == topics.stamp_ns(k * DT)
        res, latency = _timed_call(probe, Trigger, "/step", Trigger.Request(), node)
        assert res.success and res.message.startswith(f"step {k + 1},"), res.message
        # running again, reset lands between two steps: the initial state, then steps on
        assert probe.call(SetBool, "/pause", SetBool.Request(data=False), node).success
        probe.spin_for(1.0)
        res, latency = _timed_call(probe, Trigger, "/reset", Trigger.Request(), node)
        assert res.success, res.message
        # inside the tick that began at step k + 1 (10000 steps), between two of its steps
        was = int(res.message.split("(was step ")[1].split(",")[0])
        assert k + 1 <= was < k + 1 + 10000, res.message
        probe.spin_until(lambda: stamp(probe.poses[-1]) == 0, WAIT_S, "the reset state", node)
    finally:
        code = node.stop(signal.SIGTERM)
    assert code == 0, node.log
    assert "Traceback" not in node.log, node.log


def test_client_module_commands_a_running_node(installed, probe, tmp_path):
    """python -m sweep_ros.client, as the README shows it without a ROS CLI, from the
    installed package: services, both command topics, status, and a one-line error."""
    exe, env = installed
    scene_path = tmp_path / "scene.yaml"
    scene_path.write_text(yaml.safe_dump(SCENE))
    node = Running(installed, tmp_path, {"scene": str(scene_path), "dt": DT, "rate_hz": 50.0,
                                         "steps_per_tick": 2, "publish_markers": False})
    python = exe.read_text().splitlines()[0].removeprefix("#!").strip()

    def client(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([python, "-m", "sweep_ros.client", *args], env=env,
                              cwd=tmp_path, capture_output=True, text=True, timeout=60)
    try:
        probe.connect(node)
        done = client("pause")
        assert done.returncode == 0 and done.stdout.startswith("paused at step"), done
        k = int(done.stdout.split("at step ")[1].split(",")[0])
        done = client("step", "3")
        assert done.returncode == 0, done
        assert done.stdout.splitlines() == [f"step {k + i}, t = {(k + i) * DT:g} s"
                                            for i in (1, 2, 3)]
        done = client("cmd-vel", "0.6", "-0.8")
        assert done.returncode == 0 and "/crowd/cmd_vel" in done.stdout, done
        assert client("resume").returncode == 0
        t0 = stamp(probe.agents[-1])
        probe.spin_until(heading_is(probe, [0.6, -0.8], 1.0, t0), WAIT_S, "motion along cmd-vel",
                         node)
        done = client("goal", "2.0", "15.0")
        assert done.returncode == 0 and "/goal" in done.stdout, done
        t1 = stamp(probe.agents[-1])
        probe.spin_until(heading_is(probe, [0, 1], 1.3, t1), WAIT_S, "motion towards the goal",
                         node)
        # status prints the latest diagnostics (latched, 1 Hz): wait until it counts both
        probe.spin_until(lambda: diag_value(probe, "commands_applied") == "2", WAIT_S,
                         "diagnostics counting both commands", node)
        done = client("status")
        assert done.returncode == 0 and "commands_applied: 2" in done.stdout, done
        done = client("reset")
        assert done.returncode == 0 and done.stdout.startswith("reset to t = 0"), done
        # refusals: the node's reason (exit 1); bad input and no node (exit 2, one line)
        done = client("step")
        assert done.returncode == 1 and "not paused" in done.stdout, done
        done = client("cmd-vel", "nan", "0")
        assert done.returncode == 2 and "VX = 'nan' is not a finite number" in done.stderr
        done = client("--namespace", "/nowhere", "--timeout", "1", "pause")
        assert done.returncode == 2, done
        assert done.stderr.strip().splitlines() == [
            "sweep_client: error: no answer from service /nowhere/pause within 1 s (fix: "
            "start sweep_node with the same ROS_DOMAIN_ID, ROS_AUTOMATIC_DISCOVERY_RANGE and "
            "--namespace, or raise --timeout)"]
    finally:
        code = node.stop(signal.SIGTERM)
    assert code == 0, node.log


# ---------------------------------------------------------------------------------------------
# maps from a topic (issue 13)
# ---------------------------------------------------------------------------------------------

#: 8 agents on cell centres of a 0.5 m grid, no drift: they only diffuse until told to move
MAP_AGENTS = [[0.25 + 1.0 * i, 0.25 + 1.0 * j] for j in range(2) for i in range(4)]
MAP_SCENE = {"name": "test_map_topic", "agents": {"positions": MAP_AGENTS, "radius": 0.15},
             "walls": [{"kind": "segment", "a": [20.0, 20.0], "b": [21.0, 20.0]}],  # kept
             "noise": {"sigma": 0.05}}


def room_grid(width_cells: int, height_cells: int = 8, res: float = 0.5,
              origin=(-1.0, -1.0)):
    """An OccupancyGrid (frame map): a room of free cells (0) inside a one-cell border of
    occupied cells (100); with 8 rows from y = -1 the free space is -0.5 <= y <= 2.5."""
    from nav_msgs.msg import OccupancyGrid

    cells = np.zeros((height_cells, width_cells), dtype=np.int8)
    cells[0, :] = cells[-1, :] = cells[:, 0] = cells[:, -1] = 100
    msg = OccupancyGrid()
    msg.header.frame_id = "map"
    msg.info.resolution = res
    msg.info.width, msg.info.height = width_cells, height_cells
    msg.info.origin.position.x, msg.info.origin.position.y = origin
    msg.info.origin.orientation.w = 1.0
    msg.data = cells.ravel().tolist()
    return msg


def grid_of(msg):
    from sweep_core.model.maps import OccupancyMap

    i = msg.info
    return OccupancyMap.from_occupancy_grid(np.array(msg.data, dtype=np.int8), i.width, i.height,
                                            i.resolution, (i.origin.position.x,
                                                           i.origin.position.y, 0.0))


def test_map_topic_walls_refusal_and_replay(installed, probe, tmp_path):
    """A map published (transient-local) before the node starts becomes its walls (markers
    show its pieces); a wider map mid-run lets the crowd further; a map that cuts agents is
    refused naming them while the run goes on; no recorded state has an agent in a blocked
    cell of the map in effect; sweep replay reproduces the run bit for bit."""
    from rclpy.qos import DurabilityPolicy
    from visualization_msgs.msg import MarkerArray

    from sweep_core.cli import main as sweep_main

    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    walls: list[MarkerArray] = []
    probe.node.create_subscription(MarkerArray, "/walls", walls.append, latched)
    map_pub = probe.node.create_publisher(type(room_grid(4)), "/map", latched)
    narrow, wide = room_grid(12), room_grid(16)  # free x up to 4.5 m, then up to 6.5 m
    map_pub.publish(narrow)  # before the node exists: transient-local keeps it for it
    scene_path = tmp_path / "scene.yaml"
    scene_path.write_text(yaml.safe_dump(MAP_SCENE))
    record = tmp_path / "map.mcap"
    node = Running(installed, tmp_path, {
        "scene": str(scene_path), "dt": DT, "seed": 5, "rate_hz": 50.0, "steps_per_tick": 2,
        "map_topic": "map", "record": str(record), "record_flush_interval_s": 0.2})
    try:
        probe.connect(node)
        probe.spin_until(lambda: diag_value(probe, "maps_applied") == "1", DISCOVERY_S,
                         "the first map applied", node)

        def map_pieces():
            last = walls[-1] if walls else None
            return last and [m for m in last.markers if m.ns == "map"]
        pieces = probe.spin_until(map_pieces, WAIT_S, "walls markers of the map", node)
        a, b = grid_of(narrow).segments()
        got = sorted((m.pose.position.x, m.pose.position.y) for m in pieces)
        want = sorted(map(tuple, ((a + b) / 2).tolist()))
        assert len(pieces) == len(a) and np.allclose(got, want, atol=1e-9)

        probe.cmd_vel.publish(Twist(linear=Vector3(x=1.0)))  # into the east wall at x = 4.5
        probe.spin_for(4.0)
        map_pub.publish(wide)
        probe.spin_until(lambda: diag_value(probe, "maps_applied") == "2", WAIT_S,
                         "the wider map applied", node)
        probe.spin_until(lambda: max(p.position.x for p in probe.poses[-1].poses) > 5.0, WAIT_S,
                         "the crowd beyond the old wall", node)
        a, b = grid_of(wide).segments()
        assert len(walls[-1].markers) == 1 + 1 + len(a)  # DELETEALL, the scene's wall, map
        assert walls[-1].markers[0].action == 3
        got = sorted((m.pose.position.x, m.pose.position.y) for m in map_pieces())
        assert np.allclose(got, sorted(map(tuple, ((a + b) / 2).tolist())), atol=1e-9)
        probe.spin_for(3.0)
        map_pub.publish(narrow)  # now cuts the agents piled at x ~ 6.35: refused
        probe.spin_until(lambda: diag_value(probe, "map_refused") == "1", WAIT_S,
                         "the narrow map refused", node)
        assert diag_value(probe, "maps_applied") == "2"
        assert "map refused" in probe.diagnostics[-1].status[0].message
        n, t_refused = len(probe.poses), stamp(probe.poses[-1])
        probe.spin_until(lambda: len(probe.poses) > n + 10, WAIT_S, "the run going on", node)
        assert stamp(probe.poses[-1]) > t_refused and node.alive()
        # free where the agents are now, but not where a reset puts them: refused too
        map_pub.publish(room_grid(6, origin=(5.0, -1.0)))
        probe.spin_until(lambda: diag_value(probe, "map_refused") == "2", WAIT_S,
                         "the map without the start refused", node)
        # reset: back to the start, the wide map kept; then the run goes on
        n = len(probe.poses)
        assert probe.call(Trigger, "/reset", Trigger.Request(), node).success
        # the states published since the reset call: from t = 0 on (the last one before the
        # reset may be later than 2 s already)
        since = lambda: [stamp(p) for p in probe.poses[n:]]  # noqa: E731
        probe.spin_until(lambda: 0 in since() and since()[-1] > topics.stamp_ns(2.0), WAIT_S,
                         "2 s after the reset", node)
        assert len(walls[-1].markers) == 1 + len(a)  # the wide map's walls, republished
    finally:
        code = node.stop(signal.SIGINT)
    assert code == 0, node.log
    assert "Traceback" not in node.log
    refusal = [line for line in node.log.splitlines() if "map refused" in line]
    assert len(refusal) == 2 and "old walls kept" in refusal[0]
    assert re.search(r"agents \[\d+(, \d+)*\] at t = [\d.]+ s would be inside", refusal[0])
    assert "initial positions (where reset returns)" in refusal[1] and "agent 0" in refusal[1]

    info = scan_recording(record)
    meta = info.metadata
    assert info.channels["/map"].message_count == 2  # the maps applied, as received
    maps = [meta[k] for k in sorted(meta) if k.startswith("map_")]
    assert [m["topic"] for m in maps] == ["/map", "/map"]
    steps = [int(m["step"]) for m in maps]
    grids = [grid_of(narrow), grid_of(wide)]
    seen, after_reset = 0, 0
    for m in read_recording(record, ["/poses"]):
        t, _, q = cdr.decode_pose_array(m.data)
        k = round(t / (DT * 1e9))
        if m.log_time_ns > int(meta["reset_000001"]["log_time_ns"]) - 1:
            assert not grids[1].is_blocked(q).any(), k  # the wide map stays over the reset
            after_reset += 1
        elif k >= steps[0]:
            in_effect = grids[1] if k >= steps[1] else grids[0]
            assert not in_effect.is_blocked(q).any(), k
            seen += 1
    assert seen > 100 and after_reset > 10
    assert sweep_main(["replay", str(record)]) == 0


# ---------------------------------------------------------------------------------------------
# navigation fields (issue 15)
# ---------------------------------------------------------------------------------------------

#: a 10 x 6 m room split by a wall at x = 5 with a 1.5 m gap at its top (4.5 <= y <= 6); six
#: agents on the left, no drift until told
GAP_ROOM = [{"kind": "polyline", "closed": True,
             "points": [[0.0, 0.0], [10.0, 0.0], [10.0, 6.0], [0.0, 6.0]]},
            {"kind": "segment", "a": [5.0, 0.0], "b": [5.0, 4.5]}]
GAP_AGENTS = [[1.0 + i, 1.0 + j] for i in range(2) for j in range(3)]
GAP_SCENE = {"name": "test_gap", "agents": {"positions": GAP_AGENTS, "radius": 0.2,
                                            "speed": 1.3},
             "walls": GAP_ROOM, "noise": {"sigma": 0.02}}


def cloud_columns(cloud: PointCloud2) -> dict[str, np.ndarray]:
    """The FLOAT32 columns of a navigation_field cloud, by name, row-major."""
    names = [f.name for f in cloud.fields]
    assert names == list(topics.NAVIGATION_FIELDS)
    cols = np.frombuffer(bytes(cloud.data), "<f4").reshape(cloud.height * cloud.width,
                                                            len(names))
    return {n: cols[:, i].astype(np.float64) for i, n in enumerate(names)}


def navigation_probe(probe: Probe) -> list[PointCloud2]:
    """Keeps every navigation_field message (transient-local, as the node publishes it)."""
    from rclpy.qos import DurabilityPolicy

    got: list[PointCloud2] = []
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    probe.node.create_subscription(PointCloud2, "/navigation_field", got.append, latched)
    return got


def test_goal_builds_a_geodesic_field_round_the_wall(installed, probe, tmp_path):
    """In a scene with walls, a goal command builds a geodesic field (recorded as such): the
    crowd behind the wall goes through the gap; navigation_field carries the field's grid, its
    T equal to Geodesic.travel_distance at the nodes; goals in a wall or out of reach are
    refused with a warning and counted; a command without a field publishes an empty cloud;
    the recording reads with rosbags and replays bit for bit."""
    from sweep_core.cli import main as sweep_main
    from sweep_core.model.drift import field_from_spec
    from sweep_core.model.scene import Scene
    from sweep_ros.clouds import grid_from_cloud

    clouds = navigation_probe(probe)
    scene_path = tmp_path / "gap.yaml"
    scene_path.write_text(yaml.safe_dump(GAP_SCENE))
    record = tmp_path / "gap.mcap"
    node = Running(installed, tmp_path, {
        "scene": str(scene_path), "dt": DT, "seed": 3, "rate_hz": 50.0, "steps_per_tick": 5,
        "record": str(record), "record_flush_interval_s": 0.2})

    def goal(x: float, y: float) -> PointStamped:
        g = PointStamped()
        g.point.x, g.point.y = x, y
        return g
    try:
        probe.connect(node)
        probe.spin_for(0.5)
        assert clouds == []  # no drift, no navigation field
        # a goal cell too coarse for the wall buffer is refused as a parameter
        set_params = SetParameters.Request(parameters=[
            Parameter("goal_cell", value=0.5).to_parameter_msg()])
        res = probe.call(SetParameters, "/sweep_node/set_parameters", set_params, node)
        assert not res.results[0].successful
        assert "goal_cell: 0.5 m is too coarse for goal_wall_buffer 0.3 m" in \
            res.results[0].reason
        probe.goal.publish(goal(8.0, 1.0))
        probe.spin_until(lambda: clouds and clouds[-1].width > 0, 20.0,
                         "a navigation_field", node)
        cloud = clouds[-1]
        assert cloud.header.frame_id == "map" and cloud.height > 1
        cols = cloud_columns(cloud)
        scene = Scene.from_dict(GAP_SCENE)
        spec = {"kind": "geodesic", "goal": [8.0, 1.0], "speed": 1.3, "slow_radius": 0.5,
                "cell": 0.1, "wall_buffer": 0.3}
        field = field_from_spec(spec, 6, "goal", scene.geometry, None, scene.positions)
        nodes = np.stack(np.meshgrid(field.x, field.y), axis=-1).reshape(-1, 2)
        assert (cloud.height, cloud.width) == (len(field.y), len(field.x))
        np.testing.assert_allclose(cols["x"], nodes[:, 0], atol=1e-5)
        np.testing.assert_allclose(cols["T"], field.travel_distance(nodes), rtol=1e-6,
                                   atol=1e-5)
        # the cloud reads back as a velocity_field grid: the drift at its nodes
        grid = grid_from_cloud(cloud, 10.0)
        np.testing.assert_allclose(grid(0.0, nodes), field(0.0, nodes), atol=1e-5)
        # round the wall: left of it, below the gap, the field heads up to the gap
        k = int(np.argmin(np.hypot(nodes[:, 0] - 4.5, nodes[:, 1] - 1.0)))
        assert cols["vy"][k] > 0.9 * 1.3 and abs(cols["vx"][k]) < 0.3
        probe.spin_until(lambda: min(p.position.x for p in probe.poses[-1].poses) > 5.3,
                         60.0, "every agent through the gap", node)

        # refused: a goal on the wall, a goal outside the room; the field stays
        probe.goal.publish(goal(5.0, 2.0))
        probe.spin_until(lambda: diag_value(probe, "commands_refused") == "1", WAIT_S,
                         "the goal on the wall refused", node)
        probe.spin_for(2.1)  # refusals are logged at most every 2 s
        probe.goal.publish(goal(12.0, 3.0))
        probe.spin_until(lambda: diag_value(probe, "commands_refused") == "2", WAIT_S,
                         "two goals refused", node)
        assert diag_value(probe, "commands_applied") == "1"
        assert diag_value(probe, "drift") == "geodesic" and len(clouds) == 1
        # a drift without a navigation field: an empty cloud clears it
        probe.cmd_vel.publish(Twist(linear=Vector3(x=-0.5)))
        probe.spin_until(lambda: len(clouds) == 2, WAIT_S, "the empty navigation_field", node)
        assert clouds[-1].width * clouds[-1].height == 0
    finally:
        code = node.stop(signal.SIGINT)
    assert code == 0, node.log
    assert "Traceback" not in node.log
    refused = [line for line in node.log.splitlines() if "command refused" in line]
    assert len(refused) == 2, node.log
    assert "/goal: the goal refused: [5, 2] lies in or on walls[1]" in refused[0]
    assert "(fix: move the goal into the free space)" in refused[0]
    assert "/goal: the geodesic field refused: agent 0 at [1, 1] has no way to the goal" \
        in refused[1]

    counts, meta = read_standard(record)  # rosbags deserialises every message
    assert counts["/navigation_field"] == 2 and counts["/goal"] == 1
    commands = [meta[k] for k in sorted(meta) if k.startswith("command_")]
    assert [yaml.safe_load(c["field"])["kind"] for c in commands] == ["geodesic", "uniform"]
    assert yaml.safe_load(commands[0]["field"]) == {**spec, "neighbours": 16}
    assert sweep_main(["replay", str(record)]) == 0


def test_group_goals_replace_only_their_group(installed, probe, tmp_path):
    """goal/<group> (and sweep_client goal --group) gives one group a geodesic field at the
    group's speed, the other group keeps its drift; goals for two groups stack; the plain goal
    still means every agent, and a group goal after it keeps the others on it; navigation_field
    carries a grid per field with its group; an unknown group and an unreachable group goal are
    refused (the latter counted); the recording reads with rosbags and replays bit for bit."""
    from sweep_core.cli import main as sweep_main
    from sweep_core.model.drift import field_from_spec
    from sweep_core.model.scene import Scene

    clouds = navigation_probe(probe)
    refusals: list[str] = []  # the node's reasons, on command_result (its log is throttled)
    probe.node.create_subscription(
        DiagnosticArray, "/command_result",
        lambda m: refusals.append(m.status[0].message) if m.status[0].level == b"\x02" else None,
        QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE,
                   durability=DurabilityPolicy.TRANSIENT_LOCAL))
    # group a in front (x = 2), group b behind it (x = 1): a's way to the gap passes clear of b
    start = np.array([[2.0, 1.0], [2.0, 2.0], [2.0, 3.0], [1.0, 1.0], [1.0, 2.0], [1.0, 3.0]])
    scene_dict = {**GAP_SCENE, "name": "test_gap_groups",
                  "agents": {**GAP_SCENE["agents"], "positions": start.tolist(), "groups": [
                      {"name": "a", "agents": [0, 1, 2], "drift": {"kind": "none"},
                       "speed": 1.0},
                      {"name": "b", "agents": {"range": [3, 6]}, "drift": {"kind": "none"},
                       "speed": 0.6}]}}
    scene_path = tmp_path / "groups.yaml"
    scene_path.write_text(yaml.safe_dump(scene_dict))
    record = tmp_path / "groups.mcap"
    node = Running(installed, tmp_path, {
        "scene": str(scene_path), "dt": DT, "seed": 4, "rate_hz": 50.0, "steps_per_tick": 5,
        "record": str(record), "record_flush_interval_s": 0.2, "publish_markers": False})
    exe, env = installed
    python = exe.read_text().splitlines()[0].removeprefix("#!").strip()

    def client(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([python, "-m", "sweep_ros.client", *args], env=env,
                              cwd=tmp_path, capture_output=True, text=True, timeout=60)

    def goal(x: float, y: float) -> PointStamped:
        g = PointStamped()
        g.point.x, g.point.y = x, y
        return g
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    goal_b = probe.node.create_publisher(PointStamped, "/goal/b", qos)
    scene = Scene.from_dict(scene_dict)
    try:
        probe.connect(node)
        probe.spin_until(lambda: goal_b.get_subscription_count() > 0, DISCOVERY_S,
                         "sweep_node subscribing /goal/b", node)
        done = client("goal", "8", "1", "--group", "a")
        assert done.returncode == 0 and "/goal/a" in done.stdout, done
        probe.spin_until(lambda: clouds and clouds[-1].width > 0, 20.0,
                         "group a's navigation_field", node)
        cols = cloud_columns(clouds[-1])
        assert set(cols["group"].tolist()) == {0.0} and clouds[-1].height > 1
        field_a = field_from_spec({"kind": "geodesic", "goal": [8.0, 1.0], "speed": 1.0},
                                  3, "goal", scene.geometry, None, start[:3])
        nodes = np.stack(np.meshgrid(field_a.x, field_a.y), axis=-1).reshape(-1, 2)
        np.testing.assert_allclose(cols["T"], field_a.travel_distance(nodes), rtol=1e-6,
                                   atol=1e-5)
        assert np.max(np.hypot(cols["vx"], cols["vy"])) == pytest.approx(1.0, rel=1e-6)

        def moved() -> np.ndarray:
            q = np.array([[p.position.x, p.position.y] for p in probe.poses[-1].poses])
            return np.hypot(*(q - start).T)
        probe.spin_until(lambda: moved()[:3].min() > 1.5, 30.0, "group a on its way", node)
        assert moved()[3:].max() < 0.5  # group b: no drift, only noise

        # no such group: the node refuses it, naming its groups; unreachable: refused too
        done = client("goal", "8", "1", "--group", "c")
        assert done.returncode == 1, done
        assert done.stdout.strip() == (
            "refused: /goal/c: no group 'c' in the scene (its groups: a, b) (fix: publish on "
            "/goal/<group> for one of them, or on /goal for every agent)"), done
        goal_b.publish(goal(12.0, 3.0))
        probe.spin_until(lambda: diag_value(probe, "commands_refused") == "2", WAIT_S,
                         "the unreachable goal of group b refused", node)
        # goals for both groups stack
        goal_b.publish(goal(8.0, 5.0))
        probe.spin_until(lambda: len(clouds) >= 2, 20.0, "both groups' fields", node)
        cols = cloud_columns(clouds[-1])
        assert clouds[-1].height == 1 and set(cols["group"].tolist()) == {0.0, 1.0}
        field_b = field_from_spec({"kind": "geodesic", "goal": [8.0, 5.0], "speed": 0.6},
                                  3, "goal", scene.geometry, None, start[3:])
        nodes_b = np.stack(np.meshgrid(field_b.x, field_b.y), axis=-1).reshape(-1, 2)
        np.testing.assert_allclose(cols["T"][cols["group"] == 1],
                                   field_b.travel_distance(nodes_b), rtol=1e-6, atol=1e-5)
        # the plain goal: every agent; then group a's own goal, the others kept on the plain one
        probe.goal.publish(goal(8.0, 3.0))
        probe.spin_until(lambda: len(clouds) >= 3, 20.0, "the whole goal's field", node)
        assert set(cloud_columns(clouds[-1])["group"].tolist()) == {-1.0}
        assert clouds[-1].height > 1
        done = client("goal", "2", "5", "--group", "a")
        assert done.returncode == 0, done
        probe.spin_until(lambda: len(clouds) >= 4, 20.0, "group a's field over the whole", node)
        assert set(cloud_columns(clouds[-1])["group"].tolist()) == {-1.0, 0.0, 1.0}
        probe.spin_until(lambda: diag_value(probe, "commands_applied") == "4", WAIT_S,
                         "four goals applied", node)
        probe.spin_for(1.0)
    finally:
        code = node.stop(signal.SIGINT)
    assert code == 0, node.log
    assert "Traceback" not in node.log
    assert [r for r in refusals if r.startswith(
        "/goal/b: the geodesic field refused: agent 3 at [1, 1] has no way to the goal")], refusals

    counts, meta = read_standard(record)  # rosbags deserialises every message
    assert counts["/goal/a"] == 2 and counts["/goal/b"] == 1 and counts["/goal"] == 1
    assert counts["/navigation_field"] == 4
    specs = [yaml.safe_load(meta[k]["field"]) for k in sorted(meta) if k.startswith("command_")]
    assert [s["kind"] for s in specs] == ["groups", "groups", "geodesic", "groups"]
    first = specs[0]["groups"]
    assert [g["name"] for g in first] == ["a", "b"] and first[1]["drift"] == {"kind": "none"}
    assert first[0]["drift"]["kind"] == "geodesic" and first[0]["drift"]["speed"] == 1.0
    assert specs[1]["groups"][1]["drift"]["goal"] == [8.0, 5.0]
    assert specs[1]["groups"][1]["drift"]["speed"] == 0.6
    last = specs[3]
    assert last["groups"][0]["drift"]["goal"] == [2.0, 5.0]
    assert last["groups"][1]["drift"] == last["rest"] == specs[2]
    assert sweep_main(["replay", str(record)]) == 0


def test_goal_stays_straight_without_walls(installed, probe, tmp_path):
    """No wall, obstacle or map: a goal command is the straight goal field at the scene's
    speed, and no navigation_field is published."""
    clouds = navigation_probe(probe)
    scene_path = tmp_path / "open.yaml"
    scene_path.write_text(yaml.safe_dump({"name": "test_open", "agents": {
        "positions": GAP_AGENTS, "radius": 0.2, "speed": 0.9}}))
    node = Running(installed, tmp_path, {"scene": str(scene_path), "dt": DT, "rate_hz": 50.0,
                                         "publish_markers": False})
    try:
        probe.connect(node)
        g = PointStamped()
        g.point.x, g.point.y = 100.0, 2.0
        probe.goal.publish(g)
        t0 = stamp(probe.agents[-1])
        probe.spin_until(heading_is(probe, [1, 0], 0.9, t0), WAIT_S, "motion towards the goal",
                         node)
        probe.spin_until(lambda: diag_value(probe, "commands_applied") == "1", WAIT_S,
                         "the goal applied", node)
        assert diag_value(probe, "drift") == "goal" and clouds == []
    finally:
        code = node.stop(signal.SIGINT)
    assert code == 0, node.log


def test_first_goal_on_a_cold_cache_compiles_nothing_after_ready(installed, probe, tmp_path):
    """A node on a machine whose kernel cache is empty compiles its kernels before it is
    ready (said in its log, timed in its diagnostics): its first goal, a geodesic field round
    a wall (kernels the steps themselves never call), is applied with no compile after ready
    (before: the first goal waited seconds for them)."""
    scene_path = tmp_path / "gap.yaml"
    scene_path.write_text(yaml.safe_dump(GAP_SCENE))
    node = Running(installed, tmp_path, {
        "scene": str(scene_path), "dt": DT, "seed": 3, "rate_hz": 50.0, "steps_per_tick": 5},
        extra_env={"NUMBA_CACHE_DIR": str(tmp_path / "empty_cache")})
    try:
        # the compile comes before the node subscribes: minutes on a loaded machine
        probe.spin_until(lambda: probe.goal.get_subscription_count() > 0, 900.0,
                         "sweep_node ready", node)
        probe.connect(node)
        assert "compiling kernels, first run on this machine" in node.log, node.log
        g = PointStamped()
        g.point.x, g.point.y = 8.0, 1.0
        probe.goal.publish(g)
        probe.spin_until(lambda: diag_value(probe, "commands_applied") == "1", WAIT_S,
                         "the goal applied", node)
        assert float(diag_value(probe, "compile_s")) > 0.0
        assert diag_value(probe, "kernels_compiled_late") == "0", probe.diagnostics[-1]
        # a goal in the wall, refused, compiles nothing either
        g.point.x, g.point.y = 5.0, 0.5
        probe.goal.publish(g)
        probe.spin_until(lambda: diag_value(probe, "commands_refused") == "1", WAIT_S,
                         "the goal in the wall refused", node)
        assert diag_value(probe, "kernels_compiled_late") == "0", probe.diagnostics[-1]
        print(f"first goal: command_latency_last_ms {diag_value(probe, 'command_latency_last_ms')}")
    finally:
        code = node.stop(signal.SIGINT)
    assert code == 0, node.log


def test_record_may_not_be_the_scene(installed, tmp_path):
    """Before: `sweep_node -p scene:=victim.yaml -p record:=victim.yaml` started and turned
    the scene into a recording."""
    victim = tmp_path / "victim.yaml"
    victim.write_text(yaml.safe_dump(SCENE))
    before = victim.read_bytes()
    log = _refused_at_start(installed, tmp_path, {"scene": str(victim), "record": str(victim)})
    assert f"parameter record: {victim}: is also an input" in log, log
    assert "record:=OTHER.mcap" in log
    assert victim.read_bytes() == before


def _refused_at_start(installed, tmp_path: Path, overrides: dict) -> str:
    """The log of a node that refuses to start with ``overrides``: exit 2, no traceback."""
    node = Running(installed, tmp_path, overrides)
    try:
        code = node.proc.wait(timeout=60)
    finally:
        node.stop(signal.SIGKILL)
    assert code == 2 and "Traceback" not in node.log, node.log
    return node.log


def test_an_existing_recording_is_not_replaced_unasked(installed, tmp_path):
    """Before: a node started again with the same `record` replaced the last run's recording
    without a word (`sweep run --out` refuses unless --overwrite). It refuses to start,
    naming the file and both fixes; with record_overwrite:=true it replaces it."""
    scene_path = tmp_path / "scene.yaml"
    scene_path.write_text(yaml.safe_dump(SCENE))
    old = tmp_path / "run.mcap"
    old.write_bytes(b"the last run's recording")
    log = _refused_at_start(installed, tmp_path, {"scene": str(scene_path), "record": str(old)})
    assert (f"parameter record: {old}: exists, and the node does not replace a recording "
            "unasked") in log and "record_overwrite:=true" in log, log
    assert old.read_bytes() == b"the last run's recording"
    node = Running(installed, tmp_path, {"scene": str(scene_path), "record": str(old),
                                         "record_overwrite": True, "dt": DT})
    try:
        deadline = time.monotonic() + 120
        while not old.read_bytes().startswith(b"\x89MCAP"):  # the recorder has begun
            assert node.alive() and time.monotonic() < deadline, node.log
            time.sleep(0.1)
    finally:
        code = node.stop(signal.SIGINT)
    assert code == 0, node.log
    assert read_standard(old)[1]["sweep_status"]["status"] == "interrupted"


def test_a_full_disk_is_logged_at_once_and_once(installed, tmp_path):
    """Before: a node recording onto a full disk said nothing in its log until shutdown."""
    small = tmp_path / "small"
    small.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=512k", "tmpfs", str(small)],
                      capture_output=True).returncode != 0:
        pytest.skip("cannot mount a small tmpfs here")
    try:
        fd = os.open(small / "filler", os.O_WRONLY | os.O_CREAT)
        try:  # leave about 64 KiB: the metadata fits, a few seconds of messages do not
            os.write(fd, b"\0" * (512 - 64) * 1024)
        finally:
            os.close(fd)
        scene_path = tmp_path / "scene.yaml"
        scene_path.write_text(yaml.safe_dump(SCENE))
        node = Running(installed, tmp_path, {
            "scene": str(scene_path), "dt": DT, "rate_hz": 50.0, "steps_per_tick": 1,
            "record": str(small / "run.mcap"), "record_flush_interval_s": 0.2})
        try:
            deadline = time.monotonic() + 120
            while "recording stopped" not in node.log:
                assert node.alive() and time.monotonic() < deadline, node.log
                time.sleep(0.1)
            time.sleep(1.0)
            assert node.alive(), node.log  # the simulation goes on
        finally:
            code = node.stop(signal.SIGINT)
        log = node.log
        assert code == 0, log
        assert log.count("No space left on device") == 1, log
        assert "[ERROR]" in log.split("recording stopped")[0].splitlines()[-1], log
    finally:
        subprocess.run(["umount", "-l", str(small)], check=False)
