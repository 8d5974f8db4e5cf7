"""The MCAP writer (:class:`Recorder`); see :mod:`sweep_core.io.recording`."""
from __future__ import annotations

import os
import threading
import time
from collections.abc import Iterable, Mapping
from typing import IO

from mcap.exceptions import McapError
from mcap.writer import Writer

from sweep_core.errors import RecordingError
from sweep_core.io import cdr
from sweep_core.io.outputs import open_locked
from sweep_core.io.recording.format import (
    COMPRESSION,
    DEFAULT_QOS_PROFILES,
    MESSAGE_OVERHEAD,
    MSGTYPE_RE,
    check_str_dict,
    check_time,
    close_quietly,
    library_string,
)


class Recorder:
    """Writes an MCAP file in the ROS 2 profile.

    Usage::

        with Recorder("run.mcap", metadata={"scene": "corridor"}) as rec:
            rec.add_channel("/crowd/poses", "geometry_msgs/msg/PoseArray")
            rec.write("/crowd/poses", t_ns, cdr.encode_pose_array(t_ns, "map", q))

    Args:
        path: file to create (a regular file there is overwritten; one of ``inputs``, a
            folder, a device or a FIFO is refused, and so is a file another Recorder is writing:
            the file is locked while it is written, see :mod:`sweep_core.io.outputs`).
        metadata: written at once as a metadata record named ``"sweep_ros"``.
        chunk_size: close a chunk once its uncompressed content reaches this many bytes.
        flush_interval_s: close the chunk in progress and flush the file at least this often
            (wall time); ``None`` flushes only on full chunks and on ``close()``.
        compression: ``"zstd"`` (default), ``"lz4"`` or ``"none"``.
        inputs: files the run reads (its scene, its map): ``path`` may be none of them.
        other: how to name another file, the fix in errors (``--out OTHER``, ``record:=OTHER``).

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
        inputs: Iterable[str | os.PathLike[str] | None] = (),
        other: str = "--out OTHER",
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
        if compression not in COMPRESSION:
            raise RecordingError(
                f"compression: {compression!r} is not one of {sorted(COMPRESSION)}"
            )
        meta = None if metadata is None else check_str_dict(metadata, "metadata")
        if not hasattr(Writer, "flush"):
            raise RecordingError(
                "mcap: the installed mcap.writer.Writer has no flush() "
                "(fix: pip install 'mcap>=1.6')"
            )
        self.chunk_size = chunk_size
        self.flush_interval_s = None if flush_interval_s is None else float(flush_interval_s)
        self.compression = compression
        # checked, created without truncation, locked, then emptied: a second writer of the
        # same file is refused before it touches the first one's data
        self._file: IO[bytes] = os.fdopen(open_locked(self.path, inputs, other=other), "wb")
        try:
            # The Writer's own size trigger is disabled (huge chunk_size): every chunk is closed
            # by _flush_locked(), so each closed chunk also reaches the OS at once.
            self._writer = Writer(
                self._file, chunk_size=2**62, compression=COMPRESSION[compression]
            )
        except McapError as err:
            close_quietly(self._file)
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
            self._writer.start(profile="ros2", library=library_string())
            if meta is not None:
                self._writer.add_metadata("sweep_ros", meta)
            self._file.flush()
        except OSError as err:
            self._closed = True
            close_quietly(self._file)
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
        if not isinstance(msgtype, str) or not MSGTYPE_RE.match(msgtype):
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
        checked = check_str_dict(data, f"metadata {name!r}")
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
        log_time = check_time(log_time_ns, "log_time_ns")
        publish_time = log_time if publish_time_ns is None else check_time(
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
            self._pending_bytes += MESSAGE_OVERHEAD + len(data)
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
                close_quietly(self._file)

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
