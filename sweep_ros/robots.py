"""The robots' topics (:class:`RobotsMixin` of :class:`sweep_ros.node.SweepNode`), one namespace
per robot NAME of the scene, as Nav2 and nav2_loopback_sim expect them:

* ``NAME/cmd_vel`` in: geometry_msgs/TwistStamped (parameter ``enable_stamped_cmd_vel``, true)
  or Twist; the body-frame command (linear.x, linear.y, angular.z). Latest wins: the newest
  command drives the robot from the next step until another arrives or it is older than
  ``cmd_vel_timeout`` s of simulated time (then the robot is commanded to stop, as the loopback
  simulator does). The engine clips a command beyond the robot's limits; clipped commands are
  counted (diagnostics ``robot_commands_clipped``), malformed ones refused with a throttled
  warning and counted (``robot_commands_refused``). The command applied at each step is recorded
  on ``/NAME/cmd_vel`` (TwistStamped), so a recording replays whoever drove the robot.
* ``NAME/initialpose`` in: geometry_msgs/PoseWithCovarianceStamped places the robot between two
  steps, or is refused with the reason (it would overlap a person, a wall or another robot);
  each gets a verdict on ``command_result`` like the crowd's commands.
* ``NAME/odom`` out: nav_msgs/Odometry every published state (odom frame -> base frame).
* ``NAME/scan`` out: sensor_msgs/LaserScan at the scan's rate (the scene's robot block).
* ``/tf`` (odom -> base per robot) and ``/tf_static`` (map -> odom, identity) out through
  tf2_msgs when it is importable (a ROS distribution; it is not on PyPI); otherwise the node
  says so once at start. Both are recorded to the MCAP always.
"""
from __future__ import annotations

import json
import threading
from dataclasses import dataclass
from typing import Any

from geometry_msgs.msg import PoseWithCovarianceStamped, Twist, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import LaserScan

from sweep_core import SceneError
from sweep_core.io import cdr, robot_topics, topics
from sweep_core.model.scene import Scene
from sweep_ros import messages, results
from sweep_ros.robot_messages import Frames, initial_pose, robot_frames, velocity_command

try:  # a ROS distribution's; not on PyPI
    from tf2_msgs.msg import TFMessage
except ImportError:  # pragma: no cover - depends on the installation
    TFMessage = None

#: the robot names the node cannot give a namespace of their own (the crowd's commands use it)
RESERVED_NAMES = ("crowd",)
TF_TOPIC, TF_STATIC_TOPIC = robot_topics.TF, robot_topics.TF_STATIC


def robot_names(scene: Scene) -> tuple[str, ...]:
    """The names of the scene's robots (``robots:``), in order."""
    return tuple(r.name for r in scene.robots)


@dataclass
class RobotCommand:
    """The newest valid command of one robot: body-frame (vx, vy, wz) and the simulated time
    (s) it arrived at."""

    velocity: tuple[float, float, float]
    t: float


@dataclass
class RobotTopics:
    """One robot's endpoints and frames."""

    name: str
    spec: Any  # the scene's Robot
    frames: Frames
    sub_cmd_vel: Any
    sub_initialpose: Any
    pub_odom: Any
    pub_scan: Any


