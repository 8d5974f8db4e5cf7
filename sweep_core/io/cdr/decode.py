"""CDR decoders: the bytes of PoseArray, PointCloud2 and Clock messages back to numpy arrays
(see :mod:`sweep_core.io.cdr`)."""
from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sweep_core.io.cdr.msgdefs import CLOCK, POINT_CLOUD2, POSE_ARRAY
from sweep_core.io.cdr.wire import NS_PER_S, unpack_3u32, unpack_u32

_DATATYPES: dict[int, np.dtype] = {
    1: np.dtype("i1"),
    2: np.dtype("u1"),
    3: np.dtype("<i2"),
    4: np.dtype("<u2"),
    5: np.dtype("<i4"),
    6: np.dtype("<u4"),
    7: np.dtype("<f4"),
    8: np.dtype("<f8"),
}


@dataclass
class Cloud:
    """A decoded ``sensor_msgs/msg/PointCloud2``.

    ``fields`` maps each field name to a contiguous numpy array of ``height * width`` values in
    row-major point order (shape ``(height * width,)``, or ``(height * width, count)`` for a
    field with count > 1), in the field's own dtype (native byte order).
    """

    stamp_ns: int
    frame_id: str
    height: int
    width: int
    fields: dict[str, np.ndarray] = field(default_factory=dict)
    is_dense: bool = True

    @property
    def n_points(self) -> int:
        return self.height * self.width


def _check_cdr(data: Any, what: str) -> memoryview:
    try:
        mv = memoryview(data)
    except TypeError:
        raise ValueError(f"data: a {what} must be bytes-like, got {type(data).__name__}") from None
    if mv.ndim != 1 or mv.itemsize != 1:
        mv = mv.cast("B")
    if len(mv) < 4:
        raise ValueError(f"data: {len(mv)} bytes is too short for a CDR {what}")
    if mv[0] != 0 or mv[1] != 1:
        if (mv[0], mv[1]) == (0, 0):
            kind = "big-endian CDR"
        else:
            kind = f"encapsulation {bytes(mv[:2]).hex()}"
        raise ValueError(f"data: {kind} is not supported for {what} (expected CDR_LE 00 01)")
    return mv


def _need(mv: memoryview, end: int, what: str, part: str) -> None:
    if end > len(mv):
        raise ValueError(
            f"data: {what} is truncated in {part} (needs {end} bytes, has {len(mv)})"
        )


def _read_string(mv: memoryview, off: int, what: str, part: str) -> tuple[str, int]:
    """Reads a CDR string at payload-relative 4-aligned ``off``; returns it and the next offset."""
    _need(mv, 4 + off + 4, what, part)
    (length,) = unpack_u32(mv, 4 + off)
    off += 4
    _need(mv, 4 + off + length, what, part)
    raw = bytes(mv[4 + off : 4 + off + length])
    if raw.endswith(b"\x00"):
        raw = raw[:-1]
    return raw.decode("utf-8", errors="replace"), off + length


def _read_header(mv: memoryview, what: str) -> tuple[int, str, int]:
    _need(mv, 4 + 8, what, "header.stamp")
    sec, nanosec = struct.unpack_from("<iI", mv, 4)
    frame_id, off = _read_string(mv, 8, what, "header.frame_id")
    return sec * NS_PER_S + nanosec, frame_id, off


def decode_clock(data: bytes) -> int:
    """``rosgraph_msgs/msg/Clock`` -> stamp in nanoseconds."""
    mv = _check_cdr(data, CLOCK)
    _need(mv, 12, CLOCK, "clock")
    sec, nanosec = struct.unpack_from("<iI", mv, 4)
    return sec * NS_PER_S + nanosec


def _pose_block(data: bytes) -> tuple[int, str, np.ndarray]:
    mv = _check_cdr(data, POSE_ARRAY)
    stamp_ns, frame_id, off = _read_header(mv, POSE_ARRAY)
    off += -off % 4
    _need(mv, 4 + off + 4, POSE_ARRAY, "poses length")
    (n,) = unpack_u32(mv, 4 + off)
    off += 4
    if n == 0:
        return stamp_ns, frame_id, np.zeros((0, 7), dtype=np.float64)
    off += -off % 8
    _need(mv, 4 + off + 56 * n, POSE_ARRAY, "poses")
    poses = np.frombuffer(mv, dtype="<f8", count=7 * n, offset=4 + off).reshape(n, 7)
    return stamp_ns, frame_id, poses


def decode_pose_array(data: bytes) -> tuple[int, str, np.ndarray]:
    """``geometry_msgs/msg/PoseArray`` -> (stamp_ns, frame_id, positions (N, 2) float64).

    The positions are a new array (x, y of each pose); z and orientation are dropped (see
    :func:`decode_pose_array_full`).
    """
    stamp_ns, frame_id, poses = _pose_block(data)
    return stamp_ns, frame_id, np.ascontiguousarray(poses[:, 0:2], dtype=np.float64)


