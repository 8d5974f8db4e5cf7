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

from sweep_core.errors import RecordingError
from sweep_core.io.recording.background import BackgroundRecorder
from sweep_core.io.recording.format import DEFAULT_QOS_PROFILES, qos_profiles
from sweep_core.io.recording.reader import (
    RecordedMessage,
    RecordingReader,
    read_metadata,
    read_recording,
)
from sweep_core.io.recording.scan import ChannelInfo, RecordingInfo, scan_recording
from sweep_core.io.recording.writer import Recorder

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
    "qos_profiles",
    "scan_recording",
]
