"""sweep_core.cdr against rclpy (Fast-CDR) and rosbags serialisation, plus round trips.

Fast-CDR leaves alignment padding uninitialised (random bytes), so the comparison with rclpy is
exact on every non-padding byte, zero on our padding bytes, equal in length, and rclpy must
deserialise our bytes to the original message. rosbags zero-fills padding, so the comparison
with rosbags is exact byte for byte.
"""
from __future__ import annotations

import math
import os
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from sweep_core.io import cdr
from sweep_core.model import elementary

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "OFF")
os.environ.setdefault("ROS_DOMAIN_ID", "57")

FRAME_IDS = ["", "m", "map", "odom", "world_frame_long"]  # lengths 0, 1, 3, 4, 16
SIZES = [0, 1, 7, 1000]
FIELD_SETS = [
    ["x"],
    ["x", "y", "z"],
    ["x", "y", "z", "vx", "vy", "radius", "speed_ratio", "p"],  # 8 fields, mixed name lengths
]


def _align(off: int, n: int) -> int:
    return off + (-off % n)


# ---------------------------------------------------------------------------------------------
# Independent layout oracle: which bytes of a buffer are alignment padding.
# Offsets are relative to the payload (after the 4-byte encapsulation header).
# ---------------------------------------------------------------------------------------------


def _pad(mask: np.ndarray, start: int, align: int) -> int:
    end = _align(start, align)
    mask[4 + start : 4 + end] = True
    return end


def _pose_array_padding(total: int, frame_id: str, n: int) -> np.ndarray:
    mask = np.zeros(total, dtype=bool)
    off = 12 + len(frame_id.encode()) + 1
    off = _pad(mask, off, 4) + 4
    if n:
        _pad(mask, off, 8)
    return mask


def _cloud_padding(total: int, frame_id: str, names: list[str]) -> np.ndarray:
    mask = np.zeros(total, dtype=bool)
    off = 12 + len(frame_id.encode()) + 1
    off = _pad(mask, off, 4) + 12  # height, width, fields length
    for name in names:
        off += 4 + len(name.encode()) + 1
        off = _pad(mask, off, 4) + 4 + 1  # offset, datatype
        off = _pad(mask, off, 4) + 4  # count
    off += 1  # is_bigendian
    _pad(mask, off, 4)
    return mask


def _assert_same_cdr(ours: bytes, theirs: bytes, padding: np.ndarray) -> None:
    assert len(ours) == len(theirs)
    a = np.frombuffer(ours, dtype=np.uint8)
    b = np.frombuffer(theirs, dtype=np.uint8)
    assert a[:4].tobytes() == b"\x00\x01\x00\x00"
    differ = np.flatnonzero(a != b)
    assert padding[differ].all(), f"non-padding bytes differ at {differ[~padding[differ]][:10]}"
    assert not a[padding].any(), "our padding bytes must be zero"


# ---------------------------------------------------------------------------------------------
# Test data
# ---------------------------------------------------------------------------------------------


