"""CDR encoders: numpy arrays to the bytes of PoseArray, PointCloud2 and Clock messages
(see :mod:`sweep_core.io.cdr`)."""
from __future__ import annotations

import struct
from collections.abc import Mapping
from functools import lru_cache

import numpy as np

from sweep_core.io.cdr.wire import (
    ENCAPSULATION,
    PAD,
    header_prefix,
    pack_2u32,
    pack_3u32,
    scratch,
    split_stamp,
)
from sweep_core.model import elementary


def encode_clock(stamp_ns: int) -> bytes:
    """``rosgraph_msgs/msg/Clock`` with ``clock`` = ``stamp_ns`` (12 bytes)."""
    sec, nanosec = split_stamp(stamp_ns, "stamp_ns")
    return ENCAPSULATION + struct.pack("<iI", sec, nanosec)


def encode_pose_array(
    stamp_ns: int,
    frame_id: str,
    positions: np.ndarray,
    yaw: np.ndarray | None = None,
) -> bytes:
    """``geometry_msgs/msg/PoseArray`` of N poses.

    Args:
        stamp_ns: header stamp in nanoseconds.
        frame_id: header frame id.
        positions: (N, 2) x, y in metres (z = 0); must be finite.
        yaw: (N,) heading in radians about +z, or None for the identity orientation; must
            be finite.

    Raises:
        ValueError: naming the argument, on a bad stamp, frame id, shape or non-finite value.
    """
    prefix = header_prefix(stamp_ns, frame_id)
    try:
        pos = np.asarray(positions, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise ValueError(f"positions: must be an (N, 2) array of numbers ({err})") from None
    if pos.ndim != 2 or pos.shape[1] != 2:
        raise ValueError(f"positions: has shape {pos.shape}, expected (N, 2)")
    n = pos.shape[0]
    if not np.isfinite(pos).all():
        i = int(np.argwhere(~np.isfinite(pos))[0, 0])
        raise ValueError(f"positions: row {i} is not finite ({pos[i].tolist()})")
    if yaw is not None:
        try:
            th = np.asarray(yaw, dtype=np.float64)
        except (TypeError, ValueError) as err:
            raise ValueError(f"yaw: must be an (N,) array of numbers ({err})") from None
        if th.shape != (n,):
            raise ValueError(f"yaw: has shape {th.shape}, expected ({n},) to match positions")
        if not np.isfinite(th).all():
            i = int(np.argwhere(~np.isfinite(th))[0, 0])
            raise ValueError(f"yaw: entry {i} is not finite ({th[i]!r})")
    if n == 0:
        return prefix + b"\x00\x00\x00\x00"
    # Bytes before the poses: prefix, uint32 length, padding to 8 (payload-relative).
    seq_off = len(prefix) - 4
    head = len(prefix) + 4 + (-(seq_off + 4) % 8)
    # One output buffer with 4 spare leading bytes, so the poses block (payload offset
    # multiple of 8 = buffer offset 4 mod 8) is 8-byte aligned in memory and filled in place.
    # z, qx, qy stay zero from its allocation; the state says what qz, qw hold.
    entry = scratch(("PoseArray", n, len(prefix)), 4 + head + 56 * n)
    buf = entry[0]
    buf[4 : 4 + len(prefix)] = np.frombuffer(prefix, dtype=np.uint8)
    buf[4 + len(prefix) : 4 + len(prefix) + 4] = np.frombuffer(struct.pack("<I", n), np.uint8)
    poses = buf[4 + head :].view("<f8").reshape(n, 7)  # x y z qx qy qz qw
    # x, y of each pose copied as one 16-byte item (complex128 is just a pair of float64)
    poses[:, 0:2].view(np.complex128)[:, 0] = np.ascontiguousarray(pos).view(np.complex128)[:, 0]
    if yaw is None:
        if entry[1] != "identity":
            poses[:, 5] = 0.0
            poses[:, 6] = 1.0
            entry[1] = "identity"
    else:
        half = 0.5 * th
        poses[:, 5] = elementary.sin_of(half)
        poses[:, 6] = elementary.cos_of(half)
        entry[1] = "yaw"
    return buf[4:].tobytes()


#: clouds of at most this many data bytes are joined from bytes (no kept buffer)
_SMALL_CLOUD = 256


@lru_cache(maxsize=256)
def _cloud_layout(names: tuple[str, ...], n: int, height: int) -> bytes:
    """A PointCloud2's bytes between its header and its data: height, width, the fields
    (FLOAT32 at offsets 0, 4, ...), is_bigendian false and padding, point_step, row_step and
    the data's length, for n points in ``height`` rows."""
    point_step = 4 * len(names)
    width = n // height
    return b"".join((pack_2u32(height, width), _fields_block(names),
                     b"\x00\x00\x00\x00",  # is_bigendian = false + 3 bytes padding
                     pack_3u32(point_step, point_step * width, point_step * n)))


@lru_cache(maxsize=64)
def _fields_block(names: tuple[str, ...]) -> bytes:
    """The ``PointField[] fields`` sequence for FLOAT32 fields at offsets 0, 4, 8, ...

    Starts and ends on a 4-byte boundary, so its bytes do not depend on where it is placed.
    """
    parts = [struct.pack("<I", len(names))]
    for i, name in enumerate(names):
        raw = name.encode("utf-8") + b"\x00"
        parts.append(struct.pack("<I", len(raw)))
        parts.append(raw)
        parts.append(PAD[-len(raw) % 4])
        # offset, datatype FLOAT32 (7) + 3 bytes padding, count 1
        parts.append(struct.pack("<IB3xI", 4 * i, 7, 1))
    return b"".join(parts)


@lru_cache(maxsize=64)
def _plain_names(names: tuple[str, ...]) -> bool:
    return all(isinstance(name, str) and name and "\x00" not in name for name in names)


def encode_float32_cloud(stamp_ns: int, frame_id: str, names: tuple[str, ...],
                         block: np.ndarray) -> bytes:
    """The bytes :func:`encode_point_cloud2` gives for an unorganised cloud whose columns,
    fields ``names`` in order, are those of ``block`` ((N, F) float32, C-contiguous, F =
    len(names) >= 1): the block written as it is, for a caller that fills it in a few numpy
    calls rather than column by column.

    Raises:
        ValueError: naming the argument, on a bad stamp, frame id, name or block.
    """
    prefix = header_prefix(stamp_ns, frame_id)
    if type(names) is not tuple or not names or not _plain_names(names):
        raise ValueError(f"names: must be a non-empty tuple of non-empty str without NUL, got "
                         f"{names!r}")
    if not (type(block) is np.ndarray and block.dtype == np.dtype("<f4") and block.ndim == 2
            and block.shape[1] == len(names) and block.flags.c_contiguous):
        raise ValueError(f"block: must be a C-contiguous (N, {len(names)}) float32 array")
    return b"".join((prefix, _cloud_layout(names, block.shape[0], 1), block.tobytes(),
                     b"\x01" if np.isfinite(block).all() else b"\x00"))


def encode_point_cloud2(stamp_ns: int, frame_id: str, fields: Mapping[str, np.ndarray],
                        height: int = 1) -> bytes:
    """``sensor_msgs/msg/PointCloud2`` of N points, every field FLOAT32.

    ``height`` = 1 (the default: an unorganised cloud, ``width`` = N) or an organised cloud of
    ``height`` rows (``width`` = N / height; the columns hold the points row by row), fields in
    the mapping's order at offsets 0, 4, 8, ... (datatype 7, count 1), ``point_step`` = 4 F,
    ``row_step`` = 4 F width, little endian, ``data`` the float32 columns interleaved point by
    point. Values are cast to float32; NaN and inf are
    allowed (e.g. "no value"), and ``is_dense`` is true exactly when every value is finite.

    Args:
        stamp_ns: header stamp in nanoseconds.
        frame_id: header frame id.
        fields: non-empty mapping of field name to an (N,) array; all of one length N.

        height: rows of an organised cloud (N must be a multiple of it), 1 for unorganised.

    Raises:
        ValueError: naming the argument (``fields[...]`` for a column), on a bad stamp, frame
            id, name, shape, height or a non-numeric column.
    """
    prefix = header_prefix(stamp_ns, frame_id)
    if not (type(fields) is dict or isinstance(fields, Mapping)) or len(fields) == 0:
        raise ValueError("fields: must be a non-empty mapping of field name to an (N,) array")
    names = tuple(fields)
    n = -1
    cols = []
    for name in names:
        if not isinstance(name, str) or not name or "\x00" in name:
            raise ValueError(f"fields: field names must be non-empty str without NUL, got {name!r}")
        try:
            col = np.asarray(fields[name])
        except (TypeError, ValueError) as err:
            raise ValueError(
                f"fields[{name!r}]: must be an (N,) array of numbers ({err})"
            ) from None
        if col.dtype.kind not in "biuf":
            raise ValueError(f"fields[{name!r}]: must hold numbers, got dtype {col.dtype}")
        if col.ndim != 1:
            raise ValueError(f"fields[{name!r}]: has shape {col.shape}, expected (N,)")
        if n < 0:
            n = col.shape[0]
        elif col.shape[0] != n:
            raise ValueError(
                f"fields[{name!r}]: has {col.shape[0]} values, expected {n} like "
                f"fields[{names[0]!r}]"
            )
        cols.append(col)
    if isinstance(height, bool) or not isinstance(height, int) or height < 1 or n % height:
        raise ValueError(f"height: {height!r} does not divide the {n} points into rows (give "
                         "1 for an unorganised cloud, or a divisor of the number of points)")
    nf = len(names)
    nbytes = 4 * nf * n
    head = prefix + _cloud_layout(names, n, height)
    if nbytes <= _SMALL_CLOUD:  # a few points: the bytes joined, no kept buffer
        small = np.empty((n, nf), dtype="<f4")
        with np.errstate(over="ignore", invalid="ignore"):
            for i, col in enumerate(cols):
                small[:, i] = col
        return b"".join((head, small.tobytes(), b"\x01" if np.isfinite(small).all() else
                         b"\x00"))
    # One output buffer; the data block starts 4-aligned, so it is filled in place as float32.
    buf = scratch(("PointCloud2", n, names, len(head)), len(head) + nbytes + 1)[0]
    buf[: len(head)] = np.frombuffer(head, dtype=np.uint8)
    block = buf[len(head) : len(head) + nbytes].view("<f4").reshape(n, nf)
    with np.errstate(over="ignore", invalid="ignore"):
        for i, col in enumerate(cols):
            block[:, i] = col
    # checked after the cast: a finite float64 too large for float32 becomes inf
    buf[-1] = 1 if np.isfinite(block).all() else 0  # is_dense
    return buf.tobytes()


