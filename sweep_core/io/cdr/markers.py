"""CDR encoder of ``visualization_msgs/msg/MarkerArray`` (ROS 2 Kilted's definition,
:data:`~sweep_core.io.cdr.msgdefs.MARKER_ARRAY_MSGDEF`), vectorised with numpy.

The markers come in :class:`MarkerBatch` es: markers of one namespace, type and action that
differ in id, pose, scale and colour (no points, colours, texture, text or mesh). One Python
template per batch is written field by field; the batch's markers are that template repeated
(``np.tile``) with their columns patched in, so a message of 10 000 markers costs a few numpy
copies, no Python per marker. Alignment is relative to the first byte after the encapsulation
header, as in the other encoders; padding bytes are zero.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from sweep_core.io.cdr.wire import ENCAPSULATION, pack_stamp, split_stamp
from sweep_core.model import elementary

ARROW, CUBE, SPHERE, CYLINDER = 0, 1, 2, 3
ADD, DELETE, DELETEALL = 0, 2, 3


@dataclass(frozen=True)
class MarkerBatch:
    """Markers of one namespace ``ns``, ``type`` and ``action``: ``ids`` (n,) int32;
    ``position`` (n, 3) m; ``yaw`` (n,) rad about +z (orientation (0, 0, sin, cos) of half of
    it); ``scale`` (n, 3) m; ``color`` (n, 4) RGBA in [0, 1]."""

    ns: str
    type: int
    ids: np.ndarray
    position: np.ndarray
    yaw: np.ndarray
    scale: np.ndarray
    color: np.ndarray
    action: int = ADD

    def __len__(self) -> int:
        return len(self.ids)


def delete_all(ns: str = "") -> MarkerBatch:
    """One DELETEALL marker: viewers clear every marker of the topic (every namespace)."""
    return MarkerBatch(ns, ARROW, np.zeros(1, np.int32), np.zeros((1, 3)), np.zeros(1),
                       np.zeros((1, 3)), np.zeros((1, 4)), action=DELETEALL)


class _Writer:
    """Sequential little-endian CDR writer of one marker template at a payload offset."""

    def __init__(self, start: int) -> None:
        self.start, self.buf = start, bytearray()
        self.offsets: dict[str, int] = {}

    @property
    def pos(self) -> int:
        return self.start + len(self.buf)

    def align(self, n: int) -> None:
        self.buf += b"\x00" * (-self.pos % n)

    def put(self, code: str, *values: object, key: str | None = None) -> None:
        size = struct.calcsize("<" + code[0])
        self.align(size)
        if key is not None:
            self.offsets[key] = len(self.buf)
        self.buf += struct.pack("<" + code, *values)

    def string(self, raw: bytes) -> None:
        self.put("I", len(raw) + 1)
        self.buf += raw + b"\x00"


def _template(start: int, sec: int, nanosec: int, frame: bytes, batch: MarkerBatch
              ) -> tuple[bytes, dict[str, int], int]:
    """One marker of the batch written at payload offset ``start`` (a multiple of 4): its
    bytes up to the next marker's start (the trailing padding included), the offsets of the
    columns and of the end of the marker proper (``end``). The layout depends on ``start``
    only through its alignment (start mod 8) and is kept (:func:`_layout`); the stamp, the
    marker's first 8 bytes, is written into it."""
    unit, offsets, size = _layout(start % 8, frame, batch.ns, int(batch.type), int(batch.action))
    return struct.pack("<iI", sec, nanosec) + unit[8:], offsets, size


@lru_cache(maxsize=256)
def _layout(start: int, frame: bytes, ns: str, kind: int, action: int
            ) -> tuple[bytes, dict[str, int], int]:
    """A marker's template (stamp 0) written at a payload offset of ``start`` mod 8: see
    :func:`_template` (the offsets are not to be changed by callers)."""
    w = _Writer(start)
    w.put("iI", 0, 0)  # header.stamp (the first 8 bytes: start is a multiple of 4)
    w.string(frame)
    w.string(ns.encode("utf-8"))
    w.put("i", 0, key="id")
    w.put("ii", kind, action)
    w.put("ddd", 0.0, 0.0, 0.0, key="position")
    w.put("dddd", 0.0, 0.0, 0.0, 1.0, key="orientation")
    w.put("ddd", 0.0, 0.0, 0.0, key="scale")
    w.put("ffff", 0.0, 0.0, 0.0, 0.0, key="color")
    w.put("iI", 0, 0)  # lifetime: for ever
    w.put("B", 0)  # frame_locked
    w.put("I", 0)  # points
    w.put("I", 0)  # colors
    w.string(b"")  # texture_resource
    w.put("iI", 0, 0)  # texture.header.stamp
    w.string(b"")  # texture.header.frame_id
    w.string(b"")  # texture.format
    w.put("I", 0)  # texture.data
    w.put("I", 0)  # uv_coordinates
    w.string(b"")  # text
    w.string(b"")  # mesh_resource
    w.string(b"")  # mesh_file.filename
    w.put("I", 0)  # mesh_file.data
    w.put("B", 0)  # mesh_use_embedded_materials
    w.offsets["end"] = len(w.buf)
    w.align(4)  # the next marker starts with an int32
    return bytes(w.buf), w.offsets, len(w.buf)


