"""A robot's inputs to sweep_node in this process (its callbacks fed serialised messages, the
node paused and stepped by its step service): what a robotics user may send on NAME/cmd_vel
and NAME/initialpose."""
from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

rclpy = pytest.importorskip("rclpy")
import yaml  # noqa: E402
from geometry_msgs.msg import TwistStamped  # noqa: E402
from node_process import node_in_process  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.serialization import serialize_message  # noqa: E402
from robot_scenes import small_scene  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402

from sweep_ros.node import SweepNode  # noqa: E402

INFO = {"publisher_gid": {"data": bytes(24)}, "publication_sequence_number": 1,
        "reception_sequence_number": 1, "source_timestamp": 0, "received_timestamp": 0}


@pytest.fixture
def node(tmp_path: Path) -> Iterator[SweepNode]:
    """The node on small_scene() with the bundled pursuit controller in the scene, paused."""
    scene = dict(small_scene(), noise={"sigma": 0.0})
    scene["robots"][0]["controller"] = "pursuit"
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(scene))
    with node_in_process([Parameter("scene", value=str(path)),
                          Parameter("dt", value=0.05)]) as n:
        n._on_pause(SetBool.Request(data=True), SetBool.Response())
        yield n


def step(n: SweepNode, k: int) -> None:
    for _ in range(k):
        assert n._on_step(Trigger.Request(), Trigger.Response()).success


def drive(n: SweepNode, vx: float, wz: float) -> None:
    msg = TwistStamped()
    msg.twist.linear.x, msg.twist.angular.z = vx, wz
    n._on_robot_cmd_vel("bot", bytes(serialize_message(msg)), INFO)


def pose(n: SweepNode) -> Any:
    return n.sim.robots.state("bot").pose


def test_a_scene_controller_does_not_override_the_robots_commands(node: SweepNode) -> None:
    """The robot follows its cmd_vel only: without a command it stays where it is, with a
    command to turn on the spot it turns there (the scene's pursuit would drive it east to its
    goal)."""
    start = pose(node)
    step(node, 5)
    assert pose(node) == start
    drive(node, 0.0, 1.0)
    step(node, 5)
    x, y, yaw = pose(node)
    assert (x, y) == start[:2] and yaw > 0.1 and math.isfinite(yaw)
