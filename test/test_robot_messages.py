"""sweep_ros.robot_messages: a robot's cmd_vel and initialpose parsed and checked, its frames;
pure functions, no DDS."""
from __future__ import annotations

import math

import pytest
from geometry_msgs.msg import PoseWithCovarianceStamped, Twist, TwistStamped, Vector3

from sweep_ros.messages import CommandError
from sweep_ros.robot_messages import initial_pose, robot_frames, velocity_command


def test_twist_and_twist_stamped_give_the_body_frame_command():
    twist = Twist(linear=Vector3(x=0.5, y=-0.25, z=0.0), angular=Vector3(z=0.75))
    assert velocity_command(twist, False, "base_link", "/r/cmd_vel") == (0.5, -0.25, 0.75)
    stamped = TwistStamped(twist=twist)
    stamped.header.frame_id = "base_link"
    assert velocity_command(stamped, True, "base_link", "/r/cmd_vel") == (0.5, -0.25, 0.75)
    stamped.header.frame_id = ""
    assert velocity_command(stamped, True, "base_link", "/r/cmd_vel") == (0.5, -0.25, 0.75)


def test_bad_commands_are_refused_naming_the_field_and_the_fix():
    stamped = TwistStamped()
    stamped.header.frame_id = "odom"
    with pytest.raises(CommandError, match=r"/r/cmd_vel: header.frame_id 'odom' is not the "
                                           r"robot's base frame 'base_link' \(fix: "):
        velocity_command(stamped, True, "base_link", "/r/cmd_vel")
    for bad in (Twist(linear=Vector3(x=math.nan)), Twist(angular=Vector3(x=math.inf))):
        with pytest.raises(CommandError, match=r"non-finite component .* \(fix: send finite"):
            velocity_command(bad, False, "base_link", "/r/cmd_vel")


def pose(x: float, y: float, qz: float, qw: float, frame: str = "map", qx: float = 0.0
         ) -> PoseWithCovarianceStamped:
    msg = PoseWithCovarianceStamped()
    msg.header.frame_id = frame
    msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
    o = msg.pose.pose.orientation
    o.x, o.z, o.w = qx, qz, qw
    return msg


def test_initial_pose_reads_the_yaw_of_a_planar_quaternion():
    for yaw in (0.0, 0.5, -2.0, math.pi - 1e-3, -math.pi + 1e-3):
        x, y, got = initial_pose(pose(1.5, -2.0, math.sin(yaw / 2), math.cos(yaw / 2)), "map",
                                 "/r/initialpose")
        assert (x, y) == (1.5, -2.0) and got == pytest.approx(yaw, abs=1e-12)
    # an unnormalised quaternion names the same rotation; -q the same as q
    assert initial_pose(pose(0, 0, 2 * math.sin(0.3), 2 * math.cos(0.3)), "map", "t")[2] == \
        pytest.approx(0.6, abs=1e-12)
    assert initial_pose(pose(0, 0, -math.sin(0.3), -math.cos(0.3)), "map", "t")[2] == \
        pytest.approx(0.6, abs=1e-12)


def test_a_huge_quaternion_gives_the_yaw_it_names():
    """Components near 1e200 (their squares overflow): the yaw of the rotation they name, and a
    roll as large as the yaw refused (the yaw was NaN, refused later as 'must be finite',
    a value the message did not hold)."""
    assert initial_pose(pose(1.0, 2.0, 1e200, 1e200), "map", "t") == \
        (1.0, 2.0, initial_pose(pose(1.0, 2.0, 1.0, 1.0), "map", "t")[2])
    assert initial_pose(pose(0, 0, -3e300, 1e300), "map", "t")[2] == \
        initial_pose(pose(0, 0, -3.0, 1.0), "map", "t")[2]
    with pytest.raises(CommandError, match="is not a rotation about z"):
        initial_pose(pose(0, 0, 1e200, 1e200, qx=1e200), "map", "t")


def test_a_quaternion_too_small_is_refused_with_its_norm():
    """(0, 0, 1e-12, 1e-12) is not all zero: the refusal gives its norm and the bound (it
    told the sender to send a quaternion 'not all zero')."""
    with pytest.raises(CommandError) as err:
        initial_pose(pose(0, 0, 1e-12, 1e-12), "map", "/r/initialpose")
    text = str(err.value)
    assert "norm 1.41e-12 is below 1e-09" in text and "not all zero" not in text, text


def test_bad_initial_poses_are_refused_naming_the_field_and_the_fix():
    cases = [(pose(0, 0, 0, 1, frame="odom"), r"header.frame_id 'odom' is not the map frame"),
             (pose(math.nan, 0, 0, 1), r"non-finite pose"),
             (pose(2e4, 0, 0, 1), r"more than 10000 m from the origin"),
             (pose(0, 0, 0, 0), r"is not a rotation about z"),
             (pose(0, 0, 0, 1, qx=0.1), r"is not a rotation about z")]
    for msg, match in cases:
        with pytest.raises(CommandError, match=r"^/r/initialpose: .*" + match + r".* \(fix: "):
            initial_pose(msg, "map", "/r/initialpose")


def test_frames_are_plain_for_one_robot_and_namespaced_for_several():
    one = robot_frames("bot", 1, "map", "odom", "base_link")
    assert (one.map, one.odom, one.base) == ("map", "odom", "base_link")
    two = robot_frames("bot", 2, "world", "odom", "base_footprint")
    assert (two.map, two.odom, two.base) == ("world", "bot/odom", "bot/base_footprint")