def _columns(batch: MarkerBatch) -> dict[str, np.ndarray]:
    n = len(batch)
    orientation = np.empty((n, 4))
    elementary.z_rotations(np.ascontiguousarray(batch.yaw, dtype=np.float64).reshape(n),
                           orientation)
    return {"id": np.asarray(batch.ids).astype("<i4").reshape(n, 1),
            "position": np.asarray(batch.position, dtype="<f8").reshape(n, 3),
            "orientation": orientation,
            "scale": np.asarray(batch.scale, dtype="<f8").reshape(n, 3),
            "color": np.asarray(batch.color, dtype="<f4").reshape(n, 4)}


#: runs of at most this many repeats are filled through a structured view (:func:`_run_dtype`)
_SMALL_RUN = 1000
#: the columns' element type and width, as :func:`_columns` gives them
_COLUMN_TYPES = {"id": ("<i4", 1), "position": ("<f8", 3), "orientation": ("<f8", 4),
                 "scale": ("<f8", 3), "color": ("<f4", 4)}


@lru_cache(maxsize=256)
def _run_dtype(layout: tuple[tuple[int, tuple[tuple[str, int], ...]], ...], size: int
               ) -> np.dtype:
    """A structured dtype of ``period`` markers (``size`` bytes): field ``key + str(k)`` at
    the k-th marker's column offset (``layout``: per marker its start and column offsets)."""
    names, formats, offsets = [], [], []
    for k, (base, offs) in enumerate(layout):
        for key, off in offs:
            code, width = _COLUMN_TYPES[key]
            names.append(f"{key}{k}")
            formats.append((code, (width,)))
            offsets.append(base + off)
    return np.dtype({"names": names, "formats": formats, "offsets": offsets,
                     "itemsize": size})


def _encode_run(start: int, head: tuple[int, int, bytes], batch: MarkerBatch,
                columns: dict[str, np.ndarray], lo: int, hi: int, period: int
                ) -> tuple[np.ndarray, int, int]:
    """Markers lo..hi-1 of a batch written from payload offset ``start``, (hi - lo) a multiple
    of ``period``, when the alignment of the markers repeats every ``period`` markers; returns
    their bytes (uint8, flat), the next offset and the trailing padding of the last marker.
    The run is the template repeated; a short run is viewed as a structured array whose
    fields are the columns of each of the ``period`` markers, assigned at once."""
    blocks, layout, pos = [], [], start
    end = 0
    for _ in range(period):
        block, offs, size = _template(pos, *head, batch)
        blocks.append(block)
        layout.append((pos - start, tuple((key, offs[key]) for key in _COLUMN_TYPES)))
        end = offs["end"]
        pos += size
    unit = b"".join(blocks)
    reps = (hi - lo) // period
    if reps <= _SMALL_RUN:
        buf = np.frombuffer(unit * reps, dtype=np.uint8).copy()
        records = buf.view(_run_dtype(tuple(layout), len(unit)))
        for key, values in columns.items():
            for k in range(period):
                records[f"{key}{k}"] = values[lo + k:hi:period]
    else:  # long runs: each column copied as contiguous bytes (faster past a few thousand)
        grid = np.tile(np.frombuffer(unit, dtype=np.uint8), (reps, 1))
        for key, values in columns.items():
            vals = np.ascontiguousarray(values[lo:hi]).reshape(reps, period, -1)
            for k, (base, columns_at) in enumerate(layout):
                raw = np.ascontiguousarray(vals[:, k]).view(np.uint8).reshape(reps, -1)
                off = base + dict(columns_at)[key]
                grid[:, off:off + raw.shape[1]] = raw
        buf = grid.reshape(-1)
    pad = len(blocks[-1]) - end
    return buf, start + reps * len(unit), pad


#: messages of at most this many markers are written from a kept plan (:func:`_plan`)
_SMALL_MESSAGE = 64
#: (key of :func:`_layout`'s offsets, or None for the stamp at 0; width in bytes) of the parts
#: of a marker :func:`_planned` writes: stamp, id, the float64 columns, the float32 colour
_PARTS = ((None, 8), ("id", 4), ("position", 24), ("orientation", 32), ("scale", 24),
          ("color", 16))


