"""The records of one MCAP chunk with their byte offsets (:func:`chunk_records`), and one chunk
read at a known offset (:func:`read_chunk_at`), so that a reader can name where a bad message
or an unreadable chunk is and go on with the next one."""
from __future__ import annotations

import struct
from collections.abc import Iterator
from typing import IO

from mcap.data_stream import ReadDataStream
from mcap.records import Channel, Chunk, Message, Schema
from mcap.stream_reader import CRCValidationError, get_chunk_data_stream

#: MCAP opcodes read inside a chunk
_SCHEMA, _CHANNEL, _MESSAGE, _CHUNK = 0x03, 0x04, 0x05, 0x06
#: nanoseconds per second
_NS = 1_000_000_000


class ChunkError(Exception):
    """A chunk (or a record in it) cannot be read; ``str()`` says where and why."""


def chunk_span(chunk: Chunk | None, start_ns: int | None = None, end_ns: int | None = None) -> str:
    """``t = a .. b s``: the log times a chunk's messages span (from the chunk or its index)."""
    if chunk is not None:
        start_ns, end_ns = chunk.message_start_time, chunk.message_end_time
    if start_ns is None or end_ns is None:
        return ""
    return f"t = {start_ns / _NS:g} .. {end_ns / _NS:g} s"


def read_chunk_at(f: IO[bytes], offset: int, length: int) -> Chunk:
    """The chunk record at byte ``offset`` (``length`` bytes with its opcode and length).

    Raises:
        ChunkError: the bytes there are not a whole chunk record.
    """
    f.seek(offset)
    head = f.read(9)
    if len(head) < 9 or head[0] != _CHUNK:
        raise ChunkError(f"no chunk record at byte {offset}")
    body_length = struct.unpack_from("<Q", head, 1)[0]
    if 9 + body_length != length:
        raise ChunkError(f"the chunk record at byte {offset} has {9 + body_length} bytes, its "
                         f"index says {length}")
    try:
        return Chunk.read(ReadDataStream(f))
    except Exception as err:  # noqa: BLE001 - cut or damaged: named by the caller
        raise ChunkError(f"the chunk at byte {offset} is cut short ({type(err).__name__})") \
            from None


def chunk_records(chunk: Chunk) -> Iterator[tuple[int, Schema | Channel | Message]]:
    """(offset in the chunk's uncompressed data, record) of its schemas, channels and messages.

    The chunk's CRC (of its uncompressed data, when the writer stored one) is checked by mcap
    before any record is read: a damaged chunk yields nothing.

    Raises:
        ChunkError: the chunk's CRC does not match its data (the file is damaged), it cannot
            be decompressed, or a record in it is cut short (the records before it have been
            yielded).
    """
    try:
        stream, length = get_chunk_data_stream(chunk, validate_crc=True)
    except CRCValidationError:
        raise ChunkError("has a CRC that does not match its data (the file is damaged)") \
            from None
    except Exception as err:  # noqa: BLE001 - any decompression failure
        raise ChunkError(f"cannot be decompressed ({type(err).__name__}: "
                         f"{_first_line(err)})") from None
    while stream.count < length:
        start = stream.count
        try:
            opcode = stream.read1()
            record_length = stream.read8()
            if start + 9 + record_length > length:
                raise ChunkError(f"the record at byte {start} of its uncompressed data runs "
                                 f"past its end ({record_length} bytes)")
            record: Schema | Channel | Message | None = None
            if opcode == _MESSAGE:
                record = Message.read(stream, record_length)
            elif opcode == _CHANNEL:
                record = Channel.read(stream)
            elif opcode == _SCHEMA:
                record = Schema.read(stream)
            else:
                stream.read(record_length)
        except ChunkError:
            raise
        except Exception as err:  # noqa: BLE001 - a damaged record inside the chunk
            raise ChunkError(f"the record at byte {start} of its uncompressed data cannot be "
                             f"read ({type(err).__name__})") from None
        end = start + 9 + record_length
        if stream.count > end:
            raise ChunkError(f"the record at byte {start} of its uncompressed data does not "
                             "match its length")
        if stream.count < end:  # fields a later MCAP version appends
            stream.read(end - stream.count)
        if record is not None:
            yield start, record


def _first_line(err: BaseException) -> str:
    text = str(err).splitlines()[0] if str(err) else ""
    return text if len(text) <= 120 else text[:117] + "..."
