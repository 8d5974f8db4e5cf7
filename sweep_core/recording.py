"""MCAP recordings in the ROS 2 profile, written and read without a ROS installation.

Writing (:class:`Recorder`) uses ``mcap.writer.Writer``: profile ``ros2``, schemas in ``ros2msg``
encoding (default definitions from :data:`sweep_core.cdr.SCHEMAS`), messages in ``cdr``, channel
metadata ``offered_qos_profiles`` in rosbag2's YAML form, zstd (or lz4 / no) chunk compression,
chunk indexes, message indexes, statistics and summary written by ``close()``. The result plays
with ``ros2 bag play FILE.mcap`` and reads with ``mcap_ros2`` and ``rosbags``.

A recording is never lost: the chunk in progress is closed and the file flushed to the OS
whenever it reaches ``chunk_size`` bytes and at least every ``flush_interval_s`` seconds of wall
time (from ``write`` and from a background timer thread, so a paused run is flushed too).
Metadata records go to disk at once. A process killed with SIGKILL therefore leaves a file that
is readable up to its last flushed chunk; :func:`read_recording` and :func:`scan_recording` read
such a file (or one whose tail was cut off) up to its last complete record and report
``truncated = True`` instead of raising.

Reading uses mcap's own readers: the seeking reader (``mcap.reader.SeekingReader``) when the
file is complete (footer and summary present), else the sequential ``mcap.stream_reader.
StreamReader``, which stops at the first incomplete record. Messages come out in file order (the
order they were written).
"""
from __future__ import annotations

import os
import queue
import re
import threading
import time
from dataclasses import dataclass, field
from importlib.metadata import PackageNotFoundError, version
from typing import IO, Any, Iterable, Iterator, Mapping

import numpy as np
from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.records import Channel, Chunk, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import CompressionType, Writer

from . import cdr
from .errors import RecordingError

__all__ = [
    "BackgroundRecorder",
    "ChannelInfo",
    "DEFAULT_QOS_PROFILES",
    "RecordedMessage",
    "Recorder",
    "RecordingError",
    "RecordingInfo",
    "RecordingReader",
    "read_metadata",
    "read_recording",
    "scan_recording",
]

_MAGIC = b"\x89MCAP0\r\n"
# Footer record: opcode 0x02, length 20, then summary_start, summary_offset_start, crc.
_FOOTER_PREFIX = b"\x02\x14\x00\x00\x00\x00\x00\x00\x00"
_FOOTER_AND_MAGIC = 9 + 20 + 8
# Bytes a Message record adds to its payload inside a chunk (opcode, length, channel id,
# sequence, log time, publish time); used to decide when a chunk is full.
_MESSAGE_OVERHEAD = 1 + 8 + 2 + 4 + 8 + 8

_MSGTYPE_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*/msg/[A-Za-z][A-Za-z0-9_]*$")

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

_COMPRESSION = {
    "zstd": CompressionType.ZSTD,
    "lz4": CompressionType.LZ4,
    "none": CompressionType.NONE,
}


def _library_string() -> str:
    try:
        ours = version("sweep_ros")
    except PackageNotFoundError:
        ours = "dev"
    try:
        theirs = version("mcap")
    except PackageNotFoundError:
        theirs = "unknown"
    return f"sweep_ros/{ours} (mcap-python/{theirs})"


def _check_str_dict(data: Any, what: str) -> dict[str, str]:
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


def _close_quietly(f: IO[bytes]) -> None:
    """Closes a file whose buffered bytes may fail to write again (disk full)."""
    try:
        f.close()
    except OSError:
        pass


