"""Rewriting a recording that was cut short into a complete MCAP file (:func:`recover`,
``sweep recover``), as ``mcap recover`` does.

A writer killed with SIGKILL (or a disk that filled up) leaves a file without its summary
section and footer; sweep's own readers read it up to its last complete record, but rosbags
("File end magic is invalid"), Foxglove, rosbag2 and mcap's seeking reader refuse it.
:func:`recover` reads it as sweep's reader does (records in file order, up to the first one
that is incomplete or damaged, such as a chunk whose CRC does not match its data) and writes
everything it read (header profile, schemas, channels, messages with their sequence numbers
and times, metadata, attachments) into a new file with chunk and message indexes, statistics,
summary and footer, plus a metadata record ``sweep_recover`` saying where it came from and
what was lost. The source is never modified.
"""
from __future__ import annotations

import os
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

from mcap.records import (
    Attachment,
    Channel,
    Chunk,
    DataEnd,
    Header,
    Message,
    Metadata,
    Schema,
)
from mcap.stream_reader import CRCValidationError, StreamReader, breakup_chunk
from mcap.writer import CompressionType, Writer

from sweep_core.errors import RecordingError
from sweep_core.io.metadata import RECOVER_RECORD
from sweep_core.io.outputs import replacing
from sweep_core.io.recording.format import describe_stop, library_string, open_for_reading

#: nanoseconds per second
_NS = 1_000_000_000
#: MCAP opcodes of the records a cut can fall in, by name (for the report)
_OPCODES = {0x01: "header", 0x03: "schema", 0x04: "channel", 0x05: "message", 0x06: "chunk",
            0x07: "message index", 0x08: "chunk index", 0x09: "attachment",
            0x0A: "attachment index", 0x0B: "statistics", 0x0C: "metadata",
            0x0D: "metadata index", 0x0E: "summary offset", 0x0F: "data end", 0x02: "footer"}


@dataclass
class Recovery:
    """What :func:`recover` kept and lost.

    ``messages``: messages kept per topic; ``start_ns``/``end_ns``: their log-time range
    (None if none); ``complete``: the source's data section was complete (it ends with a
    DataEnd record: nothing was lost, only the summary or footer may have been missing);
    ``kept_bytes``: the source's bytes up to the end of its last complete record;
    ``source_bytes``: its size; ``tail``: what the bytes after that were (empty if none);
    ``error``: why reading stopped (None at a clean end).
    """

    source: str
    out: str
    complete: bool
    messages: dict[str, int]
    start_ns: int | None
    end_ns: int | None
    schemas: int
    channels: int
    metadata: list[str]
    attachments: int
    kept_bytes: int
    source_bytes: int
    tail: str = ""
    error: str | None = None
    skipped: dict[str, int] = field(default_factory=dict)

    @property
    def message_count(self) -> int:
        return sum(self.messages.values())

    @property
    def lost_bytes(self) -> int:
        return self.source_bytes - self.kept_bytes


def default_output(path: str | os.PathLike[str]) -> Path:
    """``run.mcap`` -> ``run.recovered.mcap``."""
    p = Path(path)
    return p.with_name(p.stem + ".recovered.mcap") if p.suffix == ".mcap" \
        else p.with_name(p.name + ".recovered.mcap")


def hint(path: str | os.PathLike[str]) -> str:
    """The one-line hint that ``analyze``, ``replay`` and ``compare`` print for a cut file."""
    return (f"hint: {os.fspath(path)} was cut short (no summary or footer); "
            f"`sweep recover {os.fspath(path)}` writes a complete copy that rosbags, Foxglove "
            "and rosbag2 can open")


def _describe_tail(f: IO[bytes], start: int, size: int) -> str:
    """What the incomplete bytes from ``start`` to ``size`` were: the record they begin."""
    if start >= size:
        return ""
    f.seek(start)
    head = f.read(9 + 16)
    n = size - start
    if len(head) < 9:
        return f"{n} bytes of an incomplete record header"
    opcode, length = head[0], struct.unpack_from("<Q", head, 1)[0]
    what = _OPCODES.get(opcode)
    if what is None:
        return f"{n} bytes that are not an MCAP record (opcode 0x{opcode:02x})"
    text = f"an incomplete {what} record ({n} of its {9 + length} bytes)"
    if opcode == 0x06 and len(head) >= 9 + 16:
        t0, t1 = struct.unpack_from("<QQ", head, 9)
        text += f" with messages from t = {t0 / _NS:g} to {t1 / _NS:g} s"
    return text


def _same_file(a: str, b: str) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.abspath(a) == os.path.abspath(b)


def recover(path: str | os.PathLike[str], out: str | os.PathLike[str] | None = None,
            *, chunk_size: int = 1 << 20) -> Recovery:
    """Writes what ``path`` holds up to its last complete record into ``out`` (default
    ``PATH.recovered.mcap``), a complete MCAP file; returns what was kept and lost.

    The output is written to a temporary file beside ``out`` and renamed over it at the end, so
    an interrupted recovery leaves no half-written ``out``.

    Raises:
        RecordingError: ``path`` cannot be opened or is not MCAP, or ``out`` is ``path``.
        OutputError: ``out`` is not a regular file (a folder, a device, a FIFO), another
            recovery is writing it, or it cannot be written (full disk).
    """
    src, f = open_for_reading(path)
    dst = os.fspath(default_output(src) if out is None else out)
    with f:
        if _same_file(src, dst):
            raise RecordingError(f"{dst}: is the recording being recovered; recover never "
                                 "overwrites its input (fix: name another OUT file)")
        # written beside OUT, then renamed over it: an interrupted recovery leaves no half OUT;
        # OUT must be absent or a regular file, and one recovery at a time writes it
        with replacing(dst, [src], other="another OUT") as tmp, open(tmp, "wb") as o:
            return _copy(src, f, o, dst, chunk_size)


