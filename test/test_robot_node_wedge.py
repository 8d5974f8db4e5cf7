"""sweep_node with two prescribed robots driven into a wall one behind the other (the engine
used to wedge: the node paused in ERROR for good), and a map that cuts a robot where it is now
(refused naming the robot, old walls kept, the run going on). One node process; every wait is
on an event with a generous deadline, never on how fast the node steps."""
from __future__ import annotations

import signal

import numpy as np
import pytest
from robot_node import editable_installation, robot_probe, stamp_ns, start
from test_node import WAIT_S, diag_value

#: the issue's case: a at (5.0, 5), b at (5.65, 5), r = 0.3, a wall 0.05 m ahead of b (x = 6)
ROBOTS = [{"name": n, "radius": 0.3, "pose": [x, 5.0, 0.0], "weight": "inf",
           "kinematics": {"max_acceleration": 100.0}} for n, x in (("a", 5.0), ("b", 5.65))]
SCENE = {"name": "robots_at_a_wall", "agents": {"positions": [[1.0, 1.0]], "radius": 0.25},
         "noise": {"sigma": 0.0},
         "walls": [{"kind": "segment", "a": [6.0, 3.0], "b": [6.0, 7.0]}], "robots": ROBOTS}


def cutting_map():
    """An OccupancyGrid over [0, 10] x [0.02, 10.02] m of 0.04 m cells, free but for the cell
    [5.96, 6] x [4.98, 5.02]: clear of b's start (its disk reaches x = 5.95), inside its disk
    once it stands against the wall (x = 6)."""
    from nav_msgs.msg import OccupancyGrid

    cells = np.zeros((250, 250), dtype=np.int8)
    cells[124, 149] = 100
    msg = OccupancyGrid()
    msg.header.frame_id = "map"
    msg.info.resolution = 0.04
    msg.info.width, msg.info.height = 250, 250
    msg.info.origin.position.x, msg.info.origin.position.y = 0.0, 0.02
    msg.info.origin.orientation.w = 1.0
    msg.data = cells.ravel().tolist()
    return msg


@pytest.fixture(scope="module")
def installed():
    return editable_installation()


def test_robots_at_a_wall_never_pause_the_node_and_a_cutting_map_is_refused(installed,
                                                                            tmp_path):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    with robot_probe(("a", "b")) as probe:
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        map_pub = probe.node.create_publisher(type(cutting_map()), "/wedge_map", latched)
        node = start(installed, tmp_path, probe, SCENE, {
            "dt": 0.01, "seed": 1, "rate_hz": 50.0, "steps_per_tick": 2,
            "map_topic": "wedge_map", "cmd_vel_timeout": 100.0})
        try:
            for name in ("a", "b"):
                probe.drive(1.0, 0.0, name=name, frame=f"{name}/base_link")
            # b comes to rest against the wall, a against b; the node keeps stepping
            probe.spin_until(lambda: probe.odoms["b"][-1].pose.pose.position.x > 5.69,
                             WAIT_S, "b at the wall", node)
            n = len(probe.odoms["a"])
            probe.spin_until(lambda: len(probe.odoms["a"]) > n + 50, WAIT_S,
                             "the run going on with both robots stopped", node)
            a, b = probe.odoms["a"][-1].pose.pose.position, probe.odoms["b"][-1].pose.pose.position
            assert 0.6 - 1e-9 <= b.x - a.x and b.x <= 5.7 + 1e-9
            probe.spin_until(lambda: diag_value(probe, "paused") is not None, WAIT_S,
                             "diagnostics", node)
            assert diag_value(probe, "paused") == "false"
            assert probe.diagnostics[-1].status[0].level != b"\x02"  # not ERROR
            map_pub.publish(cutting_map())
            probe.spin_until(lambda: diag_value(probe, "map_refused") == "1", WAIT_S,
                             "the map cutting b refused", node)
            assert diag_value(probe, "maps_applied") == "0"
            t_refused = stamp_ns(probe.odoms["b"][-1])
            probe.spin_until(lambda: stamp_ns(probe.odoms["b"][-1]) > t_refused + 10**8,
                             WAIT_S, "the run going on after the refusal", node)
            assert node.alive()
        finally:
            code = node.stop(signal.SIGINT)
        assert code == 0, node.log
        assert "Traceback" not in node.log and "failed, simulation paused" not in node.log
        refusal = [line for line in node.log.splitlines() if "map refused" in line]
        assert len(refusal) == 1 and "robot b at" in refusal[0], node.log