def _positions(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(-50.0, 50.0, size=(n, 2))


def _yaw(n: int, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(-math.pi, math.pi, size=n)


def _cloud_fields(names: list[str], n: int, seed: int = 2) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {name: rng.normal(size=n).astype(np.float32) for name in names}


STAMP = 1_700_000_123_456_789_012 // 1000  # 1.7e15 ns: sec and nanosec both non-trivial


# ---------------------------------------------------------------------------------------------
# rclpy comparison
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def rclpy_ser():
    ser = pytest.importorskip("rclpy.serialization")
    pytest.importorskip("geometry_msgs.msg")
    pytest.importorskip("sensor_msgs.msg")
    pytest.importorskip("rosgraph_msgs.msg")
    return ser


def _rclpy_pose_array(stamp_ns, frame_id, pos, yaw):
    from geometry_msgs.msg import Pose, PoseArray

    msg = PoseArray()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 10**9)
    msg.header.frame_id = frame_id
    poses = []
    for i in range(pos.shape[0]):
        p = Pose()
        p.position.x = float(pos[i, 0])
        p.position.y = float(pos[i, 1])
        if yaw is not None:
            p.orientation.z = elementary.sin(0.5 * yaw[i])
            p.orientation.w = elementary.cos(0.5 * yaw[i])
        poses.append(p)
    msg.poses = poses
    return msg


def _rclpy_cloud(stamp_ns, frame_id, fields, is_dense=True):
    from sensor_msgs.msg import PointCloud2, PointField

    names = list(fields)
    n = len(fields[names[0]])
    msg = PointCloud2()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 10**9)
    msg.header.frame_id = frame_id
    msg.height = 1
    msg.width = n
    msg.fields = [
        PointField(name=name, offset=4 * i, datatype=PointField.FLOAT32, count=1)
        for i, name in enumerate(names)
    ]
    msg.is_bigendian = False
    msg.point_step = 4 * len(names)
    msg.row_step = msg.point_step * n
    msg.data = np.stack([np.asarray(fields[k], np.float32) for k in names], axis=1).tobytes()
    msg.is_dense = is_dense
    return msg


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("frame_id", FRAME_IDS)
@pytest.mark.parametrize("with_yaw", [False, True])
def test_pose_array_matches_rclpy(rclpy_ser, n, frame_id, with_yaw):
    from geometry_msgs.msg import PoseArray

    pos = _positions(n)
    yaw = _yaw(n) if with_yaw else None
    ours = cdr.encode_pose_array(STAMP, frame_id, pos, yaw)
    msg = _rclpy_pose_array(STAMP, frame_id, pos, yaw)
    theirs = rclpy_ser.serialize_message(msg)
    _assert_same_cdr(ours, theirs, _pose_array_padding(len(ours), frame_id, n))
    assert rclpy_ser.deserialize_message(ours, PoseArray) == msg


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("frame_id", FRAME_IDS)
@pytest.mark.parametrize("names", FIELD_SETS, ids=lambda f: f"{len(f)}fields")
def test_point_cloud2_matches_rclpy(rclpy_ser, n, frame_id, names):
    from sensor_msgs.msg import PointCloud2

    fields = _cloud_fields(names, n)
    ours = cdr.encode_point_cloud2(STAMP, frame_id, fields)
    msg = _rclpy_cloud(STAMP, frame_id, fields)
    theirs = rclpy_ser.serialize_message(msg)
    _assert_same_cdr(ours, theirs, _cloud_padding(len(ours), frame_id, names))
    assert rclpy_ser.deserialize_message(ours, PointCloud2) == msg


@pytest.mark.parametrize("stamp", [0, 1, 999_999_999, 10**9, STAMP, -1, -(2**31) * 10**9,
                                   2**31 * 10**9 - 1])
def test_clock_matches_rclpy(rclpy_ser, stamp):
    from rosgraph_msgs.msg import Clock

    msg = Clock()
    msg.clock.sec, msg.clock.nanosec = divmod(stamp, 10**9)
    ours = cdr.encode_clock(stamp)
    assert ours == rclpy_ser.serialize_message(msg)  # no padding in Clock: exact
    assert cdr.decode_clock(ours) == stamp


def test_decoders_read_rclpy_bytes_with_garbage_padding(rclpy_ser):
    """rclpy's padding bytes are not zero; the decoders must not depend on them."""
    pos = _positions(7, seed=5)
    yaw = _yaw(7, seed=6)
    raw = rclpy_ser.serialize_message(_rclpy_pose_array(STAMP, "ab", pos, yaw))
    stamp, frame, got = cdr.decode_pose_array(raw)
    assert (stamp, frame) == (STAMP, "ab")
    np.testing.assert_array_equal(got, pos)
    fields = _cloud_fields(FIELD_SETS[2], 9)
    fields["p"][3] = np.nan
    raw = rclpy_ser.serialize_message(_rclpy_cloud(STAMP, "abc", fields, is_dense=False))
    cloud = cdr.decode_point_cloud2(raw)
    assert (cloud.stamp_ns, cloud.frame_id, cloud.height, cloud.width) == (STAMP, "abc", 1, 9)
    assert cloud.is_dense is False
    assert list(cloud.fields) == FIELD_SETS[2]
    for k, v in fields.items():
        np.testing.assert_array_equal(cloud.fields[k], v)


# ---------------------------------------------------------------------------------------------
# rosbags comparison (exact bytes) and decoding
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def typestore():
    typesys = pytest.importorskip("rosbags.typesys")
    store = getattr(typesys.Stores, "ROS2_KILTED", None) or typesys.Stores.LATEST
    return typesys.get_typestore(store)