class RobotsMixin:
    """Robots of :class:`~sweep_ros.node.SweepNode` (its attributes are the node's)."""

    _p: dict[str, Any]

    def _create_robot_topics(self, names: tuple[str, ...], inbound: QoSProfile,
                             reliable: QoSProfile) -> None:
        """Subscriptions and publishers of every robot (relative names: namespaces apply)."""
        self._robot_lock = threading.Lock()
        self._robot_commands: dict[str, RobotCommand] = {}
        self._blocked_reported: dict[str, int] = {}  # blocked steps when diagnostics last spoke
        self.robot_counters = {"robot_commands_received": 0, "robot_commands_refused": 0,
                               "robot_poses_applied": 0, "robot_poses_refused": 0}
        stamped = bool(self._p["enable_stamped_cmd_vel"])
        cmd_type = TwistStamped if stamped else Twist
        self.robots: list[RobotTopics] = []
        for spec in self.scene.robots:
            name = spec.name
            frames = robot_frames(name, len(names), self.frame_id, self._p["odom_frame_id"],
                                  self._p["base_frame_id"])
            robot = RobotTopics(
                name, spec, frames,
                self.create_subscription(
                    cmd_type, f"{name}/cmd_vel",
                    lambda raw, info, n=name: self._on_robot_cmd_vel(n, raw, info),
                    inbound, raw=True),
                self.create_subscription(
                    PoseWithCovarianceStamped, f"{name}/initialpose",
                    lambda raw, info, n=name: self._on_initial_pose(n, raw, info),
                    inbound, raw=True),
                self.create_publisher(Odometry, f"{name}/odom", reliable),
                self.create_publisher(LaserScan, f"{name}/scan", reliable))
            self.robots.append(robot)
        self.pub_tf = self.pub_tf_static = None
        if names and TFMessage is not None:
            static = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                                durability=DurabilityPolicy.TRANSIENT_LOCAL)
            self.pub_tf = self.create_publisher(TFMessage, TF_TOPIC, reliable)
            self.pub_tf_static = self.create_publisher(TFMessage, TF_STATIC_TOPIC, static)
        elif names:
            self.get_logger().info(
                "tf2_msgs is not installed (it comes with a ROS distribution, not from PyPI): "
                f"{TF_TOPIC} and {TF_STATIC_TOPIC} are recorded, not published")

    # -- commands (executor thread) --------------------------------------------------------------
    def _robot(self, name: str) -> RobotTopics:
        return next(r for r in self.robots if r.name == name)

    def _on_robot_cmd_vel(self, name: str, raw: bytes, info: Any) -> None:
        robot = self._robot(name)
        topic = robot.sub_cmd_vel.topic_name
        stamped = bool(self._p["enable_stamped_cmd_vel"])
        with self._robot_lock:
            self.robot_counters["robot_commands_received"] += 1
        try:
            try:
                msg = deserialize_message(raw, TwistStamped if stamped else Twist)
            except Exception as err:  # noqa: BLE001 - any undecodable payload is refused
                raise messages.CommandError(topic, f"cannot decode ({err})") from err
            velocity = velocity_command(msg, stamped, robot.frames.base, topic)
        except messages.CommandError as err:
            with self._robot_lock:
                self.robot_counters["robot_commands_refused"] += 1
            self.get_logger().warning(f"command refused, {err}", throttle_duration_sec=2.0)
            return
        with self._robot_lock:
            self._robot_commands[name] = RobotCommand(velocity, self.sim.t)

    def _forget_robot_commands(self) -> None:
        """After a reset: the robots start again at rest, until new commands arrive."""
        with self._robot_lock:
            self._robot_commands.clear()

    def _robot_velocity(self, name: str, t: float) -> tuple[float, float, float]:
        """The command in effect for the step from t (s): the newest, or zero once it is older
        than ``cmd_vel_timeout`` s of simulated time (or none came). The caller holds the
        gate."""
        with self._robot_lock:
            cmd = self._robot_commands.get(name)
        if cmd is None or t - cmd.t > self._p["cmd_vel_timeout"]:
            return (0.0, 0.0, 0.0)
        return cmd.velocity

    def _on_initial_pose(self, name: str, raw: bytes, info: Any) -> None:
        """Places the robot between two steps, or refuses with the reason; a verdict either
        way (command_result), the accepted pose recorded for replay."""
        robot = self._robot(name)
        topic = robot.sub_initialpose.topic_name
        msg = None
        try:
            try:
                msg = deserialize_message(raw, PoseWithCovarianceStamped)
            except Exception as err:  # noqa: BLE001 - any undecodable payload is refused
                raise messages.CommandError(topic, f"cannot decode ({err})") from err
            pose = initial_pose(msg, self.frame_id, topic)
        except messages.CommandError as err:
            self._refuse_pose(topic, results.command_id(info, msg), str(err))
            return
        ident = results.command_id(info, msg)
        with self._gate.control():
            if self._closed:
                return
            try:
                self._place_robot(name, topic, pose)
            except SceneError as err:
                self._refuse_pose(topic, ident, f"{topic}: {err.problem}"
                                  + (f" (fix: {err.fix})" if err.fix else ""))
                return
            self.robot_counters["robot_poses_applied"] += 1
            log_ns = self._log_ns(self.sim.t)
            self._record(topic, log_ns, bytes(raw))
            self._verdict("applied", topic, ident,
                          f"robot {name} placed at ({pose[0]:g}, {pose[1]:g}), yaw "
                          f"{pose[2]:g} rad, from step {self.sim.n_steps} (t = "
                          f"{self.sim.t:g} s)", log_ns)
            # published with the next state (one state per step in the recording)

    def _refuse_pose(self, topic: str, ident: Any, why: str) -> None:
        with self._robot_lock:
            self.robot_counters["robot_poses_refused"] += 1
        self.get_logger().warning(f"initial pose refused, {why}")
        self._verdict("refused", topic, ident, why)

    # -- the engine (the caller holds the gate) ---------------------------------------------------
    def _place_robot(self, name: str, topic: str, pose: tuple[float, float, float]) -> None:
        """Puts the robot at pose between two steps, at rest (SceneError naming the overlap:
        the state is then unchanged), and records it for replay (``robot_pose_NNNNNN``:
        ``placement`` {robot, pose} before step ``step``). The state of the step before it
        is published first if it was not yet (a placement between two steps of a tick)."""
        self._publish_pending()
        self.sim.robots.place(name, pose, self.sim.t, self.sim.positions, self.sim.radii,
                              self.sim.ids)
        with self._robot_lock:  # the command before the placement is not carried over
            self._robot_commands.pop(name, None)
        if self.recorder is not None:
            k = self.robot_counters["robot_poses_applied"] + 1
            self.recorder.metadata(f"robot_pose_{k:06d}", {
                "topic": topic, "step": str(self.sim.n_steps), "t": repr(self.sim.t),
                "log_time_ns": str(self._log_ns(self.sim.t)),
                "placement": json.dumps({"robot": name, "pose": list(pose)})})

    def _command_robots(self) -> None:
        """Before a step: every robot's command in effect handed to the engine (clipped
        there to the robot's limits)."""
        for robot in self.robots:
            self.sim.robots.command(robot.name, self._robot_velocity(robot.name, self.sim.t))

    def _record_robot_step(self) -> None:
        """After a step: the command each robot applied in it on ``/NAME/cmd_vel`` (stamped
        with the step's end, as ``sweep run`` records it: replay re-applies these), and the
        scan when the step took one (published too)."""
        t = self.sim.t
        ns, log_ns = topics.stamp_ns(t), self._log_ns(t)
        for robot in self.robots:
            state = self.sim.robots.state(robot.name)
            self._record(robot_topics.topic(robot.name, "cmd_vel"), log_ns,
                         cdr.encode_twist_stamped(ns, robot.frames.base, state.command))
            scan = state.scan
            if scan is not None and scan.step == self.sim.n_steps:
                self._publish(robot.pub_scan, robot_topics.encode_scan(
                    topics.stamp_ns(scan.t), robot.frames.base, scan), log_ns)

    def _publish_robots(self, log_ns: int) -> None:
        """With the state: each robot's odometry, contacts and status, and the odom -> base
        transforms on /tf (recorded always, published when tf2_msgs is importable)."""
        if not self.robots:
            return
        t = self.sim.t
        ns = topics.stamp_ns(t)
        transforms = []
        for robot in self.robots:
            state = self.sim.robots.state(robot.name)
            f = robot.frames
            self._publish(robot.pub_odom, cdr.encode_odometry(ns, f.odom, f.base, state.pose,
                                                              state.twist), log_ns)
            self._record(robot_topics.topic(robot.name, "contacts"), log_ns,
                         robot_topics.encode_contacts(ns, self.frame_id, state))
            self._record(robot_topics.topic(robot.name, "status"), log_ns,
                         robot_topics.encode_status(ns, f.base, state))
            transforms.append(cdr.Transform.planar(ns, f.odom, f.base, *state.pose))
        self._publish_tf(self.pub_tf, TF_TOPIC, cdr.encode_tf_message(transforms), log_ns)

    def _publish_tf_static(self) -> None:
        """map -> odom (identity: the odometry is exact) per robot, once at start."""
        log_ns = self._log_ns(self.sim.t)
        ns = topics.stamp_ns(self.sim.t)
        data = cdr.encode_tf_message([cdr.Transform.planar(ns, r.frames.map, r.frames.odom,
                                                           0.0, 0.0, 0.0) for r in self.robots])
        self._publish_tf(self.pub_tf_static, TF_STATIC_TOPIC, data, log_ns)

    def _publish_tf(self, pub: Any, topic: str, data: bytes, log_ns: int) -> None:
        if pub is not None:
            pub.publish(data)
        self._record(topic, log_ns, data)

    def _robot_diagnostics(self) -> dict[str, Any]:
        """The robots' counters for diagnostics (none without robots): commands received,
        refused, clipped by the engine to the limits; poses applied and refused; steps in
        which a prescribed robot was stopped by a pinned crowd."""
        if not self.robots:
            return {}
        states = [self.sim.robots.state(r.name) for r in self.robots]
        with self._robot_lock:
            out: dict[str, Any] = dict(self.robot_counters)
        out["robot_commands_clipped"] = sum(int(s.clipped) for s in states)
        out["robot_blocked_steps"] = sum(int(s.blocked) for s in states)
        return out

    def _robot_stops(self, window_s: float) -> str | None:
        """What diagnostics say when a robot stopped since they last spoke: its commanded
        motion was refused (it would cut a wall, or push people who cannot give way) and it
        stopped instead; None otherwise. The caller holds the gate."""
        if not self.robots:
            return None
        stopped = []
        for r in self.robots:
            blocked = int(self.sim.robots.state(r.name).blocked)
            new = blocked - self._blocked_reported.get(r.name, 0)
            self._blocked_reported[r.name] = blocked  # a reset starts the count again
            if new > 0:
                stopped.append(f"{r.name} in {new} steps")
        if not stopped:
            return None
        return (f"robot {', '.join(stopped)} of the last {window_s:.1f} s stopped instead of "
                "moving as commanded: the motion would cut a wall or push people who cannot "
                "give way")

    def _robot_channels(self) -> dict[str, str]:
        """The recorded robot topics and their types."""
        out: dict[str, str] = {}
        for robot in self.robots:
            out[robot.pub_odom.topic_name] = cdr.ODOMETRY
            out[robot_topics.topic(robot.name, "cmd_vel")] = cdr.TWIST_STAMPED
            out[robot_topics.topic(robot.name, "contacts")] = cdr.POINT_CLOUD2
            out[robot_topics.topic(robot.name, "status")] = cdr.POINT_CLOUD2
            out[robot.sub_initialpose.topic_name] = cdr.POSE_WITH_COVARIANCE_STAMPED
            if robot.spec.scan is not None:
                out[robot.pub_scan.topic_name] = cdr.LASER_SCAN
        if self.robots:
            out[TF_TOPIC] = cdr.TF_MESSAGE
            out[TF_STATIC_TOPIC] = cdr.TF_MESSAGE
        return out
