"""Reading a recording message by message, complete or cut short (:func:`read_recording`,
:func:`read_metadata`)."""
from __future__ import annotations

import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

from mcap.reader import SeekingReader
from mcap.records import Channel, Chunk, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

from sweep_core.io.recording.chunks import ChunkError, chunk_records, chunk_span, read_chunk_at
from sweep_core.io.recording.format import (
    MAGIC,
    describe_stop,
    is_complete,
    open_for_reading,
)


@dataclass(frozen=True, slots=True)
class RecordedMessage:
    """One message of a recording; ``data`` is the raw payload (CDR when ``encoding`` is
    ``"cdr"``; decode with sweep_core.cdr).

    Where it is, for messages about it (:meth:`where`): ``index``, its place among the
    messages of its topic read so far (0 = the first); ``sequence``, the writer's sequence
    number (sweep's writers count 1, 2, ... per topic; 0 when the writer does not count);
    ``offset``, the file byte offset of the record that holds it (its chunk, or the message
    record itself outside chunks); ``inner``, its byte offset in the chunk's uncompressed data
    (-1 outside chunks).
    """

    topic: str
    msgtype: str
    log_time_ns: int
    publish_time_ns: int
    data: bytes
    sequence: int = 0
    index: int = -1
    offset: int = -1
    inner: int = -1
    encoding: str = "cdr"

    def where(self) -> str:
        """``topic /poses message 17 (sequence 18, t = 0.17 s) at byte 1234 (chunk), byte 56
        uncompressed``: one line naming the message."""
        seq = f"sequence {self.sequence}, " if self.sequence else ""
        at = (f"in the chunk at byte {self.offset}, byte {self.inner} of its uncompressed data"
              if self.inner >= 0 else f"at byte {self.offset}")
        return (f"topic {self.topic} message {self.index} ({seq}t = {self.log_time_ns / NS:g} "
                f"s) {at}")


#: nanoseconds per second
NS = 1_000_000_000


