"""sweep_core.recording: MCAP written by Recorder, read by mcap_ros2, rosbags and our reader;
survival of SIGKILL and of a cut-off tail."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from mcap.data_stream import ReadDataStream
from mcap.reader import SeekingReader, make_reader
from mcap.records import Chunk, Message
from mcap.stream_reader import breakup_chunk

from sweep_core.errors import OutputError, RecordingError, SweepError
from sweep_core.io import cdr
from sweep_core.io.recording import (
    DEFAULT_QOS_PROFILES,
    BackgroundRecorder,
    Recorder,
    read_metadata,
    read_recording,
    scan_recording,
)

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "OFF")
os.environ.setdefault("ROS_DOMAIN_ID", "57")

REPO = Path(__file__).resolve().parents[1]
N_STEPS = 60
N_AGENTS = 13
CLOUD_FIELDS = ["vx", "vy", "radius"]
META = {"scene": "corridor", "seed": "3", "dt": "0.01"}


def _step_data(i: int):
    rng = np.random.default_rng(1000 + i)
    pos = rng.uniform(-10, 10, size=(N_AGENTS, 2))
    yaw = rng.uniform(-3, 3, size=N_AGENTS)
    fields = {k: rng.normal(size=N_AGENTS).astype(np.float32) for k in CLOUD_FIELDS}
    return pos, yaw, fields


def _stamp(i: int) -> int:
    return 1_000_000_000 + i * 10_000_000  # 10 ms steps from t = 1 s


def _write_run(path: Path, n_steps: int = N_STEPS, **kwargs) -> None:
    with Recorder(path, metadata=META, **kwargs) as rec:
        rec.add_channel("/clock", cdr.CLOCK)
        poses_id = rec.add_channel("/crowd/poses", cdr.POSE_ARRAY)
        rec.add_channel("/crowd/agents", cdr.POINT_CLOUD2)
        rec.add_metadata("scene_spec", {"yaml": "agents: 13\n"})
        for i in range(n_steps):
            t = _stamp(i)
            pos, yaw, fields = _step_data(i)
            rec.write("/clock", t, cdr.encode_clock(t))
            rec.write(poses_id, t, cdr.encode_pose_array(t, "map", pos, yaw), publish_time_ns=t + 1)
            rec.write("/crowd/agents", t, cdr.encode_point_cloud2(t, "map", fields))


@pytest.fixture()
def run_file(tmp_path) -> Path:
    path = tmp_path / "run.mcap"
    _write_run(path)
    return path


# ---------------------------------------------------------------------------------------------
# Readers of other projects
# ---------------------------------------------------------------------------------------------


def test_mcap_ros2_decodes_recording(run_file):
    from mcap_ros2.decoder import DecoderFactory

    seen = {"/clock": 0, "/crowd/poses": 0, "/crowd/agents": 0}
    with open(run_file, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        assert header.profile == "ros2" and header.library.startswith("sweep_ros")
        for schema, channel, message, msg in reader.iter_decoded_messages(log_time_order=False):
            assert schema.encoding == "ros2msg" and channel.message_encoding == "cdr"
            assert channel.metadata["offered_qos_profiles"] == DEFAULT_QOS_PROFILES
            i = seen[channel.topic]
            seen[channel.topic] += 1
            t = _stamp(i)
            pos, yaw, fields = _step_data(i)
            assert message.log_time == t
            if channel.topic == "/clock":
                assert schema.name == cdr.CLOCK
                assert msg.clock.sec * 10**9 + msg.clock.nanosec == t
                continue
            assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == t
            assert msg.header.frame_id == "map"
            if channel.topic == "/crowd/poses":
                assert schema.name == cdr.POSE_ARRAY and message.publish_time == t + 1
                got = np.array([[p.position.x, p.position.y] for p in msg.poses])
                np.testing.assert_array_equal(got, pos)
                got_yaw = np.array([2 * np.arctan2(p.orientation.z, p.orientation.w)
                                    for p in msg.poses])
                np.testing.assert_allclose(got_yaw, yaw, atol=1e-12)
            else:
                assert schema.name == cdr.POINT_CLOUD2
                assert [fl.name for fl in msg.fields] == CLOUD_FIELDS
                assert (msg.height, msg.width, msg.point_step) == (1, N_AGENTS, 12)
                cols = np.frombuffer(bytes(msg.data), "<f4").reshape(N_AGENTS, 3)
                for j, k in enumerate(CLOUD_FIELDS):
                    np.testing.assert_array_equal(cols[:, j], fields[k])
        assert seen == {k: N_STEPS for k in seen}
        summary = reader.get_summary()
        stats = summary.statistics
        assert stats.message_count == 3 * N_STEPS
        assert sorted(stats.channel_message_counts.values()) == [N_STEPS] * 3
        assert stats.channel_count == 3 and stats.schema_count == 3
        assert stats.message_start_time == _stamp(0)
        assert stats.message_end_time == _stamp(N_STEPS - 1)
        assert stats.chunk_count >= 1 and len(summary.chunk_indexes) == stats.chunk_count
        assert all(ci.message_index_offsets for ci in summary.chunk_indexes)
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        assert metadata == {"sweep_ros": META, "scene_spec": {"yaml": "agents: 13\n"}}


def test_rosbags_reads_bare_mcap_file(run_file):
    """rosbags (>= 0.10) opens a single .mcap path directly, no metadata.yaml needed."""
    highlevel = pytest.importorskip("rosbags.highlevel")
    from rosbags.interfaces import QosReliability

    with highlevel.AnyReader([run_file]) as reader:
        topics = {c.topic: c for c in reader.connections}
        assert {t: c.msgtype for t, c in topics.items()} == {
            "/clock": cdr.CLOCK, "/crowd/poses": cdr.POSE_ARRAY, "/crowd/agents": cdr.POINT_CLOUD2}
        assert reader.message_count == 3 * N_STEPS
        assert all(c.msgcount == N_STEPS for c in topics.values())
        qos = topics["/crowd/poses"].ext.offered_qos_profiles
        assert len(qos) == 1 and qos[0].reliability == QosReliability.RELIABLE
        counts = dict.fromkeys(topics, 0)
        for conn, timestamp, raw in reader.messages():
            i = counts[conn.topic]
            counts[conn.topic] += 1
            assert timestamp == _stamp(i)
            msg = reader.deserialize(raw, conn.msgtype)
            pos, _, fields = _step_data(i)
            if conn.topic == "/crowd/poses":
                got = np.array([[p.position.x, p.position.y] for p in msg.poses])
                np.testing.assert_array_equal(got, pos)
            elif conn.topic == "/crowd/agents":
                cols = np.frombuffer(msg.data.tobytes(), "<f4").reshape(N_AGENTS, 3)
                np.testing.assert_array_equal(cols[:, 2], fields["radius"])
            else:
                assert msg.clock.sec * 10**9 + msg.clock.nanosec == _stamp(i)
        assert counts == dict.fromkeys(topics, N_STEPS)


# ---------------------------------------------------------------------------------------------
# Our reader
# ---------------------------------------------------------------------------------------------


def test_own_reader_round_trip(run_file):
    reader = read_recording(run_file)
    assert reader.truncated is None
    msgs = list(reader)
    assert reader.truncated is False and reader.error is None
    assert reader.metadata["sweep_ros"] == META
    assert len(msgs) == 3 * N_STEPS
    poses = [m for m in msgs if m.topic == "/crowd/poses"]
    assert len(poses) == N_STEPS
    for i, m in enumerate(poses):
        assert m.msgtype == cdr.POSE_ARRAY
        assert (m.log_time_ns, m.publish_time_ns) == (_stamp(i), _stamp(i) + 1)
        stamp, frame, pos = cdr.decode_pose_array(m.data)
        assert (stamp, frame) == (_stamp(i), "map")
        np.testing.assert_array_equal(pos, _step_data(i)[0])
    only = list(read_recording(run_file, topics=["/crowd/agents"]))
    assert [m.topic for m in only] == ["/crowd/agents"] * N_STEPS
    cloud = cdr.decode_point_cloud2(only[5].data)
    np.testing.assert_array_equal(cloud.fields["vy"], _step_data(5)[2]["vy"])


def test_scan_and_metadata(run_file):
    info = scan_recording(run_file)
    assert info.truncated is False and info.error is None
    assert info.message_count == 3 * N_STEPS
    assert (info.start_ns, info.end_ns) == (_stamp(0), _stamp(N_STEPS - 1))
    assert info.duration_ns == _stamp(N_STEPS - 1) - _stamp(0)
    assert {t: c.message_count for t, c in info.channels.items()} == {
        "/clock": N_STEPS, "/crowd/poses": N_STEPS, "/crowd/agents": N_STEPS}
    assert info.channels["/crowd/agents"].msgtype == cdr.POINT_CLOUD2
    assert info.profile == "ros2" and info.library.startswith("sweep_ros/")
    assert read_metadata(run_file) == info.metadata == {
        "sweep_ros": META, "scene_spec": {"yaml": "agents: 13\n"}}


@pytest.mark.parametrize("compression", ["lz4", "none"])
def test_other_compressions(tmp_path, compression):
    path = tmp_path / f"{compression}.mcap"
    _write_run(path, n_steps=10, compression=compression)
    msgs = list(read_recording(path))
    assert len(msgs) == 30
    with open(path, "rb") as f:
        chunk_comp = {ci.compression for ci in SeekingReader(f).get_summary().chunk_indexes}
    assert chunk_comp == {"" if compression == "none" else compression}


def test_custom_definition_and_empty_recording(tmp_path):
    from mcap_ros2.decoder import DecoderFactory

    path = tmp_path / "custom.mcap"
    with Recorder(path) as rec:
        rec.add_channel("/note", "std_msgs/msg/String", "string data\n")
        assert rec.add_channel("/note", "std_msgs/msg/String", "string data\n") == 1
        text = b"hello" + b"\x00"
        rec.write("/note", 5, b"\x00\x01\x00\x00" + len(text).to_bytes(4, "little") + text)
    with open(path, "rb") as f:
        out = list(make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages())
    assert [o.decoded_message.data for o in out] == ["hello"]
    empty = tmp_path / "empty.mcap"
    Recorder(empty).close()
    info = scan_recording(empty)
    assert (info.truncated, info.message_count, info.start_ns) == (False, 0, None)
    assert info.metadata == {}
    reader = read_recording(empty)
    assert list(reader) == [] and reader.truncated is False


# ---------------------------------------------------------------------------------------------
# Errors
# ---------------------------------------------------------------------------------------------


def test_background_recorder_writes_in_order_and_keeps_errors(tmp_path):
    path = tmp_path / "bg.mcap"
    with BackgroundRecorder(path, metadata=META, max_backlog=4, flush_interval_s=None) as rec:
        rec.add_channel("/clock", cdr.CLOCK)
        for i in range(N_STEPS):
            rec.write("/clock", _stamp(i), cdr.encode_clock(_stamp(i)))
            if i == 9:
                rec.flush()  # the first ten are on disk, readable from the unfinished file
                assert [m.log_time_ns for m in read_recording(path)] == \
                    [_stamp(k) for k in range(10)]
        rec.metadata("late", {"k": "v"})
    assert rec.error is None and rec.written == N_STEPS and rec.backlog == 0
    got = [cdr.decode_clock(m.data) for m in read_recording(path)]
    assert got == [_stamp(i) for i in range(N_STEPS)]
    assert read_metadata(path) == {"sweep_ros": META, "late": {"k": "v"}}

    # an error of the Recorder stops recording; what came before stays readable
    rec = BackgroundRecorder(tmp_path / "bad.mcap", flush_interval_s=None)
    rec.add_channel("/clock", cdr.CLOCK)
    rec.write("/clock", 5, cdr.encode_clock(5))
    rec.write("/nope", 6, b"")
    rec.close()
    rec.write("/clock", 7, cdr.encode_clock(7))  # dropped, no exception
    rec.close()  # idempotent
    assert "'/nope' has no channel" in rec.error and rec.written == 1
    assert [m.log_time_ns for m in read_recording(tmp_path / "bad.mcap")] == [5]


def test_background_recorder_batches_keep_order_and_errors(tmp_path):
    """``write_many``: each batch one queue entry, its messages written in order among
    single writes; a bad message stops recording there (those before it stay), later batches
    are dropped."""
    path = tmp_path / "many.mcap"
    with BackgroundRecorder(path, max_backlog=2, flush_interval_s=None) as rec:
        rec.add_channel("/clock", cdr.CLOCK)
        rec.add_channel("/other", cdr.CLOCK)
        expected = []
        for i in range(0, N_STEPS, 4):
            batch = [("/clock" if k % 2 else "/other", _stamp(i + k),
                      cdr.encode_clock(_stamp(i + k))) for k in range(3)]
            rec.write_many(batch)
            rec.write("/clock", _stamp(i + 3), cdr.encode_clock(_stamp(i + 3)))
            expected += [(t, s) for t, s, _ in batch] + [("/clock", _stamp(i + 3))]
        rec.write_many([])  # nothing queued
    assert rec.error is None and rec.written == len(expected) and rec.backlog == 0
    got = [(m.topic, cdr.decode_clock(m.data)) for m in read_recording(path)]
    assert got == expected

    rec = BackgroundRecorder(tmp_path / "bad_many.mcap", flush_interval_s=None)
    rec.add_channel("/clock", cdr.CLOCK)
    rec.write_many([("/clock", 5, cdr.encode_clock(5)), ("/nope", 6, b""),
                    ("/clock", 7, cdr.encode_clock(7))])
    rec.flush()
    rec.write_many([("/clock", 8, cdr.encode_clock(8))])  # dropped, no exception
    rec.close()
    assert "'/nope' has no channel" in rec.error and rec.written == 1
    assert [m.log_time_ns for m in read_recording(tmp_path / "bad_many.mcap")] == [5]


def test_errors(tmp_path):
    assert issubclass(RecordingError, SweepError)
    rec = Recorder(tmp_path / "e.mcap", flush_interval_s=None)
    with pytest.raises(RecordingError,
                       match=r"no built-in definition for 'std_msgs/msg/String'.*definition="):
        rec.add_channel("/x", "std_msgs/msg/String")
    with pytest.raises(RecordingError, match="'package/msg/Type'"):
        rec.add_channel("/x", "std_msgs/String")
    with pytest.raises(RecordingError, match="start it with '/'"):
        rec.add_channel("x", cdr.CLOCK)
    rec.add_channel("/clock", cdr.CLOCK)
    with pytest.raises(RecordingError, match="already recorded as rosgraph_msgs/msg/Clock"):
        rec.add_channel("/clock", cdr.POSE_ARRAY)
    with pytest.raises(RecordingError, match=r"'/nope' has no channel.*add_channel\(\)"):
        rec.write("/nope", 0, b"")
    with pytest.raises(RecordingError, match="log_time_ns"):
        rec.write("/clock", -1, cdr.encode_clock(0))
    with pytest.raises(RecordingError, match="data: must be bytes"):
        rec.write("/clock", 0, "text")
    with pytest.raises(RecordingError, match=r"metadata 'm': keys and values must be str"):
        rec.add_metadata("m", {"a": 1})
    rec.close()
    rec.close()  # idempotent
    assert rec.closed
    with pytest.raises(RecordingError, match="closed Recorder"):
        rec.write("/clock", 0, cdr.encode_clock(0))
    with pytest.raises(RecordingError, match="compression"):
        Recorder(tmp_path / "c.mcap", compression="gzip")
    with pytest.raises(RecordingError, match="flush_interval_s"):
        Recorder(tmp_path / "c.mcap", flush_interval_s=0)
    with pytest.raises(RecordingError, match="chunk_size"):
        Recorder(tmp_path / "c.mcap", chunk_size=0)
    with pytest.raises(RecordingError, match="metadata"):
        Recorder(tmp_path / "c.mcap", metadata={"a": 1.0})
    with pytest.raises(OutputError, match="dir.mcap: cannot be created for writing"):
        Recorder(tmp_path / "no" / "dir.mcap")
    if os.path.exists("/dev/full"):  # a device is never written to, nor replaced
        with pytest.raises(OutputError, match="/dev/full: exists and is a character device"):
            Recorder("/dev/full", metadata=META)
    damaged = tmp_path / "damaged.mcap"
    _write_run(damaged, n_steps=5)
    with open(damaged, "rb") as f:
        ci = SeekingReader(f).get_summary().chunk_indexes[0]
    raw = bytearray(damaged.read_bytes())
    start = ci.chunk_start_offset + ci.chunk_length - ci.compressed_size
    raw[start : start + 16] = bytes(16)  # wipe the zstd frame header
    damaged.write_bytes(bytes(raw))
    # the damaged chunk is skipped and named; the rest of the file is read
    reader = read_recording(damaged)
    assert len(list(reader)) < 3 * 5
    [problem] = reader.problems
    assert f"the chunk at byte {ci.chunk_start_offset}" in problem
    assert "cannot be decompressed" in problem and "skipped" in problem
    bogus = tmp_path / "bogus.mcap"
    bogus.write_bytes(b"not an mcap file at all")
    with pytest.raises(RecordingError, match="not an MCAP file"):
        read_recording(bogus)
    with pytest.raises(RecordingError, match="cannot open"):
        scan_recording(tmp_path / "missing.mcap")


# ---------------------------------------------------------------------------------------------
# Never lose a recording
# ---------------------------------------------------------------------------------------------


def _copy_open_file(path: Path, tmp_path: Path) -> Path:
    """A snapshot of a file another writer still holds open."""
    snap = tmp_path / f"snap_{time.monotonic_ns()}.mcap"
    snap.write_bytes(path.read_bytes())
    return snap


def test_timer_flushes_a_paused_run(tmp_path):
    """The background flusher closes the chunk even when no further write comes."""
    path = tmp_path / "paused.mcap"
    rec = Recorder(path, metadata=META, flush_interval_s=0.05)
    try:
        rec.add_channel("/clock", cdr.CLOCK)
        for i in range(20):
            rec.write("/clock", _stamp(i), cdr.encode_clock(_stamp(i)))
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            time.sleep(0.02)
            reader = read_recording(_copy_open_file(path, tmp_path))
            msgs = list(reader)
            if msgs:
                break
        assert len(msgs) == 20 and reader.truncated is True
        assert reader.metadata == {"sweep_ros": META}
    finally:
        rec.close()
    assert len(list(read_recording(path))) == 20


def test_full_chunks_reach_disk_without_timer(tmp_path):
    path = tmp_path / "chunks.mcap"
    rec = Recorder(path, chunk_size=4096, flush_interval_s=None)
    try:
        rec.add_channel("/crowd/poses", cdr.POSE_ARRAY)
        payload = np.random.default_rng(0).integers(0, 256, 1500, dtype=np.uint8).tobytes()
        for i in range(10):
            rec.write("/crowd/poses", i, payload)
        snap = _copy_open_file(path, tmp_path)
        info = scan_recording(snap)
        # the full chunks are on disk while the recorder is open; the last one is not full yet
        assert info.truncated is True and info.chunk_count >= 2 and 6 <= info.message_count < 10
        assert [m.log_time_ns for m in read_recording(snap)] == list(range(info.message_count))
    finally:
        rec.close()
    info = scan_recording(path)
    assert info.truncated is False and info.message_count == 10
    with open(path, "rb") as f:
        sizes = [ci.uncompressed_size for ci in SeekingReader(f).get_summary().chunk_indexes]
    assert len(sizes) == info.chunk_count
    assert all(4096 <= s < 4096 + 1531 for s in sizes[:-1]) and sizes[-1] < 4096


CHILD = textwrap.dedent(
    """
    import sys, time
    import numpy as np
    from sweep_core.io import cdr
    from sweep_core.io.recording import Recorder

    # chunks far bigger than the run: only the time-based flush puts data on disk
    rec = Recorder(sys.argv[1], metadata={"scene": "killed"}, flush_interval_s=0.2,
                   chunk_size=1 << 30)
    rec.add_channel("/crowd/poses", cdr.POSE_ARRAY)
    rec.add_metadata("extra", {"k": "v"})
    t0 = time.monotonic()
    i = 0
    announced = False
    while time.monotonic() - t0 < 1.5:
        pos = np.full((50, 2), float(i))
        rec.write("/crowd/poses", i + 1, cdr.encode_pose_array(i + 1, "map", pos))
        i += 1
        if not announced and time.monotonic() - t0 >= 1.0:
            print("written", i, flush=True)
            announced = True
        time.sleep(0.001)
    time.sleep(60)  # never reaches close(): the parent kills us first
    """
)


@pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="needs SIGKILL")
def test_sigkill_leaves_readable_recording(tmp_path):
    path = tmp_path / "killed.mcap"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(REPO)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    proc = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(path)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=tmp_path,
    )
    try:
        line = proc.stdout.readline()
        assert line.startswith("written"), proc.stderr.read()
        written = int(line.split()[1])
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == -signal.SIGKILL
    reader = read_recording(path)
    msgs = list(reader)
    assert reader.truncated is True
    assert reader.metadata == {"sweep_ros": {"scene": "killed"}, "extra": {"k": "v"}}
    # everything up to the last flush (<= 0.2 s before the kill) is there, in order, intact
    assert len(msgs) >= max(50, written // 2), (len(msgs), written)
    print(f"SIGKILL: {written} written at 1 s, {len(msgs)} read back")
    for i, m in enumerate(msgs):
        stamp, frame, pos = cdr.decode_pose_array(m.data)
        assert (m.log_time_ns, stamp, frame) == (i + 1, i + 1, "map")
        assert pos.shape == (50, 2) and (pos == float(i)).all()
    info = scan_recording(path)
    assert info.truncated is True and info.message_count == len(msgs)
    assert info.metadata == reader.metadata and read_metadata(path) == reader.metadata
    assert info.channels["/crowd/poses"].message_count == len(msgs)


def test_cut_tail_reads_without_exception(tmp_path):
    path = tmp_path / "full.mcap"
    _write_run(path, n_steps=120, chunk_size=8192)
    data = path.read_bytes()
    full = [(m.topic, m.log_time_ns, m.data) for m in read_recording(path)]
    with open(path, "rb") as f:
        summary = SeekingReader(f).get_summary()
        per_chunk = []  # (end of the chunk record, messages in it)
        for ci in summary.chunk_indexes:
            f.seek(ci.chunk_start_offset + 9)
            records = breakup_chunk(Chunk.read(ReadDataStream(f)))
            per_chunk.append((ci.chunk_start_offset + ci.chunk_length,
                              sum(isinstance(r, Message) for r in records)))
    assert len(per_chunk) >= 4 and sum(n for _, n in per_chunk) == len(full)
    starts = [ci.chunk_start_offset for ci in summary.chunk_indexes]
    ends = [e for e, _ in per_chunk]
    data_end = max(ci.chunk_start_offset + ci.chunk_length + ci.message_index_length
                   for ci in summary.chunk_indexes)
    offsets = {0, 1, 5, 8, 9, 20, len(data) - 1, len(data) - 8, len(data) - 9, len(data) - 37,
               data_end, data_end + 1}
    for s, e in zip(starts, ends):
        offsets |= {s, s + 1, s + 9, s + 60, (s + e) // 2, e - 1, e, e + 1}
    offsets |= set(range(0, len(data), 997))
    previous = -1
    for cut in sorted(o for o in offsets if 0 <= o < len(data)):
        p = tmp_path / "cut.mcap"
        p.write_bytes(data[:cut])
        reader = read_recording(p)
        got = [(m.topic, m.log_time_ns, m.data) for m in reader]
        assert reader.truncated is True, cut
        # exactly the messages of the chunks whose record is complete, intact and in order
        expected = sum(n for e, n in per_chunk if e <= cut)
        assert len(got) == expected, cut
        assert got == full[:expected], cut
        assert len(got) >= previous, cut
        previous = len(got)
        info = scan_recording(p)
        assert info.truncated is True and info.message_count == expected, cut
        md = read_metadata(p)
        assert md == reader.metadata, cut
        if cut >= starts[0]:
            assert md == {"sweep_ros": META, "scene_spec": {"yaml": "agents: 13\n"}}, cut
    assert previous == len(full)


def test_recover_keeps_exactly_what_our_reader_reads_at_any_cut(tmp_path):
    """`sweep recover` (recover()) at cuts inside and between chunks, metadata and the summary:
    the same messages as read_recording (bit for bit, in order, with sequence numbers and
    publish times), schemas, channel metadata (QoS) and metadata records, in a file that mcap's
    seeking reader opens with its summary."""
    from sweep_core.io.recording.recover import recover

    path = tmp_path / "full.mcap"
    _write_run(path, n_steps=120, chunk_size=8192)
    data = path.read_bytes()
    with open(path, "rb") as f:
        summary = SeekingReader(f).get_summary()
    starts = sorted(ci.chunk_start_offset for ci in summary.chunk_indexes)
    offsets = {8, 9, 20, 100, len(data) - 1, len(data) - 37, len(data) - 200}
    for s in starts:
        offsets |= {s - 1, s, s + 9, s + 100}
    offsets |= set(range(0, len(data), 1999))
    for cut in sorted(o for o in offsets if 8 <= o <= len(data)):
        p = tmp_path / "cut.mcap"
        p.write_bytes(data[:cut])
        ours = [(m.topic, m.msgtype, m.log_time_ns, m.publish_time_ns, m.data)
                for m in read_recording(p)]
        res = recover(p, tmp_path / "fixed.mcap")
        assert res.message_count == len(ours) and res.kept_bytes <= cut, cut
        assert res.lost_bytes == cut - res.kept_bytes, cut
        with open(tmp_path / "fixed.mcap", "rb") as f:
            reader = make_reader(f)
            fixed_summary = reader.get_summary()
            assert fixed_summary is not None, cut
            got = [(c.topic, s.name, m.log_time, m.publish_time, m.data)
                   for s, c, m in reader.iter_messages(log_time_order=False)]
            seqs = {}
            for _, c, m in reader.iter_messages(log_time_order=False):
                seqs.setdefault(c.topic, []).append(m.sequence)
            md = {m.name: m.metadata for m in reader.iter_metadata()}
        assert got == ours, cut
        assert all(s == list(range(1, len(s) + 1)) for s in seqs.values()), cut
        assert md.pop("sweep_recover")["kept_bytes"] == str(res.kept_bytes)
        assert md == read_metadata(p), cut
        if got:
            qos = {c.topic: c.metadata for c in fixed_summary.channels.values()}
            assert qos["/crowd/poses"]["offered_qos_profiles"] == DEFAULT_QOS_PROFILES
    assert res.complete  # the last cut is the whole file


def test_recover_keeps_attachments_and_never_overwrites_its_input(tmp_path):
    from mcap.writer import Writer

    from sweep_core.io.recording.recover import recover

    path = tmp_path / "a.mcap"
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=256)
        w.start(profile="ros2", library="test")
        w.add_attachment(5, 6, "scene.yaml", "text/yaml", b"agents: 1\n")
        sid = w.register_schema(cdr.CLOCK, "ros2msg", b"builtin_interfaces/Time clock\n")
        cid = w.register_channel("/clock", "cdr", sid)
        for i in range(50):
            w.add_message(cid, i, cdr.encode_clock(i), i, i + 1)
        w.finish()
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    res = recover(cut)
    assert res.out == str(tmp_path / "cut.recovered.mcap") and res.attachments == 1
    assert 0 < res.message_count < 50 and not res.complete and res.tail
    with open(res.out, "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        [att] = list(reader.iter_attachments())
        assert (att.name, att.media_type, att.data, att.create_time, att.log_time) == \
            ("scene.yaml", "text/yaml", b"agents: 1\n", 5, 6)
    before = cut.read_bytes()
    with pytest.raises(RecordingError, match="never overwrites its input"):
        recover(cut, cut)
    link = tmp_path / "link.mcap"
    link.symlink_to(cut)
    with pytest.raises(RecordingError, match="never overwrites its input"):
        recover(cut, link)
    assert cut.read_bytes() == before
    assert not list(tmp_path.glob(".*partial"))
