"""The robot's CDR messages (Odometry, TwistStamped, LaserScan, TFMessage,
PoseWithCovarianceStamped) against rosbags' serialisation (exact bytes: rosbags zero-fills
padding, as ours does), decoded back by rosbags and by our decoders; their message definitions
parsed by rosbags into the same field layout as its own typestore."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sweep_core.io import cdr
from sweep_core.model import elementary

STAMP = 1_234_567_891_011
FRAMES = ["", "m", "odom", "robot_1/base_link"]


@pytest.fixture(scope="module")
def ts():
    typesys = pytest.importorskip("rosbags.typesys")
    return typesys.get_typestore(typesys.Stores.ROS2_KILTED)


def _header(ts, stamp, frame):
    sec, nanosec = divmod(stamp, 10**9)
    return ts.types["std_msgs/msg/Header"](
        stamp=ts.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec), frame_id=frame)


def _vec(ts, x, y, z):
    return ts.types["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)


def _pose(ts, x, y, yaw):
    return ts.types["geometry_msgs/msg/Pose"](
        position=ts.types["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
        orientation=ts.types["geometry_msgs/msg/Quaternion"](
            x=0.0, y=0.0, z=elementary.sin(yaw / 2), w=elementary.cos(yaw / 2)))


def _twist(ts, vx, vy, w):
    return ts.types["geometry_msgs/msg/Twist"](linear=_vec(ts, vx, vy, 0.0),
                                               angular=_vec(ts, 0.0, 0.0, w))


@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("child", ["base_link", "r/base_link", ""])
def test_odometry(ts, frame, child):
    rng = np.random.default_rng(len(frame) + 7 * len(child))
    pose = rng.normal(size=3) * [10, 10, 3]
    twist = rng.normal(size=3)
    pcov, tcov = rng.normal(size=36), rng.normal(size=36)
    msg = ts.types[cdr.ODOMETRY](
        header=_header(ts, STAMP, frame), child_frame_id=child,
        pose=ts.types["geometry_msgs/msg/PoseWithCovariance"](pose=_pose(ts, *pose),
                                                              covariance=pcov),
        twist=ts.types["geometry_msgs/msg/TwistWithCovariance"](twist=_twist(ts, *twist),
                                                                covariance=tcov))
    ours = cdr.encode_odometry(STAMP, frame, child, pose, twist, pcov, tcov)
    assert ours == bytes(ts.serialize_cdr(msg, cdr.ODOMETRY))
    back = ts.deserialize_cdr(ours, cdr.ODOMETRY)
    assert back.child_frame_id == child and back.header.frame_id == frame
    odom = cdr.decode_odometry(ours)
    assert (odom.stamp_ns, odom.frame_id, odom.child_frame_id) == (STAMP, frame, child)
    np.testing.assert_array_equal(odom.position, [pose[0], pose[1], 0.0])
    assert odom.yaw == pytest.approx(math.remainder(pose[2], 2 * math.pi), abs=1e-12)
    np.testing.assert_array_equal(odom.linear, [twist[0], twist[1], 0.0])
    np.testing.assert_array_equal(odom.angular, [0.0, 0.0, twist[2]])
    np.testing.assert_array_equal(odom.pose_covariance, pcov)
    np.testing.assert_array_equal(odom.twist_covariance, tcov)


@pytest.mark.parametrize("frame", FRAMES)
def test_twist_stamped(ts, frame):
    twist = (0.5, -0.25, 1.0 / 3.0)
    msg = ts.types[cdr.TWIST_STAMPED](header=_header(ts, -STAMP, frame),
                                      twist=_twist(ts, *twist))
    ours = cdr.encode_twist_stamped(-STAMP, frame, twist)
    assert ours == bytes(ts.serialize_cdr(msg, cdr.TWIST_STAMPED))
    back = cdr.decode_twist_stamped(ours)
    assert (back.stamp_ns, back.frame_id) == (-STAMP, frame)
    np.testing.assert_array_equal(back.linear, [0.5, -0.25, 0.0])
    np.testing.assert_array_equal(back.angular, [0.0, 0.0, 1.0 / 3.0])
    # a foreign twist with every component set decodes as sent
    full = ts.types[cdr.TWIST_STAMPED](header=_header(ts, 5, frame), twist=ts.types[
        "geometry_msgs/msg/Twist"](linear=_vec(ts, 1, 2, 3), angular=_vec(ts, 4, 5, 6)))
    back = cdr.decode_twist_stamped(bytes(ts.serialize_cdr(full, cdr.TWIST_STAMPED)))
    assert back.linear.tolist() == [1, 2, 3] and back.angular.tolist() == [4, 5, 6]


@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("n, m", [(0, 0), (1, 0), (7, 7), (360, 0)])
def test_laser_scan(ts, frame, n, m):
    rng = np.random.default_rng(n + m)
    ranges = rng.uniform(0.1, 10, n).astype(np.float32)
    if n > 2:
        ranges[1] = np.inf
    intensities = rng.uniform(0, 1, m).astype(np.float32)
    scan = cdr.LaserScan(STAMP, frame, -math.pi, math.pi, 2 * math.pi / 360, 1e-4, 0.1, 0.05,
                         30.0, ranges, intensities)
    msg = ts.types[cdr.LASER_SCAN](
        header=_header(ts, STAMP, frame), angle_min=-math.pi, angle_max=math.pi,
        angle_increment=2 * math.pi / 360, time_increment=1e-4, scan_time=0.1, range_min=0.05,
        range_max=30.0, ranges=ranges, intensities=intensities)
    ours = cdr.encode_laser_scan(scan)
    assert ours == bytes(ts.serialize_cdr(msg, cdr.LASER_SCAN))
    back = cdr.decode_laser_scan(ours)
    np.testing.assert_array_equal(back.ranges, ranges)
    np.testing.assert_array_equal(back.intensities, intensities)
    assert back.angle_increment == np.float32(2 * math.pi / 360)
    assert (back.stamp_ns, back.frame_id, back.range_max) == (STAMP, frame, 30.0)


@pytest.mark.parametrize("count", [0, 1, 3])
def test_tf_message(ts, count):
    frames = [("odom", "base_link"), ("map", "r1/odom"), ("", "x")][:count]
    tfs = [cdr.Transform.planar(STAMP + k, a, b, 1.5 * k, -2.0, 0.3 * k)
           for k, (a, b) in enumerate(frames)]
    msg = ts.types[cdr.TF_MESSAGE](transforms=[
        ts.types["geometry_msgs/msg/TransformStamped"](
            header=_header(ts, tf.stamp_ns, tf.frame_id), child_frame_id=tf.child_frame_id,
            transform=ts.types["geometry_msgs/msg/Transform"](
                translation=_vec(ts, *tf.translation),
                rotation=ts.types["geometry_msgs/msg/Quaternion"](*tf.rotation)))
        for tf in tfs])
    ours = cdr.encode_tf_message(tfs)
    assert ours == bytes(ts.serialize_cdr(msg, cdr.TF_MESSAGE))
    back = cdr.decode_tf_message(ours)
    assert [(t.stamp_ns, t.frame_id, t.child_frame_id) for t in back] == [
        (t.stamp_ns, t.frame_id, t.child_frame_id) for t in tfs]
    for a, b in zip(back, tfs):
        np.testing.assert_array_equal(a.translation, b.translation)
        assert a.yaw == pytest.approx(b.yaw, abs=1e-12)


@pytest.mark.parametrize("frame", FRAMES)
def test_pose_with_covariance_stamped(ts, frame):
    cov = np.arange(36.0)
    msg = ts.types[cdr.POSE_WITH_COVARIANCE_STAMPED](
        header=_header(ts, STAMP, frame),
        pose=ts.types["geometry_msgs/msg/PoseWithCovariance"](pose=_pose(ts, 1.0, 2.0, -2.5),
                                                              covariance=cov))
    ours = cdr.encode_pose_with_covariance_stamped(STAMP, frame, (1.0, 2.0, -2.5), cov)
    assert ours == bytes(ts.serialize_cdr(msg, cdr.POSE_WITH_COVARIANCE_STAMPED))
    back = cdr.decode_pose_with_covariance_stamped(ours)
    assert back.yaw == pytest.approx(-2.5, abs=1e-12)
    np.testing.assert_array_equal(back.covariance, cov)


@pytest.mark.parametrize("msgtype", [cdr.ODOMETRY, cdr.TWIST_STAMPED, cdr.LASER_SCAN,
                                     cdr.TF_MESSAGE, cdr.POSE_WITH_COVARIANCE_STAMPED])
def test_definitions_parse_to_the_typestore_layout(ts, msgtype):
    """Our schema text, parsed by rosbags, gives every type the fields of rosbags' own."""
    from rosbags.typesys import get_types_from_msg

    text = cdr.SCHEMAS[msgtype]
    sep = "\n" + "=" * 80 + "\n"
    sections = text.split(sep)
    types = dict(get_types_from_msg(sections[0], msgtype))
    for section in sections[1:]:
        head, body = section.split("\n", 1)
        pkg, name = head.removeprefix("MSG: ").split("/")
        types.update(get_types_from_msg(body, f"{pkg}/msg/{name}"))
    for name, (_consts, fields) in types.items():
        assert [f[0] for f in fields] == [f[0] for f in ts.fielddefs[name][1]], name
        assert fields == ts.fielddefs[name][1], name


def test_bad_values_are_named():
    with pytest.raises(ValueError, match="twist"):
        cdr.encode_twist_stamped(0, "m", (1.0, float("nan"), 0.0))
    with pytest.raises(ValueError, match="pose"):
        cdr.encode_odometry(0, "m", "b", (1.0, 2.0), (0, 0, 0))
    with pytest.raises(ValueError, match="truncated"):
        cdr.decode_odometry(cdr.encode_odometry(0, "m", "b", (1, 2, 3), (0, 0, 0))[:-8])
