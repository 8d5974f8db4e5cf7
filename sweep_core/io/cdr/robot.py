"""CDR encoders and decoders of the robot's messages: ``nav_msgs/msg/Odometry``,
``geometry_msgs/msg/TwistStamped``, ``sensor_msgs/msg/LaserScan``, ``tf2_msgs/msg/TFMessage``
and ``geometry_msgs/msg/PoseWithCovarianceStamped`` (see :mod:`sweep_core.io.cdr`).

Planar conventions: a pose (x, y, yaw) is position (x, y, 0) and orientation quaternion
(0, 0, sin(yaw/2), cos(yaw/2)); a planar twist (vx, vy, omega) is linear (vx, vy, 0) and angular
(0, 0, omega). Units are ROS units: m, rad, m/s, rad/s. The decoders return every component as
sent (a twist with linear.z or angular.x is decoded as it is; the engine decides what to do).
"""
from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from sweep_core.io.cdr.msgdefs import (
    LASER_SCAN,
    ODOMETRY,
    POSE_WITH_COVARIANCE_STAMPED,
    TF_MESSAGE,
    TWIST_STAMPED,
)
from sweep_core.io.cdr.stream import CdrReader, CdrWriter, header_tail
from sweep_core.io.cdr.wire import ENCAPSULATION, pack_stamp, pack_u32, split_stamp
from sweep_core.model import elementary


def _finite(values: Sequence[float] | np.ndarray, size: int, name: str
            ) -> np.ndarray | list[float]:
    """``size`` finite float64 values, checked (ValueError naming ``name``)."""
    # the common cases (a tuple of floats, a float64 array), without numpy's per-call cost
    if type(values) is tuple and len(values) == size \
            and all(type(v) is float and math.isfinite(v) for v in values):
        return list(values)
    if type(values) is np.ndarray and values.shape == (size,) and values.dtype == np.float64:
        out = values.tolist()
        if all(map(math.isfinite, out)):
            return out
    try:
        arr = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{name}: must be {size} numbers ({err})") from None
    if arr.shape != (size,):
        raise ValueError(f"{name}: has shape {arr.shape}, expected ({size},)")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name}: must be finite, got {arr.tolist()}")
    return arr


#: 36 float64 zeros: a covariance not given
_ZERO_COVARIANCE = bytes(8 * 36)


def _covariance(w: CdrWriter, values: Sequence[float] | np.ndarray | None, name: str) -> None:
    """A 6x6 row-major covariance (36 values; zeros when None) written to ``w``."""
    if values is None:
        w.raw(_ZERO_COVARIANCE, 8)
    else:
        w.pack("36d", *_finite(np.asarray(values, dtype=np.float64).ravel(), 36, name))


def yaw_quaternion(yaw: float) -> tuple[float, float, float, float]:
    """(qx, qy, qz, qw) of a rotation by ``yaw`` (rad) about +z."""
    s, c = elementary.sincos(0.5 * yaw)
    return 0.0, 0.0, s, c


def quaternion_yaw(q: Sequence[float] | np.ndarray) -> float:
    """Yaw (rad, in (-pi, pi]) of a quaternion (qx, qy, qz, qw) of a rotation about z."""
    qx, qy, qz, qw = (float(v) for v in q)
    return elementary.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))


@dataclass
class Odometry:
    """A decoded ``nav_msgs/msg/Odometry``: ``position`` (3,) m and ``orientation`` (4,)
    (qx, qy, qz, qw) in ``frame_id``; ``linear`` (3,) m/s and ``angular`` (3,) rad/s in
    ``child_frame_id``; covariances (36,) row-major 6x6."""

    stamp_ns: int
    frame_id: str
    child_frame_id: str
    position: np.ndarray
    orientation: np.ndarray
    linear: np.ndarray
    angular: np.ndarray
    pose_covariance: np.ndarray = field(default_factory=lambda: np.zeros(36))
    twist_covariance: np.ndarray = field(default_factory=lambda: np.zeros(36))

    @property
    def yaw(self) -> float:
        return quaternion_yaw(self.orientation)


