"""A recorder whose compression and disk writes run on a thread of their own
(:class:`BackgroundRecorder`), shared by ``sweep run`` and the node."""
from __future__ import annotations

import os
import queue
import threading
from collections.abc import Callable, Mapping
from typing import Any

from sweep_core.errors import RecordingError
from sweep_core.io.recording.format import DEFAULT_QOS_PROFILES
from sweep_core.io.recording.writer import Recorder


class BackgroundRecorder:
    """A :class:`Recorder` fed from a background thread: ``write`` and ``metadata`` only
    enqueue, so the thread that steps never waits on chunk compression or the disk.

    Compression (zstd, lz4), zlib.crc32 and the file writes release the GIL, so they run beside
    the stepping thread on another core; mcap's writer still holds the GIL while it copies a
    message into its chunk and builds records in Python, which slows a 10 000-agent step
    (0.88 MB recorded) by about 0.3 ms (``sweep bench recording``). ``max_backlog`` > 0 bounds
    the queue (messages): ``write`` then blocks while it is full, so a writer that cannot keep
    up slows the run instead of filling the memory; 0 = unbounded. A :meth:`write_many` batch
    counts as one entry.

    A Recorder error (disk full, ...) stops recording and is kept in ``error`` (later writes
    are dropped); what was flushed before stays readable. ``on_error(message)``, when given,
    is called once, on the writer thread, as soon as that happens (the node logs it at once).
    ``close()`` writes what is queued, the summary and the footer; writes after it are dropped.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        metadata: Mapping[str, str] | None = None,
        max_backlog: int = 0,
        on_error: Callable[[str], None] | None = None,
        **recorder_options: Any,
    ) -> None:
        self.recorder = Recorder(path, metadata=metadata, **recorder_options)
        self._on_error = on_error
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

    def write_many(self, messages: list[tuple[str, int, bytes]]) -> None:
        """Queues messages ``(topic, log_time_ns, data)`` for :meth:`Recorder.write`, in order,
        as one entry of the queue (one wake-up of the writer thread: what a stepping loop
        writing several topics per step hands over)."""
        if messages and self.error is None and not self._closed:
            self._queue.put(("messages", None, None, messages))

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
        """Entries queued and not yet written (messages, batches of them, metadata records)."""
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
                elif kind == "messages":
                    write = self.recorder.write
                    for topic, stamp, payload in data:
                        write(topic, stamp, payload)
                        self.written += 1
                elif kind == "metadata":
                    self.recorder.add_metadata(name, data)
                else:
                    self.recorder.flush()
            except Exception as err:  # noqa: BLE001 - kept for the caller; the thread lives on
                self.error = str(err) if isinstance(err, RecordingError) else repr(err)
                self._report()
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
            if self.error is None:
                self.error = str(err)
                self._report()

    def _report(self) -> None:
        """Calls ``on_error`` with the first error (once; its own failure is ignored)."""
        callback, self._on_error = self._on_error, None
        if callback is not None and self.error is not None:
            try:
                callback(self.error)
            except Exception:  # noqa: BLE001 - a logging failure must not stop the writer
                pass
