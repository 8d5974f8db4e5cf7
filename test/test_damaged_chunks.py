"""A recording with one damaged chunk (its bytes changed after it was written, so its CRC no
longer matches its data) is never read as if it were whole.

mcap's own CRC check runs on every chunk sweep reads: the damaged chunk is skipped with one
line on stderr naming the file, its byte offset and the CRC mismatch (``analyze``,
``replay``, ``render``, :func:`read_recording`), or the command refuses in one line when it cannot go on
without it (``export --pedpy``); ``sweep recover`` keeps what comes before it. Without the
check the damaged bytes were decoded: ``analyze`` blamed the writer for ids like 7.9e-31,
``export`` wrote ids like -9223372036854775808, ``replay`` blamed the simulation.
"""
from __future__ import annotations

from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, Message
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap_copies import rewrite

from sweep_core.analysis.frames import FrameReader
from sweep_core.analysis.run import load_run
from sweep_core.cli import main
from sweep_core.io.recording import read_recording
from sweep_core.model.yaml_files import dump_yaml

ROOM = [{"kind": "polyline", "points": [[0, 0], [10, 0], [10, 4], [0, 4]], "closed": True}]
SCENE = {"name": "corridor",
         "agents": {"positions": [[1.0, 1.0], [1.0, 2.0], [2.0, 1.5]], "radius": 0.2},
         "walls": ROOM, "drift": {"kind": "goal", "goal": [9.5, 2.0], "speed": 1.3},
         "flows": {"sources": [{"region": {"kind": "rectangle", "min": [0.3, 0.3],
                                           "max": [1.5, 3.7]}, "rate": 4.0, "count": 8}],
                   "sinks": [{"kind": "rectangle", "min": [8.5, 0.0], "max": [10.0, 4.0]}]}}