@dataclass
class Twist:
    """A decoded ``geometry_msgs/msg/TwistStamped``: ``linear`` (3,) m/s, ``angular`` (3,)
    rad/s in ``frame_id``."""

    stamp_ns: int
    frame_id: str
    linear: np.ndarray
    angular: np.ndarray


@dataclass
class LaserScan:
    """A ``sensor_msgs/msg/LaserScan``: angles (rad), times (s), ranges (m; float32 (N,), +inf
    where nothing was hit within range_max), intensities (float32, empty when not measured)."""

    stamp_ns: int
    frame_id: str
    angle_min: float
    angle_max: float
    angle_increment: float
    time_increment: float
    scan_time: float
    range_min: float
    range_max: float
    ranges: np.ndarray
    intensities: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.float32))


@dataclass
class Transform:
    """One ``geometry_msgs/msg/TransformStamped``: ``child_frame_id``'s pose in ``frame_id``,
    ``translation`` (3,) m and ``rotation`` (4,) (qx, qy, qz, qw)."""

    stamp_ns: int
    frame_id: str
    child_frame_id: str
    translation: np.ndarray
    rotation: np.ndarray

    @classmethod
    def planar(cls, stamp_ns: int, frame_id: str, child_frame_id: str, x: float, y: float,
               yaw: float) -> Transform:
        return cls(stamp_ns, frame_id, child_frame_id, np.array([x, y, 0.0]),
                   np.array(yaw_quaternion(yaw)))

    @property
    def yaw(self) -> float:
        return quaternion_yaw(self.rotation)


@dataclass
class PoseWithCovariance:
    """A decoded ``geometry_msgs/msg/PoseWithCovarianceStamped``."""

    stamp_ns: int
    frame_id: str
    position: np.ndarray
    orientation: np.ndarray
    covariance: np.ndarray

    @property
    def yaw(self) -> float:
        return quaternion_yaw(self.orientation)


def _pose(w: CdrWriter, pose: Sequence[float] | np.ndarray, name: str) -> None:
    x, y, yaw = _finite(pose, 3, name)
    w.pack("7d", x, y, 0.0, *yaw_quaternion(yaw))


#: an Odometry's pose, zero covariance, twist and zero covariance (from an 8-byte boundary)
_ODOMETRY_BODY = struct.Struct("<7d288x6d288x").pack
_SIX = struct.Struct("<6d").pack
_SEVEN = struct.Struct("<7d").pack
_SCAN_FIELDS = struct.Struct("<7f").pack


def _odometry_planar(stamp_ns: int, frame_id: str, child_frame_id: str,
                     pose: Sequence[float] | np.ndarray, twist: Sequence[float] | np.ndarray
                     ) -> bytes:
    """:func:`encode_odometry` without covariances, its fixed layout packed at once (the same
    checks in the same order)."""
    sec, nanosec = split_stamp(stamp_ns, "stamp_ns")
    tail = header_tail(((frame_id, "frame_id"), (child_frame_id, "child_frame_id")), 8)
    x, y, yaw = _finite(pose, 3, "pose")
    vx, vy, omega = _finite(twist, 3, "twist")
    _, _, s, c = yaw_quaternion(yaw)
    return b"".join((ENCAPSULATION, pack_stamp(sec, nanosec), tail,
                     _ODOMETRY_BODY(x, y, 0.0, 0.0, 0.0, s, c, vx, vy, 0.0, 0.0, 0.0, omega)))