@lru_cache(maxsize=64)
def _plan(frame: bytes, kinds: tuple[tuple[str, int, int, int], ...]
          ) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], int]:
    """A whole MarkerArray of the markers of ``kinds`` ((ns, type, action, count) per batch,
    counts > 0) in ``frame``: its bytes with every stamp and column zero (uint8, the last
    marker's trailing padding included); the index in it (intp, one row per marker) of the
    bytes of the stamps (8), ids (4), float64 position, orientation and scale (80) and
    float32 colours (16); the message's length. Laid out marker by marker as
    :func:`encode_marker_array` lays out its runs (the same templates at the same offsets)."""
    parts = [ENCAPSULATION, struct.pack("<I", sum(k[3] for k in kinds))]
    rows: list[list[np.ndarray]] = []
    pos, pad = 4, 0
    for ns, kind, action, count in kinds:
        for _ in range(count):
            unit, offsets, size = _layout(pos % 8, frame, ns, kind, action)
            starts = [4 + pos + (0 if key is None else offsets[key]) for key, _ in _PARTS]
            rows.append([np.arange(at, at + width) for at, (_, width) in zip(starts, _PARTS)])
            parts.append(unit)
            pos, pad = pos + size, size - offsets["end"]
    raw = b"".join(parts)

    def index(lo: int, hi: int) -> np.ndarray:
        return np.array([np.concatenate(r[lo:hi]) for r in rows], dtype=np.intp)

    return (np.frombuffer(raw, dtype=np.uint8).copy(),
            (index(0, 1), index(1, 2), index(2, 5), index(5, 6)), len(raw) - pad)


def _planned(sec: int, nanosec: int, frame: bytes, batches: list[MarkerBatch]) -> bytes | None:
    """The message of a few markers (at most :data:`_SMALL_MESSAGE`, one or more) written from
    its kept plan (:func:`_plan`): the template copied and each kind of column scattered in at
    once; None when the batches are not plain arrays of the expected sizes (then written run
    by run, which reshapes or raises as it does)."""
    full = [b for b in batches if len(b)]
    total = sum(len(b) for b in full)
    if not 0 < total <= _SMALL_MESSAGE:
        return None
    for b in full:
        n = len(b)
        if not (type(b.ids) is np.ndarray and b.ids.dtype.kind == "i" and b.ids.size == n
                and type(b.position) is np.ndarray and b.position.size == 3 * n
                and type(b.yaw) is np.ndarray and b.yaw.size == n
                and type(b.scale) is np.ndarray and b.scale.size == 3 * n
                and type(b.color) is np.ndarray and b.color.size == 4 * n
                and all(a.dtype.kind in "fiu" for a in (b.position, b.yaw, b.scale, b.color))):
            return None
    template, (at_stamp, at_id, at_f8, at_f4), length = _plan(
        frame, tuple((b.ns, int(b.type), int(b.action), len(b)) for b in full))
    orientation = np.empty((total, 4))
    elementary.z_rotations(np.concatenate([b.yaw for b in full], axis=None, dtype=np.float64),
                           orientation)
    f8 = np.concatenate((
        np.concatenate([b.position for b in full], axis=None, dtype=np.float64).reshape(total, 3),
        orientation,
        np.concatenate([b.scale for b in full], axis=None, dtype=np.float64).reshape(total, 3)),
        axis=1)
    buf = template.copy()
    buf[at_stamp] = np.frombuffer(pack_stamp(sec, nanosec), dtype=np.uint8)
    buf[at_id] = np.concatenate([b.ids for b in full], axis=None).astype("<i4").view(np.uint8
                                                                                    ).reshape(total, 4)
    buf[at_f8] = f8.view(np.uint8)
    buf[at_f4] = np.concatenate([b.color for b in full], axis=None).astype("<f4").view(
        np.uint8).reshape(total, 16)
    return buf[:length].tobytes()


def encode_marker_array(stamp_ns: int, frame_id: str, batches: list[MarkerBatch]) -> bytes:
    """CDR bytes of a ``visualization_msgs/msg/MarkerArray`` of the batches' markers in order,
    every header stamped ``stamp_ns`` (int ns) in ``frame_id``.

    Raises:
        ValueError: naming the argument, on a bad stamp or frame id.
    """
    sec, nanosec = split_stamp(stamp_ns, "stamp_ns")
    if not isinstance(frame_id, str) or "\x00" in frame_id:
        raise ValueError(f"frame_id: must be a str without NUL, got {frame_id!r}")
    head = (sec, nanosec, frame_id.encode("utf-8"))
    planned = _planned(sec, nanosec, head[2], batches)
    if planned is not None:
        return planned
    total = sum(len(b) for b in batches)
    parts: list = [ENCAPSULATION, struct.pack("<I", total)]
    pos, pad = 4, 0
    for batch in batches:
        n = len(batch)
        if n == 0:
            continue
        columns = _columns(batch)
        lo = 0
        while lo < n:
            # the pose's 8-byte alignment repeats after one marker (its length a multiple of
            # 8) or two; a lone marker first when the run after it repeats after one
            first = _template(pos, *head, batch)[2]
            if first % 8 == 0:
                hi, period = n, 1
            elif _template(pos + first, *head, batch)[2] % 8 == 0 or n - lo < 2:
                hi, period = lo + 1, 1
            else:
                hi, period = lo + (n - lo) // 2 * 2, 2
            data, pos, pad = _encode_run(pos, head, batch, columns, lo, hi, period)
            parts.append(data)
            lo = hi
    if pad:  # the last marker's trailing alignment is no part of the message
        parts[-1] = parts[-1][:len(parts[-1]) - pad]
    return b"".join(parts)  # one copy: numpy buffers joined as they are