def _copy(src: str, f: IO[bytes], o: IO[bytes], dst: str, chunk_size: int) -> Recovery:
    size = os.fstat(f.fileno()).st_size
    writer = Writer(o, chunk_size=chunk_size, compression=CompressionType.ZSTD)
    started = False
    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    topic_of: dict[int, str] = {}
    counts: dict[str, int] = {}
    skipped: dict[str, int] = {}
    metadata: list[str] = []
    attachments = 0
    start_ns: int | None = None
    end_ns: int | None = None
    kept = min(8, size)  # the magic, checked by open_for_reading
    complete = False
    error = None

    def start(profile: str = "", library: str = "") -> None:
        nonlocal started
        if not started:
            ours = library_string() + " recover"
            writer.start(profile=profile, library=f"{library}; {ours}" if library else ours)
            started = True

    def message(m: Message) -> None:
        nonlocal start_ns, end_ns
        cid = channel_ids.get(m.channel_id)
        if cid is None:  # a message of a channel never declared: unreadable, as in read_recording
            skipped["messages of undeclared channels"] = \
                skipped.get("messages of undeclared channels", 0) + 1
            return
        writer.add_message(cid, m.log_time, m.data, m.publish_time, m.sequence)
        topic = topic_of[m.channel_id]
        counts[topic] = counts.get(topic, 0) + 1
        start_ns = m.log_time if start_ns is None else min(start_ns, m.log_time)
        end_ns = m.log_time if end_ns is None else max(end_ns, m.log_time)

    def declare(r: Schema | Channel) -> None:
        if isinstance(r, Schema):
            if r.id not in schema_ids and r.id != 0:
                schema_ids[r.id] = writer.register_schema(r.name, r.encoding, r.data)
        elif r.id not in channel_ids:
            channel_ids[r.id] = writer.register_channel(
                r.topic, r.message_encoding, schema_ids.get(r.schema_id, 0), dict(r.metadata))
            topic_of[r.id] = r.topic
            counts.setdefault(r.topic, 0)

    records = StreamReader(f, emit_chunks=True, validate_crcs=False).records
    damaged = ""
    while True:
        try:
            record = next(records)
            inner = (breakup_chunk(record, validate_crc=True) if isinstance(record, Chunk)
                     else [record])
        except StopIteration:
            break
        except CRCValidationError:  # a damaged chunk: what follows it is not copied either
            damaged = (f"the chunk at byte {kept} and everything after it: its CRC does not "
                       "match its data (the file is damaged)")
            error = f"chunk CRC mismatch at byte {kept}"
            break
        except Exception as err:  # noqa: BLE001 - the first incomplete or damaged record
            error = describe_stop(err, f)
            break
        if isinstance(record, DataEnd):  # the summary section repeats what was read
            kept = f.tell()
            complete = True
            break
        if isinstance(record, Header):
            start(record.profile, record.library)
        else:
            start()
        for r in inner:
            if isinstance(r, (Schema, Channel)):
                declare(r)
            elif isinstance(r, Message):
                message(r)
        if isinstance(record, Metadata):
            writer.add_metadata(record.name, dict(record.metadata))
            metadata.append(record.name)
        elif isinstance(record, Attachment):
            writer.add_attachment(record.create_time, record.log_time, record.name,
                                  record.media_type, record.data)
            attachments += 1
        kept = f.tell()
    if complete:
        kept = size
    start()
    tail = "" if complete else damaged or _describe_tail(f, kept, size)
    writer.add_metadata(RECOVER_RECORD, {
        "source": src, "source_bytes": str(size), "kept_bytes": str(kept),
        "complete": str(complete).lower(), "lost": tail, "stopped": error or ""})
    writer.finish()
    return Recovery(src, dst, complete, counts, start_ns, end_ns, len(schema_ids),
                    len(channel_ids), metadata, attachments, kept, size, tail, error, skipped)


def format_recovery(r: Recovery, t_end: float | None = None) -> str:
    """The lines ``sweep recover`` prints: what was kept (messages per topic) and lost."""
    per_topic = ", ".join(f"{t} {n}" for t, n in sorted(r.messages.items())) or "none"
    lines = [f"recovered  {r.source} -> {r.out}"]
    span = ""
    if r.start_ns is not None and r.end_ns is not None:
        span = f"; t = {r.start_ns / _NS:g} .. {r.end_ns / _NS:g} s"
    lines.append(f"kept       {r.message_count} messages ({per_topic}){span}")
    lines.append(f"           {r.schemas} schemas, {r.channels} channels, metadata "
                 f"{', '.join(r.metadata) or 'none'}, {r.attachments} attachments; "
                 f"{r.kept_bytes} of {r.source_bytes} bytes read")
    if r.complete:
        lines.append("lost       nothing (the file's data section was complete)")
        return "\n".join(lines)
    lost = [r.tail or "no partial record (the file ends at a record boundary)"]
    if not (r.error or "").startswith("chunk CRC mismatch"):
        lost.append("whatever the writer had not flushed when it stopped (sweep run and "
                    "sweep_node flush at least once a second)")
    if t_end is not None and r.end_ns is not None:
        lost.append(f"the run was to reach t = {t_end:g} s")
    for what, n in r.skipped.items():
        lost.append(f"{n} {what}")
    if r.message_count == 0:
        lost.insert(0, f"no messages: the file ends at byte {r.source_bytes} before its first "
                       "chunk; it was cut short")
    lines.append("lost       " + "; ".join(lost))
    return "\n".join(lines)