def encode_odometry(stamp_ns: int, frame_id: str, child_frame_id: str,
                    pose: Sequence[float] | np.ndarray, twist: Sequence[float] | np.ndarray,
                    pose_covariance: Sequence[float] | np.ndarray | None = None,
                    twist_covariance: Sequence[float] | np.ndarray | None = None) -> bytes:
    """``nav_msgs/msg/Odometry`` of a planar pose (x, y, yaw) in ``frame_id`` (m, rad) and a
    planar twist (vx, vy, omega) in ``child_frame_id`` (m/s, rad/s); covariances 36 values
    (row-major 6x6), zero when None. Raises ValueError naming a bad argument."""
    if pose_covariance is None and twist_covariance is None and type(frame_id) is str \
            and type(child_frame_id) is str:
        return _odometry_planar(stamp_ns, frame_id, child_frame_id, pose, twist)
    w = CdrWriter()
    w.header(stamp_ns, frame_id)
    w.string(child_frame_id, "child_frame_id")
    _pose(w, pose, "pose")
    _covariance(w, pose_covariance, "pose_covariance")
    vx, vy, omega = _finite(twist, 3, "twist")
    w.pack("6d", vx, vy, 0.0, 0.0, 0.0, omega)
    _covariance(w, twist_covariance, "twist_covariance")
    return w.bytes()


def decode_odometry(data: bytes) -> Odometry:
    r = CdrReader(data, ODOMETRY)
    stamp, frame = r.header()
    child = r.string("child_frame_id")
    pose = np.array(r.unpack("7d", "pose.pose"))
    pcov = np.array(r.unpack("36d", "pose.covariance"))
    twist = np.array(r.unpack("6d", "twist.twist"))
    tcov = np.array(r.unpack("36d", "twist.covariance"))
    return Odometry(stamp, frame, child, pose[:3], pose[3:], twist[:3], twist[3:], pcov, tcov)


def encode_twist_stamped(stamp_ns: int, frame_id: str,
                         twist: Sequence[float] | np.ndarray) -> bytes:
    """``geometry_msgs/msg/TwistStamped`` of a planar twist (vx, vy, omega) (m/s, rad/s)."""
    vx, vy, omega = _finite(twist, 3, "twist")
    if type(frame_id) is str:  # the fixed layout packed at once
        sec, nanosec = split_stamp(stamp_ns, "stamp_ns")
        return b"".join((ENCAPSULATION, pack_stamp(sec, nanosec),
                         header_tail(((frame_id, "frame_id"),), 8),
                         _SIX(vx, vy, 0.0, 0.0, 0.0, omega)))
    w = CdrWriter()
    w.header(stamp_ns, frame_id)
    w.pack("6d", vx, vy, 0.0, 0.0, 0.0, omega)
    return w.bytes()


def decode_twist_stamped(data: bytes) -> Twist:
    r = CdrReader(data, TWIST_STAMPED)
    stamp, frame = r.header()
    v = np.array(r.unpack("6d", "twist"))
    return Twist(stamp, frame, v[:3], v[3:])


def encode_laser_scan(scan: LaserScan) -> bytes:
    """``sensor_msgs/msg/LaserScan`` of a :class:`LaserScan` (ranges and intensities cast to
    float32; inf and NaN allowed there, as REP 117 uses them)."""
    if type(scan.frame_id) is str:  # the header and angles packed at once
        sec, nanosec = split_stamp(scan.stamp_ns, "stamp_ns")
        parts = [ENCAPSULATION, pack_stamp(sec, nanosec),
                 header_tail(((scan.frame_id, "frame_id"),), 4),
                 _SCAN_FIELDS(scan.angle_min, scan.angle_max, scan.angle_increment,
                              scan.time_increment, scan.scan_time, scan.range_min,
                              scan.range_max)]
        for name in ("ranges", "intensities"):  # 4-byte aligned from here on
            values = np.asarray(getattr(scan, name))
            if values.ndim != 1 or values.dtype.kind not in "iuf":
                raise ValueError(f"{name}: must be an (N,) array of numbers, got {values.shape}")
            parts.append(pack_u32(len(values)))
            if len(values):
                parts.append(np.ascontiguousarray(values, dtype="<f4").tobytes())
        return b"".join(parts)
    w = CdrWriter()
    w.header(scan.stamp_ns, scan.frame_id)
    w.pack("7f", scan.angle_min, scan.angle_max, scan.angle_increment, scan.time_increment,
           scan.scan_time, scan.range_min, scan.range_max)
    for name in ("ranges", "intensities"):
        values = np.asarray(getattr(scan, name))
        if values.ndim != 1 or values.dtype.kind not in "iuf":
            raise ValueError(f"{name}: must be an (N,) array of numbers, got {values.shape}")
        w.float32_sequence(values)
    return w.bytes()