class RecordingReader:
    """Iterator over the messages of a recording (see :func:`read_recording`).

    After the iteration ends, ``truncated`` tells whether the file was cut short (``None``
    before), ``error`` says where reading stopped, ``problems`` lists the chunks that could
    not be read and were skipped (one line each: where, the time span and why), and
    ``metadata`` holds the metadata records seen (all of them for a complete file) and
    ``lost_from_ns`` the earliest log time (ns) from which a skipped chunk may have held
    messages (None: no chunk skipped), ``lost_spans`` the log-time spans (ns, both ends
    included) of the skipped chunks.
    """

    def __init__(self, path: str | os.PathLike[str], topics: Iterable[str] | None = None) -> None:
        if isinstance(topics, str):
            topics = [topics]
        self.topics = None if topics is None else set(topics)
        self.path, self._file = open_for_reading(path)
        self.truncated: bool | None = None
        self.error: str | None = None
        self.problems: list[str] = []
        self.metadata: dict[str, dict[str, str]] = {}
        self.lost_from_ns: int | None = None
        self.lost_spans: list[tuple[int, int]] = []
        self._counts: dict[str, int] = {}
        self._it = self._generate()

    def __iter__(self) -> RecordingReader:
        return self

    def __next__(self) -> RecordedMessage:
        return next(self._it)

    def close(self) -> None:
        self._it.close()  # type: ignore[attr-defined]  # a generator
        self._file.close()

    def __enter__(self) -> RecordingReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _message(self, m: Message, channel: tuple[str, str, str], offset: int, inner: int
                 ) -> RecordedMessage | None:
        """The RecordedMessage of ``m`` (topic, msgtype, encoding), counted; None if its topic
        is not read."""
        topic = channel[0]
        index = self._counts.get(topic, 0)
        self._counts[topic] = index + 1
        if self.topics is not None and topic not in self.topics:
            return None
        return RecordedMessage(topic, channel[1], m.log_time, m.publish_time, m.data,
                               m.sequence, index, offset, inner, channel[2])

    def _lost(self, log_ns: int, span: tuple[int, int]) -> None:
        self.lost_spans.append(span)
        if self.lost_from_ns is None or log_ns < self.lost_from_ns:
            self.lost_from_ns = log_ns

    def _chunk(self, chunk: Chunk, offset: int, schemas: dict[int, str],
               channels: dict[int, tuple[str, str, str]]) -> Iterator[RecordedMessage]:
        seen = None  # log time of the chunk's last message read
        try:
            for inner, r in chunk_records(chunk):
                if isinstance(r, Message):
                    seen = r.log_time
                    ch = channels.get(r.channel_id)
                    if ch is not None and (msg := self._message(r, ch, offset, inner)):
                        yield msg
                else:
                    _declare(r, schemas, channels)
        except ChunkError as err:
            self._lost(chunk.message_start_time if seen is None else seen,
                       (chunk.message_start_time, chunk.message_end_time))
            span = chunk_span(chunk)
            self.problems.append(f"the chunk at byte {offset}{f' ({span})' if span else ''} "
                                 f"{err}; its messages {'are' if seen is None else 'from there on are'} "
                                 "skipped")

    def _generate(self) -> Iterator[RecordedMessage]:
        try:
            if is_complete(self._file):
                try:
                    reader = SeekingReader(self._file)
                    summary = reader.get_summary()
                    if summary is not None:
                        for md in reader.iter_metadata():
                            self.metadata[md.name] = dict(md.metadata)
                except Exception:  # noqa: BLE001 - a damaged footer: read sequentially instead
                    summary = None
                if summary is not None and summary.chunk_indexes:
                    schemas = {k: v.name for k, v in summary.schemas.items()}
                    channels = {k: (c.topic, schemas.get(c.schema_id, ""), c.message_encoding)
                                for k, c in summary.channels.items()}
                    for ci in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
                        try:
                            chunk = read_chunk_at(self._file, ci.chunk_start_offset,
                                                  ci.chunk_length)
                        except ChunkError as err:
                            self._lost(ci.message_start_time,
                                       (ci.message_start_time, ci.message_end_time))
                            span = chunk_span(None, ci.message_start_time, ci.message_end_time)
                            self.problems.append(f"{err} ({span}); its messages are skipped")
                            continue
                        yield from self._chunk(chunk, ci.chunk_start_offset, schemas, channels)
                    self.truncated = False
                    return
                self._file.seek(0)
            yield from self._stream()
        finally:
            self._file.close()

    def _stream(self) -> Iterator[RecordedMessage]:
        schemas: dict[int, str] = {}
        channels: dict[int, tuple[str, str, str]] = {}
        records = StreamReader(self._file, emit_chunks=True, validate_crcs=False).records
        footer_seen = False
        start = self._file.tell() + len(MAGIC)
        while True:
            try:
                record = next(records)
            except StopIteration:
                break
            except Exception as err:  # noqa: BLE001 - any failure past here is the cut-off tail
                self.error = describe_stop(err, self._file)
                break
            offset, start = start, self._file.tell()
            if isinstance(record, Chunk):
                yield from self._chunk(record, offset, schemas, channels)
            elif isinstance(record, Message):
                ch = channels.get(record.channel_id)
                if ch is not None and (msg := self._message(record, ch, offset, -1)):
                    yield msg
            elif isinstance(record, (Schema, Channel)):
                _declare(record, schemas, channels)
            elif isinstance(record, Metadata):
                self.metadata[record.name] = dict(record.metadata)
            elif isinstance(record, Footer):
                footer_seen = True
        self.truncated = not (footer_seen and self.error is None)


def _declare(r: Schema | Channel | Message, schemas: dict[int, str],
             channels: dict[int, tuple[str, str, str]]) -> None:
    if isinstance(r, Schema):
        schemas[r.id] = r.name
    elif isinstance(r, Channel) and r.id not in channels:
        channels[r.id] = (r.topic, schemas.get(r.schema_id, ""), r.message_encoding)


def read_recording(
    path: str | os.PathLike[str], topics: Iterable[str] | None = None
) -> RecordingReader:
    """Iterates over the messages of ``path`` (optionally only ``topics``) in file order.

    Returns a :class:`RecordingReader`: iterate it for :class:`RecordedMessage` items; once
    exhausted, ``reader.truncated`` is True if the file was cut short (every complete message
    up to the last complete chunk was still yielded, and no exception is raised for the cut),
    and ``reader.problems`` lists the chunks that could not be read (skipped, the rest read).

    Raises:
        RecordingError: the file cannot be opened or is not MCAP.
    """
    return RecordingReader(path, topics)


def read_metadata(path: str | os.PathLike[str]) -> dict[str, dict[str, str]]:
    """Metadata records of ``path``: name -> {key: value}; works on truncated files too."""
    p, f = open_for_reading(path)
    with f:
        if is_complete(f):
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