def decode_pose_array_full(data: bytes) -> tuple[int, str, np.ndarray]:
    """``geometry_msgs/msg/PoseArray`` -> (stamp_ns, frame_id, poses (N, 7) float64).

    Columns: x, y, z, qx, qy, qz, qw. Yaw of a planar pose is ``2 * arctan2(qz, qw)``.
    """
    stamp_ns, frame_id, poses = _pose_block(data)
    return stamp_ns, frame_id, np.array(poses, dtype=np.float64)


def decode_point_cloud2(data: bytes) -> Cloud:
    """``sensor_msgs/msg/PointCloud2`` -> :class:`Cloud`.

    Handles every PointField datatype (INT8 ... FLOAT64), any count, any offsets and
    point_step / row_step (padding between points or rows is skipped), organised clouds
    (height > 1: columns are flattened row-major) and big-endian point data.

    Raises:
        ValueError: on a truncated buffer, an unknown datatype, duplicate field names or a
            field that lies outside ``point_step``.
    """
    what = POINT_CLOUD2
    mv = _check_cdr(data, what)
    stamp_ns, frame_id, off = _read_header(mv, what)
    off += -off % 4
    _need(mv, 4 + off + 12, what, "height/width/fields")
    height, width, nfields = unpack_3u32(mv, 4 + off)
    off += 12
    specs: list[tuple[str, int, int, int]] = []
    for k in range(nfields):
        name, off = _read_string(mv, off, what, f"fields[{k}].name")
        off += -off % 4
        _need(mv, 4 + off + 12, what, f"fields[{k}]")
        (offset,) = unpack_u32(mv, 4 + off)
        datatype = mv[4 + off + 4]
        (count,) = unpack_u32(mv, 4 + off + 8)
        off += 12
        specs.append((name, offset, datatype, count))
    _need(mv, 4 + off + 1, what, "is_bigendian")
    is_bigendian = bool(mv[4 + off])
    off += 1
    off += -off % 4
    _need(mv, 4 + off + 12, what, "point_step/row_step/data")
    point_step, row_step, ndata = unpack_3u32(mv, 4 + off)
    off += 12
    _need(mv, 4 + off + ndata, what, "data")
    data_off = 4 + off
    off += ndata
    is_dense = bool(mv[4 + off]) if 4 + off < len(mv) else True

    npts = height * width
    names = [s[0] for s in specs]
    if len(set(names)) != len(names):
        raise ValueError(f"data: {what} has duplicate field names {names}")
    if npts and width * point_step > row_step:
        raise ValueError(
            f"data: {what} row_step {row_step} < width {width} * point_step {point_step}"
        )
    if npts and height * row_step > ndata:
        raise ValueError(
            f"data: {what} holds {ndata} data bytes, height {height} * row_step {row_step} needed"
        )
    dtypes: list[tuple[np.dtype, int]] = []
    for name, offset, datatype, count in specs:
        dt = _DATATYPES.get(datatype)
        if dt is None:
            raise ValueError(f"data: {what} field {name!r} has unknown datatype {datatype}")
        if is_bigendian:
            dt = dt.newbyteorder(">")
        count = max(count, 1)
        if offset + dt.itemsize * count > point_step:
            raise ValueError(
                f"data: {what} field {name!r} (offset {offset}, {count} x {dt}) lies outside "
                f"point_step {point_step}"
            )
        dtypes.append((dt, count))

    fields: dict[str, np.ndarray] = {}
    if npts == 0:
        for (name, _o, _d, _c), (dt, count) in zip(specs, dtypes):
            shape = (0,) if count == 1 else (0, count)
            fields[name] = np.zeros(shape, dtype=dt.newbyteorder("="))
    else:
        raw = np.frombuffer(mv, dtype=np.uint8, count=height * row_step, offset=data_off)
        if row_step != width * point_step:
            raw = raw.reshape(height, row_step)[:, : width * point_step]
        points = np.ascontiguousarray(raw).reshape(npts, point_step)
        typed: dict[np.dtype, np.ndarray] = {}
        for (name, offset, _d, _c), (dt, count) in zip(specs, dtypes):
            size = dt.itemsize
            native = dt.newbyteorder("=")
            if point_step % size == 0 and offset % size == 0:
                # fast path: a strided column of the points viewed as this dtype
                view = typed.get(dt)
                if view is None:
                    view = typed[dt] = points.view(dt)
                col = view[:, offset // size : offset // size + count]
            else:
                col = np.ascontiguousarray(points[:, offset : offset + size * count]).view(dt)
            col = col.reshape(npts) if count == 1 else col.reshape(npts, count)
            fields[name] = np.array(col, dtype=native, order="C")
    return Cloud(stamp_ns, frame_id, height, width, fields, is_dense)