def _rb_header(ts, stamp_ns, frame_id):
    t = ts.types["builtin_interfaces/msg/Time"]
    h = ts.types["std_msgs/msg/Header"]
    sec, nanosec = divmod(stamp_ns, 10**9)
    return h(stamp=t(sec=sec, nanosec=nanosec), frame_id=frame_id)


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("frame_id", FRAME_IDS)
@pytest.mark.parametrize("with_yaw", [False, True])
def test_pose_array_matches_rosbags(typestore, n, frame_id, with_yaw):
    ts = typestore
    pose_t = ts.types["geometry_msgs/msg/Pose"]
    point_t = ts.types["geometry_msgs/msg/Point"]
    quat_t = ts.types["geometry_msgs/msg/Quaternion"]
    pos = _positions(n, seed=3)
    yaw = _yaw(n, seed=4) if with_yaw else None
    poses = []
    for i in range(n):
        qz, qw = (0.0, 1.0) if yaw is None else (elementary.sin(0.5 * yaw[i]), elementary.cos(0.5 * yaw[i]))
        poses.append(pose_t(position=point_t(x=pos[i, 0], y=pos[i, 1], z=0.0),
                            orientation=quat_t(x=0.0, y=0.0, z=qz, w=qw)))
    msg = ts.types[cdr.POSE_ARRAY](header=_rb_header(ts, STAMP, frame_id), poses=poses)
    ours = cdr.encode_pose_array(STAMP, frame_id, pos, yaw)
    assert ours == bytes(ts.serialize_cdr(msg, cdr.POSE_ARRAY))
    back = ts.deserialize_cdr(ours, cdr.POSE_ARRAY)
    assert back.header.frame_id == frame_id
    assert back.header.stamp.sec * 10**9 + back.header.stamp.nanosec == STAMP
    got = np.array([[p.position.x, p.position.y, p.position.z] for p in back.poses]).reshape(n, 3)
    np.testing.assert_array_equal(got[:, :2], pos)
    assert not got[:, 2].any()
    if yaw is not None and n:
        yaw_back = np.array([2 * math.atan2(p.orientation.z, p.orientation.w) for p in back.poses])
        np.testing.assert_allclose(yaw_back, yaw, atol=1e-12)


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("frame_id", FRAME_IDS)
@pytest.mark.parametrize("names", FIELD_SETS, ids=lambda f: f"{len(f)}fields")
def test_point_cloud2_matches_rosbags(typestore, n, frame_id, names):
    ts = typestore
    field_t = ts.types["sensor_msgs/msg/PointField"]
    fields = _cloud_fields(names, n, seed=7)
    data = np.stack([fields[k] for k in names], axis=1).tobytes()
    msg = ts.types[cdr.POINT_CLOUD2](
        header=_rb_header(ts, STAMP, frame_id),
        height=1,
        width=n,
        fields=[field_t(name=k, offset=4 * i, datatype=7, count=1) for i, k in enumerate(names)],
        is_bigendian=False,
        point_step=4 * len(names),
        row_step=4 * len(names) * n,
        data=np.frombuffer(data, dtype=np.uint8),
        is_dense=True,
    )
    ours = cdr.encode_point_cloud2(STAMP, frame_id, fields)
    assert ours == bytes(ts.serialize_cdr(msg, cdr.POINT_CLOUD2))
    back = ts.deserialize_cdr(ours, cdr.POINT_CLOUD2)
    assert [f.name for f in back.fields] == names
    assert back.width == n and back.height == 1 and back.is_dense
    cols = np.frombuffer(back.data.tobytes(), dtype="<f4").reshape(n, len(names))
    for i, k in enumerate(names):
        np.testing.assert_array_equal(cols[:, i], fields[k])


