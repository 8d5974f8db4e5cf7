"""``sweep analyze`` of the robot in node recordings (docs/social_metrics.md): a robot placed
by ``NAME/initialpose`` is measured up to its first placement (the jump is no motion of the
robot), as a run is up to its first reset; its geodesic distance goes round the map the node
took from its map topic."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

rclpy = pytest.importorskip("rclpy")
import yaml  # noqa: E402
from geometry_msgs.msg import PoseWithCovarianceStamped, TwistStamped  # noqa: E402
from mcap_ros2.reader import read_ros2_messages  # noqa: E402
from nav_msgs.msg import OccupancyGrid  # noqa: E402
from node_process import node_in_process  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.serialization import serialize_message  # noqa: E402
from robot_scenes import small_scene  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402

from sweep_core.analysis import metrics  # noqa: E402
from sweep_core.io.recording import read_metadata  # noqa: E402

INFO = {"publisher_gid": {"data": bytes(24)}, "publication_sequence_number": 1,
        "reception_sequence_number": 1, "source_timestamp": 0, "received_timestamp": 0}


def test_a_placement_ends_the_robots_episode(tmp_path: Path) -> None:
    """The robot drives east for 10 steps, then is placed inside its goal radius: it did not
    reach its goal, and its path is what it drove (from its odometry up to the placement),
    not the jump to where it was put."""
    scene = dict(small_scene(), noise={"sigma": 0.0})
    path, rec = tmp_path / "scene.yaml", tmp_path / "run.mcap"
    path.write_text(yaml.safe_dump(scene))
    with node_in_process([Parameter("scene", value=str(path)), Parameter("dt", value=0.05),
                          Parameter("record", value=str(rec))]) as n:
        n._on_pause(SetBool.Request(data=True), SetBool.Response())
        cmd = TwistStamped()
        cmd.twist.linear.x = 0.5
        n._on_robot_cmd_vel("bot", bytes(serialize_message(cmd)), INFO)
        for _ in range(10):
            assert n._on_step(Trigger.Request(), Trigger.Response()).success
        pose = PoseWithCovarianceStamped()
        pose.header.frame_id = "map"
        pose.pose.pose.position.x, pose.pose.pose.position.y = 5.1, 1.5  # goal [5, 1.5], 0.3 m
        pose.pose.pose.orientation.w = 1.0
        n._on_initial_pose("bot", bytes(serialize_message(pose)), INFO)
        assert n.sim.robots.state("bot").pose[:2] == (5.1, 1.5)
        for _ in range(5):
            assert n._on_step(Trigger.Request(), Trigger.Response()).success
    placed_ns = int(read_metadata(rec)["robot_pose_000001"]["log_time_ns"])
    driven = [(m.ros_msg.pose.pose.position.x, m.ros_msg.pose.pose.position.y)
              for m in read_ros2_messages(str(rec), topics=["/bot/odom"])
              if m.log_time_ns <= placed_ns]
    length = sum(math.dist(a, b) for a, b in zip(driven, driven[1:]))
    assert 0.1 < length < 1.0  # it drove, less than the 4.6 m jump to the goal
    m = metrics.analyze(rec).summary["robots"]["bot"]
    assert m["reached_goal"] is False and m["time_to_goal_s"] is None
    assert m["frames"] == len(driven)
    assert m["path_length_m"] == pytest.approx(length, rel=1e-9)


def test_the_geodesic_goes_round_the_map_from_the_topic(tmp_path: Path) -> None:
    """A map from the node's map topic puts a pillar (x 2-2.5 m, y 1-2 m) on the straight
    4.5 m line from the robot's start [0.5, 1.5] to its goal [5, 1.5]: the geodesic distance
    analyze reports goes round it (> 4.7 m), not through it (4.5 m)."""
    scene = dict(small_scene(), noise={"sigma": 0.0})
    path, rec = tmp_path / "scene.yaml", tmp_path / "run.mcap"
    path.write_text(yaml.safe_dump(scene))
    grid = OccupancyGrid()
    grid.header.frame_id = "map"
    grid.info.width, grid.info.height, grid.info.resolution = 20, 10, 0.5
    grid.info.origin.position.x, grid.info.origin.position.y = -2.0, -1.0  # x -2..8, y -1..4
    grid.info.origin.orientation.w = 1.0
    cells = [0] * 200
    for i, j in ((8, 4), (8, 5)):  # the cells [2, 2.5] x [1, 1.5] and [2, 2.5] x [1.5, 2]
        cells[j * 20 + i] = 100
    grid.data = cells
    with node_in_process([Parameter("scene", value=str(path)), Parameter("dt", value=0.05),
                          Parameter("record", value=str(rec)),
                          Parameter("map_topic", value="map")]) as n:
        n._on_pause(SetBool.Request(data=True), SetBool.Response())
        n._on_map(bytes(serialize_message(grid)))
        assert n._maps_applied == 1
        for _ in range(5):
            assert n._on_step(Trigger.Request(), Trigger.Response()).success
    m = metrics.analyze(rec).summary["robots"]["bot"]
    assert m["geodesic_m"] > 4.7