def decode_laser_scan(data: bytes) -> LaserScan:
    r = CdrReader(data, LASER_SCAN)
    stamp, frame = r.header()
    a0, a1, da, dt, scan_time, r0, r1 = r.unpack("7f", "angles and ranges")
    ranges = r.float32_sequence("ranges")
    intensities = r.float32_sequence("intensities")
    return LaserScan(stamp, frame, a0, a1, da, dt, scan_time, r0, r1, ranges, intensities)


def _tf_packed(transforms: Sequence[Transform]) -> bytes:
    """:func:`encode_tf_message` with each transform's header and numbers packed at once:
    the first transform's stamp at payload offset 4 (after the count), the others' at a
    multiple of 8 (after the 7 float64 of the last)."""
    parts = [ENCAPSULATION, pack_u32(len(transforms))]
    for k, tf in enumerate(transforms):
        sec, nanosec = split_stamp(tf.stamp_ns, "stamp_ns")
        parts.append(pack_stamp(sec, nanosec))
        parts.append(header_tail(((tf.frame_id, "frame_id"),
                                  (tf.child_frame_id, f"transforms[{k}].child_frame_id")),
                                 8, 4 if k == 0 else 0))
        parts.append(_SEVEN(*_finite(tf.translation, 3, f"transforms[{k}].translation"),
                            *_finite(tf.rotation, 4, f"transforms[{k}].rotation")))
    return b"".join(parts)


def encode_tf_message(transforms: Sequence[Transform]) -> bytes:
    """``tf2_msgs/msg/TFMessage`` of transforms (each stamped with its own time)."""
    try:  # each transform's fixed layout packed at once
        return _tf_packed(transforms)
    except (ValueError, TypeError):  # a bad transform: written field by field, which raises
        pass                        # the error of the first bad field
    w = CdrWriter()
    w.pack("I", len(transforms))
    for k, tf in enumerate(transforms):
        w.header(tf.stamp_ns, tf.frame_id)
        w.string(tf.child_frame_id, f"transforms[{k}].child_frame_id")
        w.pack("3d", *_finite(tf.translation, 3, f"transforms[{k}].translation"))
        w.pack("4d", *_finite(tf.rotation, 4, f"transforms[{k}].rotation"))
    return w.bytes()


def decode_tf_message(data: bytes) -> list[Transform]:
    r = CdrReader(data, TF_MESSAGE)
    (n,) = r.unpack("I", "transforms length")
    out = []
    for k in range(n):
        stamp, frame = r.header()
        child = r.string(f"transforms[{k}].child_frame_id")
        values = np.array(r.unpack("7d", f"transforms[{k}].transform"))
        out.append(Transform(stamp, frame, child, values[:3], values[3:]))
    return out


def encode_pose_with_covariance_stamped(
        stamp_ns: int, frame_id: str, pose: Sequence[float] | np.ndarray,
        covariance: Sequence[float] | np.ndarray | None = None) -> bytes:
    """``geometry_msgs/msg/PoseWithCovarianceStamped`` of a planar pose (x, y, yaw)."""
    w = CdrWriter()
    w.header(stamp_ns, frame_id)
    _pose(w, pose, "pose")
    _covariance(w, covariance, "covariance")
    return w.bytes()


def decode_pose_with_covariance_stamped(data: bytes) -> PoseWithCovariance:
    r = CdrReader(data, POSE_WITH_COVARIANCE_STAMPED)
    stamp, frame = r.header()
    pose = np.array(r.unpack("7d", "pose.pose"))
    cov = np.array(r.unpack("36d", "pose.covariance"))
    return PoseWithCovariance(stamp, frame, pose[:3], pose[3:], cov)