def test_decode_point_cloud2_general_layouts(typestore):
    """Organised cloud, mixed datatypes, padding inside points and rows, counts > 1."""
    ts = typestore
    field_t = ts.types["sensor_msgs/msg/PointField"]
    h, w = 3, 5
    rng = np.random.default_rng(11)
    pt = np.dtype({
        "names": ["a", "b", "c", "d", "e"],
        "formats": ["<f4", "<f8", "<i4", "<u4", ("<f4", 2)],
        "offsets": [0, 8, 16, 20, 28],
        "itemsize": 40,
    })
    pts = np.zeros((h, w), dtype=pt)
    pts["a"] = rng.normal(size=(h, w))
    pts["a"][1, 2] = np.nan
    pts["b"] = rng.normal(size=(h, w))
    pts["c"] = rng.integers(-(2**31), 2**31, size=(h, w))
    pts["d"] = rng.integers(0, 2**32, size=(h, w))
    pts["e"] = rng.normal(size=(h, w, 2))
    row_step = w * pt.itemsize + 6  # 6 bytes of row padding
    data = np.zeros((h, row_step), dtype=np.uint8)
    data[:, : w * pt.itemsize] = pts.view(np.uint8).reshape(h, -1)
    msg = ts.types[cdr.POINT_CLOUD2](
        header=_rb_header(ts, 42, "lidar"),
        height=h,
        width=w,
        fields=[
            field_t(name="a", offset=0, datatype=7, count=1),
            field_t(name="b", offset=8, datatype=8, count=1),
            field_t(name="c", offset=16, datatype=5, count=1),
            field_t(name="d", offset=20, datatype=6, count=1),
            field_t(name="e", offset=28, datatype=7, count=2),
        ],
        is_bigendian=False,
        point_step=pt.itemsize,
        row_step=row_step,
        data=data.reshape(-1),
        is_dense=False,
    )
    raw = bytes(ts.serialize_cdr(msg, cdr.POINT_CLOUD2))
    cloud = cdr.decode_point_cloud2(raw)
    assert (cloud.stamp_ns, cloud.frame_id, cloud.height, cloud.width) == (42, "lidar", h, w)
    assert cloud.n_points == h * w and cloud.is_dense is False
    for k in "abcd":
        np.testing.assert_array_equal(cloud.fields[k], pts[k].reshape(-1))
        assert cloud.fields[k].dtype == pts.dtype[k]
    assert cloud.fields["c"].dtype == np.int32 and cloud.fields["d"].dtype == np.uint32
    np.testing.assert_array_equal(cloud.fields["e"], pts["e"].reshape(-1, 2))


def test_decode_point_cloud2_packed_unaligned_fields(typestore):
    """point_step 15 with fields at odd offsets (no aligned typed view possible)."""
    ts = typestore
    field_t = ts.types["sensor_msgs/msg/PointField"]
    pt = np.dtype({"names": ["a", "b", "c", "d"], "formats": ["<f8", "u1", "<f4", "<i2"],
                   "offsets": [0, 8, 9, 13], "itemsize": 15})
    n = 6
    rng = np.random.default_rng(12)
    pts = np.zeros(n, dtype=pt)
    pts["a"] = rng.normal(size=n)
    pts["b"] = rng.integers(0, 256, size=n)
    pts["c"] = rng.normal(size=n)
    pts["d"] = rng.integers(-(2**15), 2**15, size=n)
    msg = ts.types[cdr.POINT_CLOUD2](
        header=_rb_header(ts, 7, "x"), height=1, width=n,
        fields=[field_t(name="a", offset=0, datatype=8, count=1),
                field_t(name="b", offset=8, datatype=2, count=1),
                field_t(name="c", offset=9, datatype=7, count=1),
                field_t(name="d", offset=13, datatype=3, count=1)],
        is_bigendian=False, point_step=15, row_step=15 * n,
        data=pts.view(np.uint8).copy(), is_dense=True,
    )
    cloud = cdr.decode_point_cloud2(bytes(ts.serialize_cdr(msg, cdr.POINT_CLOUD2)))
    for k in "abcd":
        np.testing.assert_array_equal(cloud.fields[k], pts[k])
        assert cloud.fields[k].dtype == pts.dtype[k] and cloud.fields[k].flags.c_contiguous