def _check_time(value: Any, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise RecordingError(f"{what}: must be an int number of nanoseconds, got {value!r}")
    value = int(value)
    if not 0 <= value < 2**64:
        raise RecordingError(f"{what}: {value} ns is outside the MCAP range [0, 2**64)")
    return value


class Recorder:
    """Writes an MCAP file in the ROS 2 profile.

    Usage::

        with Recorder("run.mcap", metadata={"scene": "corridor"}) as rec:
            rec.add_channel("/crowd/poses", "geometry_msgs/msg/PoseArray")
            rec.write("/crowd/poses", t_ns, cdr.encode_pose_array(t_ns, "map", q))

    Args:
        path: file to create (overwritten).
        metadata: written at once as a metadata record named ``"sweep_ros"``.
        chunk_size: close a chunk once its uncompressed content reaches this many bytes.
        flush_interval_s: close the chunk in progress and flush the file at least this often
            (wall time); ``None`` flushes only on full chunks and on ``close()``.
        compression: ``"zstd"`` (default), ``"lz4"`` or ``"none"``.

    Not safe for concurrent ``write`` calls from several threads without an outer lock (the
    internal lock only guards against the background flusher).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        metadata: Mapping[str, str] | None = None,
        chunk_size: int = 1 << 20,
        flush_interval_s: float | None = 1.0,
        compression: str = "zstd",
    ) -> None:
        self.path = os.fspath(path)
        if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size <= 0:
            raise RecordingError(f"chunk_size: must be a positive int of bytes, got {chunk_size!r}")
        if flush_interval_s is not None:
            ok = not isinstance(flush_interval_s, bool) and isinstance(flush_interval_s, (int, float))
            if not ok or not 0 < flush_interval_s < float("inf"):
                raise RecordingError(
                    f"flush_interval_s: must be a finite number of seconds > 0 or None, "
                    f"got {flush_interval_s!r}"
                )
        if compression not in _COMPRESSION:
            raise RecordingError(
                f"compression: {compression!r} is not one of {sorted(_COMPRESSION)}"
            )
        meta = None if metadata is None else _check_str_dict(metadata, "metadata")
        if not hasattr(Writer, "flush"):
            raise RecordingError(
                "mcap: the installed mcap.writer.Writer has no flush() "
                "(fix: pip install 'mcap>=1.6')"
            )
        self.chunk_size = chunk_size
        self.flush_interval_s = None if flush_interval_s is None else float(flush_interval_s)
        self.compression = compression
        try:
            self._file: IO[bytes] = open(self.path, "wb")
        except OSError as err:
            raise RecordingError(
                f"{self.path}: cannot create the recording ({err.strerror})"
            ) from None
        try:
            # The Writer's own size trigger is disabled (huge chunk_size): every chunk is closed
            # by _flush_locked(), so each closed chunk also reaches the OS at once.
            self._writer = Writer(
                self._file, chunk_size=2**62, compression=_COMPRESSION[compression]
            )
        except McapError as err:
            _close_quietly(self._file)
            raise RecordingError(
                f"compression: {compression!r} is unavailable ({err}) "
                "(fix: pip install zstandard lz4, or compression='none')"
            ) from None
        self._lock = threading.Lock()
        self._closed = False
        self._schemas: dict[tuple[str, str], int] = {}
        self._channels: dict[str, int] = {}
        self._channel_types: dict[int, str] = {}
        self._sequence: dict[int, int] = {}
        self._pending_bytes = 0
        self._pending_messages = 0
        self._flush_error: RecordingError | None = None
        self.message_count = 0
        self._last_flush = time.monotonic()
        try:
            self._writer.start(profile="ros2", library=_library_string())
            if meta is not None:
                self._writer.add_metadata("sweep_ros", meta)
            self._file.flush()
        except OSError as err:
            self._closed = True
            _close_quietly(self._file)
            raise RecordingError(
                f"{self.path}: cannot write the recording ({err.strerror or err}) "
                "(fix: free disk space or record elsewhere)"
            ) from None
        self._stop = threading.Event()
        self._flusher: threading.Thread | None = None
        if self.flush_interval_s is not None:
            self._flusher = threading.Thread(
                target=self._flush_loop, name=f"Recorder flusher {self.path}", daemon=True
            )
            self._flusher.start()

    # -- context manager ------------------------------------------------------------------------

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- channels, metadata, messages -----------------------------------------------------------

    def add_channel(
        self,
        topic: str,
        msgtype: str,
        definition: str | None = None,
        *,
        offered_qos_profiles: str = DEFAULT_QOS_PROFILES,
    ) -> int:
        """Registers ``topic`` with message type ``msgtype`` (``pkg/msg/Type``); returns its id.

        ``definition`` is the ``ros2msg`` text of the type with its dependencies; it defaults to
        ``sweep_core.cdr.SCHEMAS[msgtype]``. Adding a topic again with the same type returns the
        existing id. ``offered_qos_profiles`` is stored as channel metadata for ``ros2 bag play``
        (rosbag2's YAML list; ``""`` lets the player use its defaults).
        """
        self._check_open("add_channel")
        if not isinstance(topic, str) or not topic.startswith("/") or len(topic) < 2:
            raise RecordingError(
                f"topic: {topic!r} is not an absolute ROS topic name (fix: start it with '/', "
                "e.g. '/crowd/poses')"
            )
        if not isinstance(msgtype, str) or not _MSGTYPE_RE.match(msgtype):
            raise RecordingError(
                f"msgtype: {msgtype!r} is not a ROS 2 message type name "
                "(fix: write it as 'package/msg/Type', e.g. 'geometry_msgs/msg/PoseArray')"
            )
        if definition is None:
            definition = cdr.SCHEMAS.get(msgtype)
            if definition is None:
                raise RecordingError(
                    f"msgtype: no built-in definition for {msgtype!r} (built-in: "
                    f"{', '.join(sorted(cdr.SCHEMAS))}) (fix: pass definition= the ros2msg text "
                    "of the type followed by its dependencies)"
                )
        elif not isinstance(definition, str):
            raise RecordingError(
                f"definition: must be a str of ros2msg text, got {type(definition).__name__}"
            )
        if not isinstance(offered_qos_profiles, str):
            raise RecordingError("offered_qos_profiles: must be a YAML str (or '')")
        with self._lock:
            existing = self._channels.get(topic)
            if existing is not None:
                if self._channel_types[existing] != msgtype:
                    raise RecordingError(
                        f"topic: {topic} is already recorded as {self._channel_types[existing]}, "
                        f"cannot add it again as {msgtype} (fix: use another topic name)"
                    )
                return existing
            schema_key = (msgtype, definition)
            schema_id = self._schemas.get(schema_key)
            if schema_id is None:
                schema_id = self._writer.register_schema(
                    name=msgtype, encoding="ros2msg", data=definition.encode("utf-8")
                )
                self._schemas[schema_key] = schema_id
                self._pending_bytes += len(definition) + len(msgtype) + 20
            channel_id = self._writer.register_channel(
                topic=topic,
                message_encoding="cdr",
                schema_id=schema_id,
                metadata={"offered_qos_profiles": offered_qos_profiles},
            )
            self._pending_bytes += len(topic) + len(offered_qos_profiles) + 40
            self._channels[topic] = channel_id
            self._channel_types[channel_id] = msgtype
            self._sequence[channel_id] = 0
            return channel_id

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Writes a metadata record ``name`` with ``data`` (str to str) and flushes it to disk."""
        self._check_open("add_metadata")
        if not isinstance(name, str) or not name:
            raise RecordingError(f"name: metadata name must be a non-empty str, got {name!r}")
        checked = _check_str_dict(data, f"metadata {name!r}")
        with self._lock:
            try:
                self._writer.add_metadata(name, checked)
                self._file.flush()
            except OSError as err:
                raise RecordingError(
                    f"{self.path}: cannot write metadata {name!r} ({err.strerror or err}) "
                    "(fix: free disk space or record elsewhere)"
                ) from err

    def write(
        self,
        topic_or_channel_id: str | int,
        log_time_ns: int,
        data: bytes,
        publish_time_ns: int | None = None,
    ) -> None:
        """Appends one message (raw CDR ``data``) to a channel given by topic or id.

        ``publish_time_ns`` defaults to ``log_time_ns``.
        """
        channel_id = self._channels.get(topic_or_channel_id)  # type: ignore[arg-type]
        if channel_id is None:
            if isinstance(topic_or_channel_id, int) and not isinstance(topic_or_channel_id, bool) \
                    and topic_or_channel_id in self._channel_types:
                channel_id = topic_or_channel_id
            else:
                self._check_open("write")
                raise RecordingError(
                    f"topic: {topic_or_channel_id!r} has no channel in {self.path} "
                    f"(known: {sorted(self._channels)}) (fix: call add_channel() first)"
                )
        log_time = _check_time(log_time_ns, "log_time_ns")
        publish_time = log_time if publish_time_ns is None else _check_time(
            publish_time_ns, "publish_time_ns"
        )
        if not isinstance(data, (bytes, bytearray, memoryview)):
            raise RecordingError(f"data: must be bytes of CDR, got {type(data).__name__}")
        with self._lock:
            self._check_open("write")
            if self._flush_error is not None:
                raise self._flush_error
            seq = self._sequence[channel_id] = (self._sequence[channel_id] + 1) & 0xFFFFFFFF
            self._writer.add_message(
                channel_id=channel_id,
                log_time=log_time,
                data=bytes(data),
                publish_time=publish_time,
                sequence=seq,
            )
            self.message_count += 1
            self._pending_messages += 1
            self._pending_bytes += _MESSAGE_OVERHEAD + len(data)
            if self._pending_bytes >= self.chunk_size or (
                self.flush_interval_s is not None
                and time.monotonic() - self._last_flush >= self.flush_interval_s
            ):
                self._flush_locked()

    def flush(self) -> None:
        """Closes the chunk in progress (if it holds messages) and flushes the file to the OS."""
        with self._lock:
            if not self._closed:
                self._flush_locked()

    def close(self) -> None:
        """Writes the last chunk, the summary (statistics, indexes) and the footer; idempotent."""
        if self._closed:
            return
        self._stop.set()
        if self._flusher is not None and self._flusher is not threading.current_thread():
            self._flusher.join()
        with self._lock:
            if self._closed:
                return
            self._closed = True
            try:
                self._writer.finish()
                self._file.flush()
            except OSError as err:
                raise RecordingError(
                    f"{self.path}: cannot finish the recording ({err.strerror or err}); it stays "
                    "readable up to its last flushed chunk (fix: free disk space)"
                ) from err
            finally:
                _close_quietly(self._file)

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def topics(self) -> dict[str, str]:
        """Topic -> message type of every channel added so far."""
        return {t: self._channel_types[c] for t, c in self._channels.items()}

    # -- internals ------------------------------------------------------------------------------

    def _check_open(self, what: str) -> None:
        if self._closed:
            raise RecordingError(
                f"{self.path}: {what}() on a closed Recorder (fix: open a new Recorder)"
            )

    def _flush_locked(self) -> None:
        # Writer.flush() (public in mcap 1.6.0) closes the chunk in progress (a chunk without
        # messages is kept open), writes it with its message indexes, and flushes the stream we
        # gave it, so the bytes reach the OS and survive SIGKILL of this process.
        if self._flush_error is not None:
            raise self._flush_error
        if self._pending_messages:
            try:
                self._writer.flush()
            except OSError as err:
                self._flush_error = RecordingError(
                    f"{self.path}: cannot write the recording ({err.strerror or err}); what was "
                    "flushed before stays readable (fix: free disk space or record elsewhere)"
                )
                raise self._flush_error from err
            self._pending_bytes = 0
            self._pending_messages = 0
        self._last_flush = time.monotonic()

    def _flush_loop(self) -> None:
        interval = self.flush_interval_s
        assert interval is not None
        while not self._stop.wait(interval / 2):
            with self._lock:
                if self._closed or self._flush_error is not None:
                    return
                if self._pending_messages and time.monotonic() - self._last_flush >= interval:
                    try:
                        self._flush_locked()
                    except RecordingError:
                        return  # kept in _flush_error; the next write() raises it


class BackgroundRecorder:
    """A :class:`Recorder` fed from a background thread: ``write`` and ``metadata`` only
    enqueue, so the thread that steps never waits on chunk compression or the disk.

    Compression (zstd, lz4), zlib.crc32 and the file writes release the GIL, so they run beside
    the stepping thread on another core; mcap's writer still holds the GIL while it copies a
    message into its chunk and builds records in Python, which slows a 10 000-agent step
    (0.88 MB recorded) by about 0.3 ms (``sweep bench recording``). ``max_backlog`` > 0 bounds
    the queue (messages): ``write`` then blocks while it is full, so a writer that cannot keep
    up slows the run instead of filling the memory; 0 = unbounded.

    A Recorder error (disk full, ...) stops recording and is kept in ``error`` (later writes
    are dropped); what was flushed before stays readable. ``close()`` writes what is queued,
    the summary and the footer; writes after it are dropped.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        metadata: Mapping[str, str] | None = None,
        max_backlog: int = 0,
        **recorder_options: Any,
    ) -> None:
        self.recorder = Recorder(path, metadata=metadata, **recorder_options)
        self.path = self.recorder.path
        self.error: str | None = None
        self.written = 0
        self._closed = False
        self._queue: queue.Queue = queue.Queue(max_backlog)
        self._thread = threading.Thread(
            target=self._run, name=f"Recorder writer {self.path}", daemon=True
        )
        self._thread.start()

    def __enter__(self) -> BackgroundRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def add_channel(self, topic: str, msgtype: str, definition: str | None = None, *,
                    offered_qos_profiles: str = DEFAULT_QOS_PROFILES) -> int:
        """As :meth:`Recorder.add_channel` (at once, in the calling thread)."""
        return self.recorder.add_channel(
            topic, msgtype, definition, offered_qos_profiles=offered_qos_profiles
        )

    def write(self, topic: str, log_time_ns: int, data: bytes) -> None:
        """Queues one message for :meth:`Recorder.write`."""
        if self.error is None and not self._closed:
            self._queue.put(("message", topic, log_time_ns, data))

    def metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Queues a metadata record for :meth:`Recorder.add_metadata`."""
        if self.error is None and not self._closed:
            self._queue.put(("metadata", name, None, data))

    def flush(self) -> None:
        """Waits until everything queued so far is written, then flushes the file to the OS."""
        if not self._closed:
            done = threading.Event()
            self._queue.put(("flush", None, None, done))
            done.wait()

    @property
    def backlog(self) -> int:
        """Messages and metadata records queued and not yet written."""
        return self._queue.qsize()

    def _run(self) -> None:
        while (item := self._queue.get()) is not None:
            kind, name, log_time, data = item
            try:
                if self.error is not None:
                    pass  # recording stopped: drop
                elif kind == "message":
                    self.recorder.write(name, log_time, data)
                    self.written += 1
                elif kind == "metadata":
                    self.recorder.add_metadata(name, data)
                else:
                    self.recorder.flush()
            except Exception as err:  # noqa: BLE001 - kept for the caller; the thread lives on
                self.error = str(err) if isinstance(err, RecordingError) else repr(err)
            finally:
                if kind == "flush":
                    data.set()

    def close(self) -> None:
        """Writes what is queued, then the summary and the footer; idempotent."""
        self._closed = True
        if self._thread.is_alive():
            self._queue.put(None)
            self._thread.join()
        try:
            self.recorder.close()
        except RecordingError as err:
            self.error = self.error or str(err)


# ---------------------------------------------------------------------------------------------
# Reading
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class RecordedMessage:
    """One message of a recording; ``data`` is the raw CDR (decode with sweep_core.cdr)."""

    topic: str
    msgtype: str
    log_time_ns: int
    publish_time_ns: int
    data: bytes


@dataclass
class ChannelInfo:
    id: int
    topic: str
    msgtype: str
    message_encoding: str
    message_count: int = 0
    metadata: dict[str, str] = field(default_factory=dict)


@dataclass
class RecordingInfo:
    """What :func:`scan_recording` found.

    ``truncated`` is True when the file has no valid footer/summary (killed writer or cut-off
    tail); then the counts and times cover the complete records only and ``error`` says where
    reading stopped. ``start_ns``/``end_ns`` are the smallest/largest log time (None if empty).
    """

    path: str
    truncated: bool
    message_count: int
    start_ns: int | None
    end_ns: int | None
    channels: dict[str, ChannelInfo]
    metadata: dict[str, dict[str, str]]
    profile: str = ""
    library: str = ""
    chunk_count: int = 0
    error: str | None = None

    @property
    def duration_ns(self) -> int:
        if self.start_ns is None or self.end_ns is None:
            return 0
        return self.end_ns - self.start_ns


def _open_for_reading(path: str | os.PathLike[str]) -> tuple[str, IO[bytes]]:
    p = os.fspath(path)
    try:
        f = open(p, "rb")
    except OSError as err:
        raise RecordingError(f"{p}: cannot open the recording ({err.strerror})") from None
    head = f.read(len(_MAGIC))
    if head != _MAGIC[: len(head)]:
        f.close()
        raise RecordingError(
            f"{p}: not an MCAP file (starts with {head!r}) (fix: pass a .mcap written by "
            "sweep_ros or ros2 bag record -s mcap)"
        )
    f.seek(0)
    return p, f


def _is_complete(f: IO[bytes]) -> bool:
    """True if the file ends with a footer record and the closing magic."""
    size = f.seek(0, os.SEEK_END)
    if size < len(_MAGIC) + _FOOTER_AND_MAGIC:
        return False
    f.seek(size - _FOOTER_AND_MAGIC)
    tail = f.read(_FOOTER_AND_MAGIC)
    f.seek(0)
    return tail.startswith(_FOOTER_PREFIX) and tail.endswith(_MAGIC)


class RecordingReader:
    """Iterator over the messages of a recording (see :func:`read_recording`).

    After the iteration ends, ``truncated`` tells whether the file was cut short (``None``
    before), ``error`` says where reading stopped, and ``metadata`` holds the metadata records
    seen (all of them for a complete file).
    """

    def __init__(self, path: str | os.PathLike[str], topics: Iterable[str] | None = None) -> None:
        if isinstance(topics, str):
            topics = [topics]
        self.topics = None if topics is None else set(topics)
        self.path, self._file = _open_for_reading(path)
        self.truncated: bool | None = None
        self.error: str | None = None
        self.metadata: dict[str, dict[str, str]] = {}
        self._it = self._generate()

    def __iter__(self) -> RecordingReader:
        return self

    def __next__(self) -> RecordedMessage:
        return next(self._it)

    def close(self) -> None:
        self._it.close()
        self._file.close()

    def __enter__(self) -> RecordingReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _generate(self) -> Iterator[RecordedMessage]:
        try:
            if _is_complete(self._file):
                try:
                    reader = SeekingReader(self._file)
                    summary = reader.get_summary()
                except Exception:  # noqa: BLE001 - a damaged footer: read sequentially instead
                    summary = None
                if summary is not None and summary.chunk_indexes:
                    for md in reader.iter_metadata():
                        self.metadata[md.name] = dict(md.metadata)
                    topics = None if self.topics is None else sorted(self.topics)
                    messages = reader.iter_messages(topics=topics, log_time_order=False)
                    while True:
                        try:
                            schema, channel, message = next(messages)
                        except StopIteration:
                            break
                        except Exception as err:  # noqa: BLE001 - report which file
                            raise RecordingError(
                                f"{self.path}: damaged recording, a chunk listed in its summary "
                                f"cannot be read ({type(err).__name__}: {err})"
                            ) from err
                        yield RecordedMessage(
                            channel.topic,
                            schema.name if schema is not None else "",
                            message.log_time,
                            message.publish_time,
                            message.data,
                        )
                    self.truncated = False
                    return
                self._file.seek(0)
            yield from self._stream()
        finally:
            self._file.close()

    def _stream(self) -> Iterator[RecordedMessage]:
        schemas: dict[int, str] = {}
        channels: dict[int, tuple[str, str]] = {}
        records = StreamReader(self._file, validate_crcs=False).records
        footer_seen = False
        while True:
            try:
                record = next(records)
            except StopIteration:
                break
            except Exception as err:  # noqa: BLE001 - any failure past here is the cut-off tail
                self.error = _describe_stop(err, self._file)
                break
            if isinstance(record, Message):
                ch = channels.get(record.channel_id)
                if ch is None:
                    continue
                if self.topics is not None and ch[0] not in self.topics:
                    continue
                yield RecordedMessage(
                    ch[0], ch[1], record.log_time, record.publish_time, record.data
                )
            elif isinstance(record, Schema):
                schemas[record.id] = record.name
            elif isinstance(record, Channel):
                channels[record.id] = (record.topic, schemas.get(record.schema_id, ""))
            elif isinstance(record, Metadata):
                self.metadata[record.name] = dict(record.metadata)
            elif isinstance(record, Footer):
                footer_seen = True
        self.truncated = not (footer_seen and self.error is None)


def _describe_stop(err: Exception, f: IO[bytes]) -> str:
    try:
        pos = f.tell()
        size = os.fstat(f.fileno()).st_size
        where = f" near byte {pos} of {size}"
    except (OSError, ValueError):
        where = ""
    detail = f"{type(err).__name__}: {err}" if str(err) else type(err).__name__
    return f"incomplete record{where} ({detail})"


def read_recording(
    path: str | os.PathLike[str], topics: Iterable[str] | None = None
) -> RecordingReader:
    """Iterates over the messages of ``path`` (optionally only ``topics``) in file order.

    Returns a :class:`RecordingReader`: iterate it for :class:`RecordedMessage` items; once
    exhausted, ``reader.truncated`` is True if the file was cut short (every complete message
    up to the last complete chunk was still yielded, and no exception is raised for the cut).

    Raises:
        RecordingError: the file cannot be opened or is not MCAP.
    """
    return RecordingReader(path, topics)


def read_metadata(path: str | os.PathLike[str]) -> dict[str, dict[str, str]]:
    """Metadata records of ``path``: name -> {key: value}; works on truncated files too."""
    p, f = _open_for_reading(path)
    with f:
        if _is_complete(f):
            try:
                reader = SeekingReader(f)
                if reader.get_summary() is not None:
                    return {md.name: dict(md.metadata) for md in reader.iter_metadata()}
            except Exception:  # noqa: BLE001 - damaged summary: scan instead
                pass
            f.seek(0)
        out: dict[str, dict[str, str]] = {}
        try:
            for record in StreamReader(f, emit_chunks=True).records:
                if isinstance(record, Metadata):
                    out[record.name] = dict(record.metadata)
        except Exception:  # noqa: BLE001 - cut-off tail
            pass
        return out


def scan_recording(path: str | os.PathLike[str]) -> RecordingInfo:
    """Counts, time range, channels, metadata and the truncated flag of ``path``.

    Uses the summary of a complete file (fast); scans a truncated one up to its last complete
    record.
    """
    p, f = _open_for_reading(path)
    with f:
        if _is_complete(f):
            try:
                info = _scan_summary(p, f)
            except Exception:  # noqa: BLE001 - damaged summary: scan instead
                info = None
            if info is not None:
                return info
            f.seek(0)
        return _scan_stream(p, f)


def _scan_summary(p: str, f: IO[bytes]) -> RecordingInfo | None:
    reader = SeekingReader(f)
    summary = reader.get_summary()
    if summary is None or summary.statistics is None:
        return None
    header = reader.get_header()
    stats = summary.statistics
    channels: dict[str, ChannelInfo] = {}
    for cid, ch in summary.channels.items():
        schema = summary.schemas.get(ch.schema_id)
        channels[ch.topic] = ChannelInfo(
            cid,
            ch.topic,
            schema.name if schema is not None else "",
            ch.message_encoding,
            stats.channel_message_counts.get(cid, 0),
            dict(ch.metadata),
        )
    metadata = {md.name: dict(md.metadata) for md in reader.iter_metadata()}
    empty = stats.message_count == 0
    return RecordingInfo(
        path=p,
        truncated=False,
        message_count=stats.message_count,
        start_ns=None if empty else stats.message_start_time,
        end_ns=None if empty else stats.message_end_time,
        channels=channels,
        metadata=metadata,
        profile=header.profile,
        library=header.library,
        chunk_count=stats.chunk_count,
    )


def _scan_stream(p: str, f: IO[bytes]) -> RecordingInfo:
    schemas: dict[int, str] = {}
    by_id: dict[int, ChannelInfo] = {}
    metadata: dict[str, dict[str, str]] = {}
    header: Header | None = None
    count = 0
    start: int | None = None
    end: int | None = None
    chunks = 0
    footer_seen = False
    error = None
    records = StreamReader(f, emit_chunks=True).records
    pending: list[Any] = []
    while True:
        if pending:
            record = pending.pop()
        else:
            try:
                record = next(records)
                if isinstance(record, Chunk):
                    pending = breakup_chunk(record)[::-1]
                    chunks += 1
                    continue
            except StopIteration:
                break
            except Exception as err:  # noqa: BLE001 - cut-off tail
                error = _describe_stop(err, f)
                break
        if isinstance(record, Message):
            ch = by_id.get(record.channel_id)
            if ch is not None:
                ch.message_count += 1
            count += 1
            t = record.log_time
            start = t if start is None or t < start else start
            end = t if end is None or t > end else end
        elif isinstance(record, Schema):
            schemas[record.id] = record.name
        elif isinstance(record, Channel):
            if record.id not in by_id:
                by_id[record.id] = ChannelInfo(
                    record.id,
                    record.topic,
                    schemas.get(record.schema_id, ""),
                    record.message_encoding,
                    0,
                    dict(record.metadata),
                )
        elif isinstance(record, Metadata):
            metadata[record.name] = dict(record.metadata)
        elif isinstance(record, Header):
            header = record
        elif isinstance(record, Footer):
            footer_seen = True
    return RecordingInfo(
        path=p,
        truncated=not (footer_seen and error is None),
        message_count=count,
        start_ns=start,
        end_ns=end,
        channels={ch.topic: ch for ch in by_id.values()},
        metadata=metadata,
        profile=header.profile if header else "",
        library=header.library if header else "",
        chunk_count=chunks,
        error=error,
    )
