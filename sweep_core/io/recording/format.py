"""MCAP constants and small helpers shared by the writer, the readers and the scanner: magic,
footer layout, rosbag2's QoS YAML, compression names, argument checks."""
from __future__ import annotations

import os
import re
import stat
from collections.abc import Mapping
from importlib.metadata import PackageNotFoundError, version
from typing import IO, Any

import numpy as np
from mcap.writer import CompressionType

from sweep_core.checks import file_kind
from sweep_core.errors import RecordingError

MAGIC = b"\x89MCAP0\r\n"
# Footer record: opcode 0x02, length 20, then summary_start, summary_offset_start, crc.
FOOTER_PREFIX = b"\x02\x14\x00\x00\x00\x00\x00\x00\x00"
FOOTER_AND_MAGIC = 9 + 20 + 8
# Bytes a Message record adds to its payload inside a chunk (opcode, length, channel id,
# sequence, log time, publish time); used to decide when a chunk is full.
MESSAGE_OVERHEAD = 1 + 8 + 2 + 4 + 8 + 8

MSGTYPE_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*/msg/[A-Za-z][A-Za-z0-9_]*$")

# One offered profile, rosbag2 (metadata version >= 9) YAML: a reliable, volatile, keep-last
# publisher with no deadline / lifespan / lease (infinite durations as rmw reports them).
_INF = "    sec: 9223372036\n    nsec: 854775807\n"
DEFAULT_QOS_PROFILES = (
    "- history: keep_last\n"
    "  depth: 10\n"
    "  reliability: reliable\n"
    "  durability: volatile\n"
    "  deadline:\n" + _INF + "  lifespan:\n" + _INF + "  liveliness: automatic\n"
    "  liveliness_lease_duration:\n" + _INF + "  avoid_ros_namespace_conventions: false\n"
)


def qos_profiles(depth: int = 10, transient_local: bool = False) -> str:
    """rosbag2's offered_qos_profiles YAML for a reliable keep-last publisher of ``depth``
    (transient-local durability for a latched topic such as walls or navigation_field)."""
    text = DEFAULT_QOS_PROFILES.replace("depth: 10", f"depth: {depth}")
    if transient_local:
        text = text.replace("durability: volatile", "durability: transient_local")
    return text


COMPRESSION = {
    "zstd": CompressionType.ZSTD,
    "lz4": CompressionType.LZ4,
    "none": CompressionType.NONE,
}


def library_string() -> str:
    try:
        ours = version("sweep_ros")
    except PackageNotFoundError:
        ours = "dev"
    try:
        theirs = version("mcap")
    except PackageNotFoundError:
        theirs = "unknown"
    return f"sweep_ros/{ours} (mcap-python/{theirs})"


def check_str_dict(data: Any, what: str) -> dict[str, str]:
    if not isinstance(data, Mapping):
        raise RecordingError(f"{what}: must be a dict of str to str, got {type(data).__name__}")
    out = {}
    for k, v in data.items():
        if not isinstance(k, str) or not isinstance(v, str):
            raise RecordingError(
                f"{what}: keys and values must be str, got {k!r}: {v!r} "
                "(fix: convert values with str() or json.dumps())"
            )
        out[k] = v
    return out


def close_quietly(f: IO[bytes]) -> None:
    """Closes a file whose buffered bytes may fail to write again (disk full)."""
    try:
        f.close()
    except OSError:
        pass


def check_time(value: Any, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise RecordingError(f"{what}: must be an int number of nanoseconds, got {value!r}")
    value = int(value)
    if not 0 <= value < 2**64:
        raise RecordingError(f"{what}: {value} ns is outside the MCAP range [0, 2**64)")
    return value


def open_for_reading(path: str | os.PathLike[str]) -> tuple[str, IO[bytes]]:
    """``path`` opened for reading once it is known to be a regular file that starts with the
    MCAP magic (a FIFO or a device is refused before it is opened: reading one could block or
    never end). Errors name the file, never its contents."""
    p = os.fspath(path)
    try:
        mode = os.stat(p).st_mode
        if not stat.S_ISREG(mode):
            raise RecordingError(f"{p}: is {file_kind(mode)}, not a recording file (fix: pass "
                                 "a .mcap file written by sweep_ros or ros2 bag record -s mcap)")
        f = open(p, "rb")
    except OSError as err:
        raise RecordingError(f"{p}: cannot open the recording ({err.strerror})") from None
    if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):  # replaced since the check
        f.close()
        raise RecordingError(f"{p}: is not a regular file (fix: pass a .mcap file)")
    head = f.read(len(MAGIC))
    if head != MAGIC[: len(head)]:
        f.close()
        raise RecordingError(
            f"{p}: not an MCAP file (it does not start with the MCAP magic bytes) (fix: pass a "
            ".mcap written by sweep_ros or ros2 bag record -s mcap)"
        )
    f.seek(0)
    return p, f


def is_complete(f: IO[bytes]) -> bool:
    """True if the file ends with a footer record and the closing magic."""
    size = f.seek(0, os.SEEK_END)
    if size < len(MAGIC) + FOOTER_AND_MAGIC:
        return False
    f.seek(size - FOOTER_AND_MAGIC)
    tail = f.read(FOOTER_AND_MAGIC)
    f.seek(0)
    return tail.startswith(FOOTER_PREFIX) and tail.endswith(MAGIC)


def describe_stop(err: Exception, f: IO[bytes]) -> str:
    try:
        pos = f.tell()
        size = os.fstat(f.fileno()).st_size
        where = f" near byte {pos} of {size}"
    except (OSError, ValueError):
        where = ""
    text = str(err)
    # the reader's own words only: a message that quotes the file's bytes is not shown
    quotes = "b'" in text or 'b"' in text or "\\x" in text
    detail = f"{type(err).__name__}: {text}" if text and not quotes else type(err).__name__
    return f"incomplete record{where} ({detail})"
