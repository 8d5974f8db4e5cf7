"""CDR wire helpers shared by the encoders and decoders: encapsulation header, stamps split
into builtin_interfaces/Time, strings, padding, and the per-thread reusable output buffers."""
from __future__ import annotations

import struct
import threading
from functools import lru_cache
from typing import Any

import numpy as np

ENCAPSULATION = b"\x00\x01\x00\x00"  # CDR_LE, options 0
NS_PER_S = 1_000_000_000
_INT32_MIN = -(2**31)
_INT32_MAX = 2**31 - 1
_STAMP_MIN = _INT32_MIN * NS_PER_S
_STAMP_MAX = (_INT32_MAX + 1) * NS_PER_S - 1
PAD = (b"", b"\x00", b"\x00\x00", b"\x00\x00\x00", b"\x00" * 4, b"\x00" * 5, b"\x00" * 6,
        b"\x00" * 7)

_pack_time_strlen = struct.Struct("<iII").pack
#: a builtin_interfaces/Time (sec int32, nanosec uint32)
pack_stamp = struct.Struct("<iI").pack
pack_u32 = struct.Struct("<I").pack
pack_2u32 = struct.Struct("<II").pack
pack_3u32 = struct.Struct("<III").pack
_unpack_time_strlen = struct.Struct("<iII").unpack_from
unpack_u32 = struct.Struct("<I").unpack_from
_unpack_2u32 = struct.Struct("<II").unpack_from
unpack_3u32 = struct.Struct("<III").unpack_from


def split_stamp(stamp_ns: Any, name: str) -> tuple[int, int]:
    if isinstance(stamp_ns, bool) or not isinstance(stamp_ns, (int, np.integer)):
        raise ValueError(f"{name}: must be an int number of nanoseconds, got {stamp_ns!r}")
    stamp_ns = int(stamp_ns)
    if not _STAMP_MIN <= stamp_ns <= _STAMP_MAX:
        raise ValueError(
            f"{name}: {stamp_ns} ns is outside builtin_interfaces/Time (sec must fit int32, "
            f"i.e. {_STAMP_MIN} <= {name} <= {_STAMP_MAX})"
        )
    sec, nanosec = divmod(stamp_ns, NS_PER_S)
    return sec, nanosec


@lru_cache(maxsize=256)
def _string_block(frame_id: str, name: str) -> bytes:
    """uint32 length (with NUL) + UTF-8 bytes + NUL; the caller pads."""
    if not isinstance(frame_id, str):
        raise ValueError(f"{name}: must be a str, got {type(frame_id).__name__}")
    if "\x00" in frame_id:
        raise ValueError(f"{name}: must not contain a NUL character, got {frame_id!r}")
    raw = frame_id.encode("utf-8")
    return raw + b"\x00"


def frame_bytes(frame_id: Any, name: str) -> bytes:
    """A CDR string's bytes (UTF-8 + NUL) of ``frame_id``, checked (ValueError naming
    ``name``); kept for the strings seen last."""
    if not isinstance(frame_id, str):
        raise ValueError(f"{name}: must be a str, got {type(frame_id).__name__}")
    return _string_block(frame_id, name)


_scratch_local = threading.local()
_SCRATCH_KEPT = 8  # layouts kept per thread (the oldest is dropped beyond)


def scratch(key: tuple, size: int) -> list:
    """``[buffer, state]`` kept for one message layout in this thread: a zeroed uint8 buffer of
    ``size`` bytes when new (state None), else as the last encoder of that layout left it.

    Reusing the buffer spares a fresh allocation per message, whose page faults cost more than
    the encoding (about 0.3 ms for the 560 kB of 10 000 poses)."""
    cache = getattr(_scratch_local, "buffers", None)
    if cache is None:
        cache = _scratch_local.buffers = {}
    entry = cache.pop(key, None)
    if entry is None:
        if len(cache) >= _SCRATCH_KEPT:
            cache.pop(next(iter(cache)))
        entry = [np.zeros(size, dtype=np.uint8), None]
    cache[key] = entry  # most recently used last
    return entry


def header_prefix(stamp_ns: Any, frame_id: Any) -> bytes:
    """Encapsulation + std_msgs/Header, padded to a 4-byte boundary of the payload."""
    sec, nanosec = split_stamp(stamp_ns, "stamp_ns")
    fid = frame_bytes(frame_id, "frame_id")
    # payload offset after the string: 12 + len(fid); pad to 4
    return b"".join(
        (ENCAPSULATION, _pack_time_strlen(sec, nanosec, len(fid)), fid, PAD[-len(fid) % 4])
    )


