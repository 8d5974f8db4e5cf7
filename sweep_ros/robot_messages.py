"""A robot's commands from ROS messages, as pure functions (no node, no engine state).

* :func:`velocity_command`: geometry_msgs/TwistStamped (or Twist) on ``NAME/cmd_vel`` to the
  body-frame command (vx forward, vy to the left, wz counter-clockwise), as Nav2's controller
  server sends it: finite components, the stamped header's frame empty or the robot's base
  frame.
* :func:`initial_pose`: geometry_msgs/PoseWithCovarianceStamped on ``NAME/initialpose`` to the
  pose (x, y, yaw) in the map frame, as RViz's "2D Pose Estimate" sends it.
* :class:`Frames`: the robot's frame names (REP 105: map -> odom -> base_link).

Anything malformed raises :class:`~sweep_ros.messages.CommandError` naming the field, the value
and the fix, and never reaches the engine.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from sweep_core.errors import show
from sweep_core.model import elementary
from sweep_ros.messages import (
    MAX_COORDINATE,
    MIN_QUATERNION_NORM,
    CommandError,
    bounded_quaternion,
)

#: largest |roll| or |pitch| quaternion component of a pose taken as planar (relative to its norm)
PLANAR_TOLERANCE = 1e-6


@dataclass(frozen=True)
class Frames:
    """A robot's frame names: ``map`` (the node's frame_id), ``odom`` and ``base``."""

    map: str
    odom: str
    base: str


def robot_frames(name: str, n_robots: int, map_frame: str, odom_frame: str,
                 base_frame: str) -> Frames:
    """The frames of robot ``name``: ``odom_frame`` and ``base_frame`` as they are when the
    scene has one robot, prefixed ``NAME/`` when it has several (one TF tree per robot under
    the shared map frame)."""
    if n_robots == 1:
        return Frames(map_frame, odom_frame, base_frame)
    return Frames(map_frame, f"{name}/{odom_frame}", f"{name}/{base_frame}")


def velocity_command(msg: Any, stamped: bool, base_frame: str, topic: str
                     ) -> tuple[float, float, float]:
    """(vx, vy, wz): linear.x and linear.y (m/s, in the robot's base frame) and angular.z
    (rad/s) of a Twist or TwistStamped; the other components must be finite and are ignored
    (a planar robot). A stamped header's frame must be empty or ``base_frame`` (the frame Nav2's
    controller server stamps its commands with)."""
    if stamped:
        frame = msg.header.frame_id
        if frame not in ("", base_frame):
            raise CommandError(topic, f"header.frame_id {show(frame)} is not the robot's base frame "
                                      f"{base_frame!r} (fix: send the velocity in "
                                      f"{base_frame!r}, or an empty frame_id)")
        twist = msg.twist
    else:
        twist = msg
    values = [twist.linear.x, twist.linear.y, twist.linear.z,
              twist.angular.x, twist.angular.y, twist.angular.z]
    if not all(math.isfinite(v) for v in values):
        raise CommandError(topic, f"non-finite component in linear {show(values[:3])} / "
                                  f"angular {show(values[3:])} (fix: send finite numbers; "
                                  "linear.x, linear.y in m/s and angular.z in rad/s)")
    return float(twist.linear.x), float(twist.linear.y), float(twist.angular.z)


def initial_pose(msg: Any, map_frame: str, topic: str) -> tuple[float, float, float]:
    """(x, y, yaw) of a PoseWithCovarianceStamped (m, m, rad); the header's frame must be empty
    or ``map_frame`` (there is no TF lookup), the orientation a rotation about z, the position
    finite and within the scene's coordinate bound. The covariance is ignored (the pose is
    exact)."""
    frame = msg.header.frame_id
    if frame not in ("", map_frame):
        raise CommandError(topic, f"header.frame_id {show(frame)} is not the map frame "
                                  f"{map_frame!r} (fix: send the pose in {map_frame!r})")
    p, o = msg.pose.pose.position, msg.pose.pose.orientation
    quat = [o.x, o.y, o.z, o.w]
    if not all(math.isfinite(c) for c in [p.x, p.y, p.z] + quat):
        raise CommandError(topic, f"non-finite pose: position {show([p.x, p.y, p.z])}, "
                                  f"orientation {show(quat)} (fix: send finite numbers)")
    if max(abs(p.x), abs(p.y)) > MAX_COORDINATE:
        raise CommandError(topic, f"position {show([p.x, p.y])} is more than "
                                  f"{MAX_COORDINATE:g} m from the origin (fix: place the robot "
                                  "inside the scene)")
    qx, qy, qz, qw = bounded_quaternion(quat)
    norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    if norm < MIN_QUATERNION_NORM:
        raise CommandError(topic, f"orientation {show(quat)} is not a rotation about z: its "
                                  f"norm {norm:.3g} is below {MIN_QUATERNION_NORM:g} (fix: send "
                                  "a unit quaternion, x = y = 0, z = sin(yaw / 2), "
                                  "w = cos(yaw / 2))")
    if max(abs(qx), abs(qy)) > PLANAR_TOLERANCE * norm:
        raise CommandError(topic, f"orientation {show(quat)} is not a rotation about z (fix: "
                                  "send a planar pose, quaternion x = y = 0)")
    # yaw in (-pi, pi] of the rotation about z (the quaternion need not be normalised)
    return float(p.x), float(p.y), elementary.atan2(2.0 * qw * qz, qw * qw - qz * qz)
