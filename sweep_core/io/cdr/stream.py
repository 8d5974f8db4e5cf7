"""A sequential CDR (XCDR1, little endian) writer and reader for small messages of fixed shape
(the robot's odometry, commands, scans and transforms): fields in order, each aligned to its own
size relative to the first payload byte, padding zero."""
from __future__ import annotations

import struct
from functools import lru_cache
from typing import Any

import numpy as np

from sweep_core.io.cdr.wire import ENCAPSULATION, NS_PER_S, PAD, frame_bytes, split_stamp


@lru_cache(maxsize=128)
def _packer(fmt: str) -> tuple[Any, int]:
    """(pack function, alignment in bytes) of ``fmt``: one primitive type, repeated."""
    return struct.Struct("<" + fmt).pack, struct.calcsize("<" + fmt[-1])


class CdrWriter:
    """Appends fields to one CDR buffer; ``bytes()`` gives the message with its encapsulation."""

    def __init__(self) -> None:
        self.parts: list[bytes] = [ENCAPSULATION]
        self.offset = 0  # payload bytes written so far

    def _put(self, raw: bytes) -> None:
        self.parts.append(raw)
        self.offset += len(raw)

    def align(self, size: int) -> None:
        pad = -self.offset % size
        if pad:
            self._put(PAD[pad])

    def pack(self, fmt: str, *values: Any) -> None:
        """Values of one primitive type (``fmt`` a single struct code, repeated)."""
        pack, size = _packer(fmt)
        self.align(size)
        self._put(pack(*values))

    def raw(self, data: bytes, size: int) -> None:
        """Bytes already encoded (e.g. a run of zeros), aligned to ``size`` first."""
        self.align(size)
        self._put(data)

    def string(self, text: str, name: str) -> None:
        raw = frame_bytes(text, name)  # checked, UTF-8, NUL-terminated
        self.pack("I", len(raw))
        self._put(raw)

    def header(self, stamp_ns: int, frame_id: str) -> None:
        sec, nanosec = split_stamp(stamp_ns, "stamp_ns")
        self.pack("iI", sec, nanosec)
        self.string(frame_id, "frame_id")

    def float32_sequence(self, values: np.ndarray) -> None:
        self.pack("I", len(values))
        if len(values):
            self.align(4)
            self._put(np.ascontiguousarray(values, dtype="<f4").tobytes())

    def bytes(self) -> bytes:
        return b"".join(self.parts)


@lru_cache(maxsize=128)
def header_tail(strings: tuple[tuple[str, str], ...], align: int, start: int = 0) -> bytes:
    """The bytes :class:`CdrWriter` writes after a header's stamp (at payload offset ``start``,
    a multiple of 4) for the strings ((text, name) each: a header's ``frame_id``, then e.g. a
    ``child_frame_id``) and the padding to the next multiple of ``align`` bytes: what a
    message of fixed layout puts between its stamp and its first number. Raises ValueError
    naming a bad string."""
    w = CdrWriter()
    w.offset = start
    w.pack("iI", 0, 0)
    for text, name in strings:
        w.string(text, name)
    w.align(align)
    return w.bytes()[12:]


class CdrReader:
    """Reads fields in order from a CDR buffer; a short buffer raises ValueError naming the
    message type and the part."""

    def __init__(self, data: Any, what: str) -> None:
        try:
            mv = memoryview(data)
        except TypeError:
            raise ValueError(
                f"data: a {what} must be bytes-like, got {type(data).__name__}") from None
        if mv.ndim != 1 or mv.itemsize != 1:
            mv = mv.cast("B")
        if len(mv) < 4 or mv[0] != 0 or mv[1] != 1:
            raise ValueError(f"data: not a little-endian CDR {what} (expected 00 01 first)")
        self.mv = mv
        self.what = what
        self.offset = 0

    def _need(self, size: int, part: str) -> int:
        start = 4 + self.offset
        if start + size > len(self.mv):
            raise ValueError(f"data: {self.what} is truncated in {part} (needs {start + size} "
                             f"bytes, has {len(self.mv)})")
        self.offset += size
        return start

    def align(self, size: int) -> None:
        self.offset += -self.offset % size

    def unpack(self, fmt: str, part: str) -> tuple:
        self.align(struct.calcsize("<" + fmt[-1]))
        start = self._need(struct.calcsize("<" + fmt), part)
        return struct.unpack_from("<" + fmt, self.mv, start)

    def string(self, part: str) -> str:
        (length,) = self.unpack("I", part)
        start = self._need(length, part)
        raw = bytes(self.mv[start:start + length])
        return raw.removesuffix(b"\x00").decode("utf-8", errors="replace")

    def header(self) -> tuple[int, str]:
        sec, nanosec = self.unpack("iI", "header.stamp")
        return sec * NS_PER_S + nanosec, self.string("header.frame_id")

    def float32_sequence(self, part: str) -> np.ndarray:
        (n,) = self.unpack("I", part)
        if n == 0:
            return np.zeros(0, dtype=np.float32)
        self.align(4)
        start = self._need(4 * n, part)
        return np.frombuffer(self.mv, dtype="<f4", count=n, offset=start).astype(np.float32)
