"""sweep_robot_controller: drives one robot of a sweep_node over its ROS topics with the bundled
pursuit controller (sweep_core's ``Pursuit``: along the geodesic field to the robot's goal,
slowing for the scan's nearest return), as any external controller (Nav2's) would.

    sweep_robot_controller --ros-args -p scene:=room.yaml -p robot:=bot

It reads the scene (the same file as the node's, for the walls and the robot's goal, radius and
limits), subscribes to ``ROBOT/odom`` and ``ROBOT/scan`` and, at every odometry message, sends
the controller's command on ``ROBOT/cmd_vel`` (TwistStamped, or Twist with
``enable_stamped_cmd_vel: false``), stamped with the odometry's time. Names are relative, so a
namespace or remapping applies as for the node.
"""
from __future__ import annotations

import os
import sys
from typing import Any

import numpy as np
import rclpy
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import LaserScan

from sweep_core import SceneError
from sweep_core.io import cdr
from sweep_core.model.scene import Scene, load_scene
from sweep_core.numerics.robots.control import Observation, Pursuit
from sweep_core.numerics.robots.scan import Scan

NODE_NAME = "sweep_robot_controller"


def pick_robot(scene: Scene, name: str) -> Any:
    """The scene's robot ``name`` (empty: its only robot); SceneError naming the choices."""
    robots = scene.robots
    if not robots:
        raise SceneError("robots", "the scene has no robot", "add a robots: block")
    if not name:
        if len(robots) > 1:
            raise SceneError("robot", f"the scene has {len(robots)} robots "
                             f"({', '.join(r.name for r in robots)})",
                             "choose one with -p robot:=NAME")
        return robots[0]
    for r in robots:
        if r.name == name:
            return r
    raise SceneError("robot", f"no robot {name!r} in the scene (its robots: "
                     f"{', '.join(r.name for r in robots)})", "choose one of them")


class ControllerNode(Node):
    """Pursuit of one robot's goal over its topics (see the module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        scene_file = self.declare_parameter("scene", "").value
        name = self.declare_parameter("robot", "").value
        self.stamped = bool(self.declare_parameter("enable_stamped_cmd_vel", True).value)
        self.base_frame = self.declare_parameter("base_frame_id", "base_link").value
        self.scene = load_scene(os.path.expanduser(scene_file))
        self.robot = pick_robot(self.scene, name)
        if len(self.scene.robots) > 1:
            self.base_frame = f"{self.robot.name}/{self.base_frame}"
        self.controller = Pursuit(self.scene, self.robot)
        self.scan: cdr.LaserScan | None = None
        self.sent = 0
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        ns = self.robot.name
        self.pub = self.create_publisher(TwistStamped if self.stamped else Twist,
                                         f"{ns}/cmd_vel", qos)
        self.create_subscription(LaserScan, f"{ns}/scan", self._on_scan, qos, raw=True)
        self.create_subscription(Odometry, f"{ns}/odom", self._on_odom, qos, raw=True)
        self.get_logger().info(f"driving robot {ns!r} to its goal "
                               f"{list(self.robot.goal) if self.robot.goal is not None else None}")

    def _on_scan(self, raw: bytes) -> None:
        self.scan = cdr.decode_laser_scan(bytes(raw))

    def _on_odom(self, raw: bytes) -> None:
        odom = cdr.decode_odometry(bytes(raw))
        pose = (float(odom.position[0]), float(odom.position[1]), odom.yaw)
        twist = (float(odom.linear[0]), float(odom.linear[1]), float(odom.angular[2]))
        t = odom.stamp_ns * 1e-9
        scan = None
        if self.scan is not None and self.robot.scan is not None:
            # the scan's beams are the scene's (its spec); taken from the pose of this odometry
            scan = Scan(self.scan.stamp_ns * 1e-9, -1, pose,
                        np.asarray(self.scan.ranges, dtype=np.float64), self.robot.scan)
        obs = Observation(t, pose, twist, scan, self.robot.goal, self.robot.goal_radius,
                          self.robot.radius)
        vx, vy, wz = self.controller(obs)
        if self.stamped:
            self.pub.publish(cdr.encode_twist_stamped(odom.stamp_ns, self.base_frame,
                                                      (vx, vy, wz)))
        else:
            msg = Twist()
            msg.linear.x, msg.linear.y, msg.angular.z = float(vx), float(vy), float(wz)
            self.pub.publish(msg)
        self.sent += 1


def main(args: list[str] | None = None) -> int:
    """Entry point of ``sweep_robot_controller``."""
    rclpy.init(args=args)
    node = None
    try:
        node = ControllerNode()
        rclpy.spin(node)
    except (SceneError, ValueError) as err:  # the scene, the robot, or a robot without goal
        print(f"{NODE_NAME}: error: {err}", file=sys.stderr)
        return 2
    except (KeyboardInterrupt, ExternalShutdownException):
        # Ctrl-C or a SIGINT/SIGTERM: rclpy's handler may shut the context down while spin
        # waits, which it reports as ExternalShutdownException rather than KeyboardInterrupt
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