def test_decode_point_cloud2_big_endian_data(typestore):
    ts = typestore
    field_t = ts.types["sensor_msgs/msg/PointField"]
    vals = np.array([1.5, -2.25, 3e9], dtype=">f8")
    msg = ts.types[cdr.POINT_CLOUD2](
        header=_rb_header(ts, 0, ""), height=1, width=3,
        fields=[field_t(name="v", offset=0, datatype=8, count=1)],
        is_bigendian=True, point_step=8, row_step=24,
        data=np.frombuffer(vals.tobytes(), dtype=np.uint8), is_dense=True,
    )
    cloud = cdr.decode_point_cloud2(bytes(ts.serialize_cdr(msg, cdr.POINT_CLOUD2)))
    np.testing.assert_array_equal(cloud.fields["v"], vals.astype("<f8"))


# ---------------------------------------------------------------------------------------------
# Round trips through our own decoders
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("frame_id", FRAME_IDS + ["ünïcødé"])
def test_pose_array_round_trip(n, frame_id):
    pos = _positions(n, seed=8)
    yaw = _yaw(n, seed=9)
    raw = cdr.encode_pose_array(STAMP, frame_id, pos, yaw)
    stamp, frame, got = cdr.decode_pose_array(raw)
    assert (stamp, frame) == (STAMP, frame_id)
    assert got.shape == (n, 2) and got.dtype == np.float64 and got.flags.c_contiguous
    np.testing.assert_array_equal(got, pos)
    _, _, full = cdr.decode_pose_array_full(raw)
    assert full.shape == (n, 7)
    np.testing.assert_allclose(2 * np.arctan2(full[:, 5], full[:, 6]), yaw, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(full[:, 3:], axis=1), 1.0, atol=1e-15)


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("names", FIELD_SETS, ids=lambda f: f"{len(f)}fields")
def test_point_cloud2_round_trip(n, names):
    fields = _cloud_fields(names, n, seed=10)
    cloud = cdr.decode_point_cloud2(cdr.encode_point_cloud2(STAMP, "map", fields))
    assert (cloud.stamp_ns, cloud.frame_id, cloud.height, cloud.width) == (STAMP, "map", 1, n)
    assert list(cloud.fields) == names and cloud.is_dense
    for k in names:
        assert cloud.fields[k].dtype == np.float32
        np.testing.assert_array_equal(cloud.fields[k], fields[k])


def test_reused_buffers_carry_nothing_between_calls():
    """The encoders reuse one output buffer per layout and thread: a yaw does not leak into the
    next identity orientation, returned bytes never change, and threads do not mix."""
    from concurrent.futures import ThreadPoolExecutor

    n = 7
    pos = _positions(n, seed=3)
    plain = cdr.encode_pose_array(STAMP, "map", pos)
    turned = cdr.encode_pose_array(STAMP + 1, "map", 2 * pos, _yaw(n, seed=4))
    assert cdr.encode_pose_array(STAMP, "map", pos) == plain
    assert cdr.decode_pose_array_full(plain)[2][:, 3:].tolist() == [[0.0, 0.0, 0.0, 1.0]] * n
    assert cdr.decode_pose_array(turned)[0] == STAMP + 1
    np.testing.assert_array_equal(cdr.decode_pose_array(turned)[2], 2 * pos)
    # a non-contiguous input and another frame id (another layout) in between
    wide = np.column_stack([pos, pos])[:, 1:3]
    assert cdr.decode_pose_array(cdr.encode_pose_array(0, "odom", wide))[2].tolist() == \
        wide.tolist()
    fields = _cloud_fields(["a", "b"], n, seed=5)
    cloud = cdr.encode_point_cloud2(STAMP, "map", fields)
    cdr.encode_point_cloud2(STAMP, "map", {"a": np.full(n, np.nan), "b": np.zeros(n)})
    assert cdr.encode_point_cloud2(STAMP, "map", fields) == cloud

    def job(seed: int) -> bool:
        p = _positions(n, seed=seed)
        f = _cloud_fields(["a", "b"], n, seed=seed)
        want = (cdr.encode_pose_array(seed, "map", p), cdr.encode_point_cloud2(seed, "map", f))
        return all((cdr.encode_pose_array(seed, "map", p),
                    cdr.encode_point_cloud2(seed, "map", f)) == want for _ in range(200))

    with ThreadPoolExecutor(4) as pool:
        assert all(pool.map(job, range(8)))