CRC_WORDS = ("CRC", "does not match", "damaged")


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> tuple[Path, Path, int]:
    """(the recording, a copy with one chunk in its middle damaged, that chunk's offset):
    the run written again in small uncompressed chunks, 200 bytes of the middle one flipped."""
    folder = tmp_path_factory.mktemp("damaged_chunks")
    scene = folder / "corridor.yaml"
    scene.write_text(dump_yaml(SCENE))
    run = folder / "run.mcap"
    assert main(["run", str(scene), "--t-end", "1.0", "--dt", "0.05", "--out", str(run),
                 "--quiet"]) == 0
    good = folder / "good.mcap"
    rewrite(run, good, chunk_size=2048, library="test damaged")
    with open(good, "rb") as f:
        summary = make_reader(f).get_summary()
        assert summary is not None
        chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    assert len(chunks) >= 5
    chunk = chunks[len(chunks) // 2]
    data = bytearray(good.read_bytes())
    middle = chunk.chunk_start_offset + chunk.chunk_length // 2
    for i in range(middle - 100, middle + 100):
        data[i] ^= 0xFF
    bad = folder / "bad.mcap"
    bad.write_bytes(bytes(data))
    return good, bad, chunk.chunk_start_offset


def _named(line: str, bad: Path, offset: int) -> bool:
    return str(bad) in line and f"byte {offset}" in line and all(w in line for w in CRC_WORDS)


def test_the_reader_skips_the_damaged_chunk_and_names_it(files):
    good, bad, offset = files
    whole = {(m.topic, m.sequence): m.data for m in read_recording(good)}
    reader = read_recording(bad)
    read = list(reader)
    assert len(reader.problems) == 1 and f"byte {offset}" in reader.problems[0]
    assert all(w in reader.problems[0] for w in CRC_WORDS), reader.problems
    assert 0 < len(read) < len(whole)
    assert all(m.offset != offset for m in read)
    assert all(whole[(m.topic, m.sequence)] == m.data for m in read)  # nothing damaged read


def test_analyze_skips_the_damaged_chunk_with_a_note(files, capsys):
    _, bad, offset = files
    code = main(["analyze", str(bad), "--no-plots", "--quiet"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "Traceback" not in err and "error" not in err, err
    assert any(_named(line, bad, offset) for line in err.splitlines()), err


def test_export_refuses_a_damaged_recording_in_one_line(files, tmp_path, capsys):
    _, bad, offset = files
    out = tmp_path / "traj.txt"
    code = main(["export", str(bad), "--pedpy", str(out)])
    err = capsys.readouterr().err
    errors = [ln for ln in err.splitlines() if ln.startswith("sweep: error:")]
    assert code == 2 and len(errors) == 1 and "Traceback" not in err, err
    assert _named(errors[0], bad, offset) and "re-record" in errors[0], errors[0]
    assert not out.exists()


def test_replay_does_not_compare_the_damaged_chunk(files, capsys):
    _, bad, offset = files
    code = main(["replay", str(bad)])
    cap = capsys.readouterr()
    assert code == 0, cap.out + cap.err
    assert "DIVERGED" not in cap.out and "IDENTICAL on the" in cap.out, cap.out
    assert "not compared" in cap.out and "in a skipped chunk" in cap.out, cap.out
    assert any(_named(line, bad, offset) for line in cap.err.splitlines()), cap.err


def test_recover_keeps_what_comes_before_the_damaged_chunk(files, tmp_path, capsys):
    _, bad, offset = files
    out = tmp_path / "copy.mcap"
    assert main(["recover", str(bad), str(out)]) == 0
    text = capsys.readouterr().out
    assert f"the chunk at byte {offset}" in text and "CRC does not match" in text, text
    assert "had not flushed" not in text, text
    with open(out, "rb") as f:
        kept = list(make_reader(f, validate_crcs=True).iter_messages())
    assert kept and max(m.log_time for _, _, m in kept) < 1e9


def test_render_names_the_damaged_chunk(files, tmp_path, capsys):
    _, bad, offset = files
    out = tmp_path / "video.gif"
    assert main(["render", str(bad), "--out", str(out), "--size", "160", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err and out.exists(), err
    assert any(_named(line, bad, offset) for line in err.splitlines()), err



def _split_frame(run: Path, folder: Path) -> tuple[Path, int, float]:
    """A copy of ``run`` in uncompressed chunks, one of which (after the first) ends with a
    /poses message whose /agents opens the next chunk: (the copy, that next chunk's offset,
    the /poses message's time (s)). The chunk size is searched for (deterministic: the
    messages' sizes do not depend on the run's numbers)."""
    copy = folder / "split.mcap"
    for size in range(300, 3000, 50):
        rewrite(run, copy, chunk_size=size, library="test split")
        topics: dict[int, str] = {}
        ends = []  # (chunk offset, topic and log time of its last message)
        with open(copy, "rb") as f:
            records = StreamReader(f, emit_chunks=True).records
            while True:
                offset = f.tell()
                record = next(records, None)
                if record is None:
                    break
                inner = breakup_chunk(record) if isinstance(record, Chunk) else [record]
                for r in inner:
                    if isinstance(r, Channel):
                        topics[r.id] = r.topic
                messages = [r for r in inner if isinstance(r, Message)]
                if isinstance(record, Chunk) and messages:
                    ends.append((offset, topics[messages[-1].channel_id],
                                 messages[-1].log_time))
        for (_, topic, t), (after, _, _) in zip(ends[1:], ends[2:]):
            if topic == "/poses" and t > 0:
                return copy, after, t / 1e9
    raise AssertionError("no chunk size splits a state from its /agents")


def test_a_state_the_damage_cut_from_its_agents_is_left_out_of_the_recovered_copy(
        files, tmp_path, capsys):
    """The recovered copy ends with a /poses whose /agents was in the damaged chunk. Before:
    `analyze` and `export` of the copy refused it whole ("the frame at t = 0.35 s has no
    readable /agents ids ... fix: record /agents"), though every earlier state is whole; a
    file cut there (not recovered) already had that last state left out."""
    good = files[0]
    split, offset, t = _split_frame(good, tmp_path)
    data = bytearray(split.read_bytes())
    for i in range(offset + 40, offset + 60):  # inside the chunk's records: its CRC fails
        data[i] ^= 0xFF
    bad = tmp_path / "bad_split.mcap"
    bad.write_bytes(bytes(data))
    copy = tmp_path / "copy.mcap"
    assert main(["recover", str(bad), str(copy)]) == 0
    capsys.readouterr()
    whole = [fr.stamp_ns for fr in FrameReader(load_run(good))]
    kept = [s for s in whole if s < round(t * 1e9)]
    reader = FrameReader(load_run(copy))
    assert [fr.stamp_ns for fr in reader] == kept and kept
    note = (f"the last /poses (t = {t:g} s) has no /agents: the file this copy was recovered "
            "from was cut or damaged between them; that state is left out")
    assert reader.problems == [f"{copy}: {note}"], reader.problems
    assert main(["analyze", str(copy), "--no-plots", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert note in err and "error" not in err, err
    out = tmp_path / "traj.txt"
    assert main(["export", str(copy), "--pedpy", str(out)]) == 0
    frames = {int(line.split()[1]) for line in out.read_text().splitlines()
              if line and not line.startswith("#")}
    assert len(frames) == len(kept)
    # the export says where the copy's states end (before: nothing told it from a whole run)
    end = (f"recovered from a recording cut short or damaged: its states end at t = "
           f"{kept[-1] / 1e9:g} s, before the run did")
    assert f"note: {end}" in capsys.readouterr().out
    assert f"# note: {end}" in out.read_text().splitlines()[:4]
    whole_out = tmp_path / "whole.txt"
    assert main(["export", str(good), "--pedpy", str(whole_out)]) == 0
    assert "note" not in capsys.readouterr().out + whole_out.read_text()
