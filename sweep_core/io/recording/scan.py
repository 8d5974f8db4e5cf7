"""What a recording holds without reading its messages: counts, time range, channels,
metadata, whether it was cut short (:func:`scan_recording`)."""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import IO, Any

from mcap.reader import SeekingReader
from mcap.records import Channel, Chunk, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

from sweep_core.io.recording.chunks import ChunkError, chunk_records
from sweep_core.io.recording.format import describe_stop, is_complete, open_for_reading


def _readable(chunk: Chunk) -> list[Any]:
    """The records of a chunk up to the first that cannot be read (the reader names it)."""
    out = []
    try:
        for _, record in chunk_records(chunk):
            out.append(record)
    except ChunkError:
        pass
    return out


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


def scan_recording(path: str | os.PathLike[str]) -> RecordingInfo:
    """Counts, time range, channels, metadata and the truncated flag of ``path``.

    Uses the summary of a complete file (fast); scans a truncated one up to its last complete
    record.
    """
    p, f = open_for_reading(path)
    with f:
        if is_complete(f):
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
                    pending = _readable(record)[::-1]
                    chunks += 1
                    continue
            except StopIteration:
                break
            except Exception as err:  # noqa: BLE001 - cut-off tail
                error = describe_stop(err, f)
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