def test_point_cloud2_casts_and_flags_non_finite():
    n = 4
    cloud = cdr.decode_point_cloud2(cdr.encode_point_cloud2(
        0, "map", {"id": np.arange(n), "v": [0.5, np.nan, 1.0, np.inf]}))
    np.testing.assert_array_equal(cloud.fields["id"], np.arange(n, dtype=np.float32))
    assert np.isnan(cloud.fields["v"][1]) and np.isinf(cloud.fields["v"][3])
    assert cloud.is_dense is False
    assert cdr.decode_point_cloud2(cdr.encode_point_cloud2(0, "", {"v": [1.0]})).is_dense


def test_stamp_split_and_negative_stamps():
    for stamp in [-1, -(10**9), -(10**9) - 1, 0, 2**31 * 10**9 - 1]:
        raw = cdr.encode_pose_array(stamp, "m", np.zeros((1, 2)))
        sec, nanosec = np.frombuffer(raw, dtype="<i4", count=1, offset=4)[0], \
            np.frombuffer(raw, dtype="<u4", count=1, offset=8)[0]
        assert 0 <= nanosec < 10**9
        assert int(sec) * 10**9 + int(nanosec) == stamp
        assert cdr.decode_pose_array(raw)[0] == stamp
    assert cdr.decode_clock(cdr.encode_clock(np.int64(5))) == 5


# ---------------------------------------------------------------------------------------------
# Validation
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("stamp", [2**31 * 10**9, -(2**31) * 10**9 - 1, 1.5, True, "1", None])
def test_bad_stamp_names_argument(stamp):
    for call in (lambda: cdr.encode_clock(stamp),
                 lambda: cdr.encode_pose_array(stamp, "m", np.zeros((1, 2))),
                 lambda: cdr.encode_point_cloud2(stamp, "m", {"x": [1.0]})):
        with pytest.raises(ValueError, match="stamp_ns"):
            call()


@pytest.mark.parametrize("positions, match", [
    (np.zeros((3,)), r"positions: has shape \(3,\)"),
    (np.zeros((3, 3)), r"positions: has shape \(3, 3\)"),
    (np.array([[0.0, 1.0], [np.nan, 0.0]]), "positions: row 1 is not finite"),
    (np.array([[0.0, np.inf]]), "positions: row 0 is not finite"),
    ([["a", "b"]], "positions"),
])
def test_bad_positions(positions, match):
    with pytest.raises(ValueError, match=match):
        cdr.encode_pose_array(0, "m", positions)


def test_bad_yaw_and_frame():
    with pytest.raises(ValueError, match=r"yaw: has shape \(2,\), expected \(3,\)"):
        cdr.encode_pose_array(0, "m", np.zeros((3, 2)), np.zeros(2))
    with pytest.raises(ValueError, match="yaw: entry 1 is not finite"):
        cdr.encode_pose_array(0, "m", np.zeros((2, 2)), [0.0, np.nan])
    with pytest.raises(ValueError, match="frame_id: must be a str"):
        cdr.encode_pose_array(0, b"m", np.zeros((1, 2)))
    with pytest.raises(ValueError, match="frame_id: must not contain a NUL"):
        cdr.encode_point_cloud2(0, "a\x00b", {"x": [1.0]})


