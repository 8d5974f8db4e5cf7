"""Copies of a recording written again with mcap's own writer (for tests that damage or
tamper with one): every schema, channel, metadata record and message, in file order."""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer


def rewrite(src: Path, dst: Path, edit: Callable[[str, bytes], bytes | None] | None = None,
            chunk_size: int | None = None, library: str = "test copy") -> int:
    """``src`` written again to ``dst``, uncompressed (in chunks of ``chunk_size`` bytes:
    mcap's default when None), each message's data replaced by ``edit(topic, data)`` when
    that is not None; the count of messages replaced."""
    edited = 0
    with open(src, "rb") as f, open(dst, "wb") as o:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        sized = {} if chunk_size is None else {"chunk_size": chunk_size}
        w = Writer(o, compression=CompressionType.NONE, **sized)
        w.start(profile="ros2", library=library)
        sids = {k: w.register_schema(s.name, s.encoding, s.data)
                for k, s in summary.schemas.items()}
        cids = {k: w.register_channel(c.topic, c.message_encoding, sids[c.schema_id],
                                      dict(c.metadata)) for k, c in summary.channels.items()}
        for md in reader.iter_metadata():
            w.add_metadata(md.name, dict(md.metadata))
        for _, ch, m in reader.iter_messages(log_time_order=False):
            new = None if edit is None else edit(ch.topic, m.data)
            edited += new is not None
            w.add_message(cids[ch.id], m.log_time, m.data if new is None else new,
                          m.publish_time, m.sequence)
        w.finish()
    return edited
