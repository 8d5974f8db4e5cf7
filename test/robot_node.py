"""The test side of sweep_node's robots over DDS, shared by the robot tests (not a test file):
the node of this checkout's editable installation, a probe that drives a scene's robots and
keeps their odometry and the verdicts, and the node's start.

The node runs from ``pip install -e``'s executable (its numba caches are warm, so no test waits
for a build); every wait is on an event (a message, a verdict, a process exit) with a generous
deadline, never on how fast the node steps.
"""
from __future__ import annotations

import math
import os
import signal
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseWithCovarianceStamped, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.qos import QoSProfile, ReliabilityPolicy
from test_node import DISCOVERY_S, WAIT_S, Probe, Running, ros_env

from sweep_ros import results


def editable_installation() -> tuple[Path, dict[str, str]]:
    """The sweep_node of this checkout's editable installation and the environment that keeps
    its DDS on this machine, on this test process's domain."""
    exe = Path(sys.executable).with_name("sweep_node")
    assert exe.is_file(), f"{exe} missing (pip install -e .)"
    return exe, dict(os.environ, **ros_env())


class RobotProbe(Probe):
    """A controller of the scene's robots ``names`` (TwistStamped on ``/NAME/cmd_vel``,
    ``/NAME/initialpose``), their odometry (``odoms[NAME]``; ``odom`` is the first robot's) and
    the verdicts on ``command_result``."""

    def __init__(self, context: Any, names: tuple[str, ...] = ("bot",)) -> None:
        super().__init__(context)
        qos = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
        self.names = names
        self.odoms: dict[str, list[Odometry]] = {n: [] for n in names}
        self.robot_cmds = {}
        self.initialposes = {}
        for n in names:
            self.node.create_subscription(Odometry, f"/{n}/odom", self.odoms[n].append, qos)
            self.robot_cmds[n] = self.node.create_publisher(TwistStamped, f"/{n}/cmd_vel", qos)
            self.initialposes[n] = self.node.create_publisher(
                PoseWithCovarianceStamped, f"/{n}/initialpose", qos)
        self.odom = self.odoms[names[0]]
        self.robot_cmd = self.robot_cmds[names[0]]
        self.initialpose = self.initialposes[names[0]]
        self.verdicts: list[dict[str, str]] = []

        def keep(msg: DiagnosticArray) -> None:
            parsed = results.parse(msg)
            if parsed is not None:
                self.verdicts.append(parsed)
        self.node.create_subscription(DiagnosticArray, "/command_result", keep, results.QOS)

    def drive(self, v: float, w: float, name: str | None = None, frame: str = "base_link",
              vy: float = 0.0) -> None:
        """One command: linear.x v (m/s), linear.y vy, angular.z w (rad/s) to robot name (the
        first robot by default), in the body frame ``frame``."""
        msg = TwistStamped()
        msg.header.frame_id = frame
        msg.twist.linear.x, msg.twist.linear.y, msg.twist.angular.z = v, vy, w
        self.robot_cmds[name or self.names[0]].publish(msg)

    def drive_until(self, v: float, w: float, pred, what: str, node: Running) -> None:
        """Sends (v, w) every 0.05 s, as a controller does (a command older than the node's
        cmd_vel_timeout stops the robot), until pred() holds."""
        last = [-1.0]

        def check():
            if time.monotonic() - last[0] >= 0.05:
                self.drive(v, w)
                last[0] = time.monotonic()
            return pred()
        self.spin_until(check, WAIT_S, what, node)

    def place(self, x: float, y: float, yaw: float) -> None:
        """An initial pose (m, m, rad) in map for the first robot."""
        msg = PoseWithCovarianceStamped()
        msg.header.frame_id = "map"
        msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
        msg.pose.pose.orientation.z = math.sin(yaw / 2)
        msg.pose.pose.orientation.w = math.cos(yaw / 2)
        self.initialpose.publish(msg)


@contextmanager
def robot_probe(names: tuple[str, ...] = ("bot",)) -> Iterator[RobotProbe]:
    """A RobotProbe of names in a context of its own, closed on exit."""
    context = rclpy.Context()
    rclpy.init(context=context)
    p = RobotProbe(context, names)
    try:
        yield p
    finally:
        p.close()
        rclpy.shutdown(context=context)


def start(installed: tuple[Path, dict[str, str]], tmp_path: Path, probe: RobotProbe,
          scene: dict, params: dict[str, Any]) -> Running:
    """sweep_node on ``scene`` (written to tmp_path) with ``params``, once it subscribes to
    every robot's topics and each robot's first odometry has arrived; stopped if it never
    gets there."""
    scene_path = tmp_path / "scene.yaml"
    scene_path.write_text(yaml.safe_dump(scene))
    node = Running(installed, tmp_path, dict(params, scene=str(scene_path)))
    try:  # a node that never comes up is stopped, not left running
        probe.connect(node)
        for pub in (*probe.robot_cmds.values(), *probe.initialposes.values()):
            probe.spin_until(lambda p=pub: p.get_subscription_count() > 0, DISCOVERY_S,
                             f"sweep_node subscribing {pub.topic_name}", node)
        for name, odom in probe.odoms.items():
            probe.spin_until(lambda o=odom: o, DISCOVERY_S, f"the first odometry of {name}",
                             node)
    except BaseException:
        node.stop(signal.SIGINT)
        raise
    return node


def stamp_ns(msg: Any) -> int:
    """A message's header stamp, ns."""
    return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


def verdict_on(probe: RobotProbe, n: int, node: Running,
               topic: str = "/bot/initialpose") -> dict[str, str]:
    """The n-th final verdict (applied or refused) on topic."""
    def got():
        final = [v for v in probe.verdicts if v["topic"] == topic
                 and v["verdict"] in ("applied", "refused")]
        return final[n - 1] if len(final) >= n else None
    return probe.spin_until(got, WAIT_S, f"verdict {n} on {topic}", node)