@pytest.mark.parametrize("height", [2, 5])
def test_organised_point_cloud2_matches_rosbags(typestore, height):
    """height > 1: an organised cloud (the navigation_field grid), rows of width points."""
    ts = typestore
    field_t = ts.types["sensor_msgs/msg/PointField"]
    names = ["x", "y", "T"]
    n = 10 * height
    fields = _cloud_fields(names, n, seed=3)
    data = np.stack([fields[k] for k in names], axis=1).tobytes()
    msg = ts.types[cdr.POINT_CLOUD2](
        header=_rb_header(ts, STAMP, "map"), height=height, width=n // height,
        fields=[field_t(name=k, offset=4 * i, datatype=7, count=1) for i, k in enumerate(names)],
        is_bigendian=False, point_step=12, row_step=12 * (n // height),
        data=np.frombuffer(data, dtype=np.uint8), is_dense=True)
    ours = cdr.encode_point_cloud2(STAMP, "map", fields, height=height)
    assert ours == bytes(ts.serialize_cdr(msg, cdr.POINT_CLOUD2))
    back = cdr.decode_point_cloud2(ours)
    assert (back.height, back.width) == (height, n // height)
    np.testing.assert_array_equal(back.fields["T"], fields["T"])


def test_bad_cloud_fields():
    with pytest.raises(ValueError, match="fields: must be a non-empty mapping"):
        cdr.encode_point_cloud2(0, "m", {})
    with pytest.raises(ValueError, match=r"fields\['y'\]: has 2 values, expected 3"):
        cdr.encode_point_cloud2(0, "m", {"x": [1, 2, 3], "y": [1, 2]})
    with pytest.raises(ValueError, match=r"fields\['x'\]: has shape \(2, 2\)"):
        cdr.encode_point_cloud2(0, "m", {"x": np.zeros((2, 2))})
    with pytest.raises(ValueError, match=r"fields\['x'\]: must hold numbers"):
        cdr.encode_point_cloud2(0, "m", {"x": ["a", "b"]})
    with pytest.raises(ValueError, match="field names must be non-empty"):
        cdr.encode_point_cloud2(0, "m", {"": [1.0]})
    with pytest.raises(ValueError, match="height: 2 does not divide the 3 points into rows"):
        cdr.encode_point_cloud2(0, "m", {"x": [1.0, 2.0, 3.0]}, height=2)


def test_decoders_refuse_bad_buffers():
    raw = cdr.encode_pose_array(0, "map", _positions(3))
    for cut in [0, 3, 10, 18, len(raw) - 1]:
        with pytest.raises(ValueError, match="data:"):
            cdr.decode_pose_array(raw[:cut])
    with pytest.raises(ValueError, match="big-endian"):
        cdr.decode_pose_array(b"\x00\x00\x00\x00" + raw[4:])
    cloud = cdr.encode_point_cloud2(0, "map", {"x": [1.0, 2.0]})
    for cut in [5, 30, len(cloud) - 3]:
        with pytest.raises(ValueError, match="truncated"):
            cdr.decode_point_cloud2(cloud[:cut])
    with pytest.raises(ValueError, match="data:"):
        cdr.decode_clock(b"\x00\x01\x00\x00\x01")


# ---------------------------------------------------------------------------------------------
# Schemas
# ---------------------------------------------------------------------------------------------


def _share_dirs() -> list[Path]:
    dirs = [Path(sys.prefix) / "share"]
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            dirs.append(Path(prefix) / "share")
    return dirs


def _strip(text: str) -> list[str]:
    lines = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            lines.append(re.sub(r"\s+", " ", line))
    return lines


def test_schemas_structure():
    assert set(cdr.SCHEMAS) == {cdr.POSE_ARRAY, cdr.POINT_CLOUD2, cdr.CLOCK, cdr.ODOMETRY,
                                cdr.TWIST_STAMPED, cdr.LASER_SCAN, cdr.TF_MESSAGE,
                                cdr.POSE_WITH_COVARIANCE_STAMPED, cdr.MARKER_ARRAY}
    sep = "\n" + "=" * 80 + "\n"
    for msgtype, text in cdr.SCHEMAS.items():
        sections = text.split(sep)
        names = [s.split("\n", 1)[0] for s in sections[1:]]
        assert all(n.startswith("MSG: ") for n in names), msgtype
        assert "builtin_interfaces/Time" in {n[5:] for n in names}
    assert "MSG: geometry_msgs/Pose\n" in cdr.POSE_ARRAY_MSGDEF
    assert "MSG: sensor_msgs/PointField\n" in cdr.POINT_CLOUD2_MSGDEF


def test_schemas_equal_installed_msg_files():
    """Each section equals the installed .msg file with comments stripped."""
    sep = "\n" + "=" * 80 + "\n"
    checked = 0
    for msgtype, text in cdr.SCHEMAS.items():
        sections = text.split(sep)
        todo = [(msgtype.replace("/msg/", "/"), sections[0])]
        todo += [tuple(s.split("\n", 1)) for s in sections[1:]]
        for name, body in todo:
            name = name.removeprefix("MSG: ")
            pkg, typ = name.split("/")
            path = next((d / pkg / "msg" / f"{typ}.msg" for d in _share_dirs()
                         if (d / pkg / "msg" / f"{typ}.msg").is_file()), None)
            if path is None:
                continue
            assert _strip(body) == _strip(path.read_text()), name
            checked += 1
    if checked == 0:
        pytest.skip("no installed .msg files found")
