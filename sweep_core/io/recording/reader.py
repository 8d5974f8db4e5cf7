"""Reading a recording message by message, complete or cut short (:func:`read_recording`,
:func:`read_metadata`)."""
from __future__ import annotations

import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

from mcap.reader import SeekingReader
from mcap.records import Channel, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

from sweep_core.errors import RecordingError
from sweep_core.io.recording.format import describe_stop, is_complete, open_for_reading


@dataclass(frozen=True, slots=True)
class RecordedMessage:
    """One message of a recording; ``data`` is the raw CDR (decode with sweep_core.cdr)."""

    topic: str
    msgtype: str
    log_time_ns: int
    publish_time_ns: int
    data: bytes


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
        self.path, self._file = open_for_reading(path)
        self.truncated: bool | None = None
        self.error: str | None = None
        self.metadata: dict[str, dict[str, str]] = {}
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

    def _generate(self) -> Iterator[RecordedMessage]:
        try:
            if is_complete(self._file):
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
                self.error = describe_stop(err, self._file)
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
