"""Faults of `sweep run` and its recordings (issue 12): SIGTERM and SIGINT close the recording,
kill -9 then `sweep recover` gives a file the standard readers open, every run ends with a
status record and a summary, `sweep run` refuses runs beyond its bounds, `sweep analyze`
bounds its density grid, and the two contact counts have different names."""
from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import pytest
from mcap.reader import SeekingReader, make_reader

from sweep_core.cli import main
from sweep_core.io import limits
from sweep_core.io.recording import read_metadata, read_recording, scan_recording

REPO = Path(__file__).resolve().parents[1]

SCENE = """
agents: {positions: [[0.0, 0.0], [0.6, 0.0], [1.2, 0.0]], radius: 0.25}
walls: [{kind: halfplane, normal: [1, 0], offset: -0.5}]
drift: {kind: uniform, velocity: [-1.0, 0.0]}
noise: {sigma: 0.05}
"""

# two disks between walls 1 m apart growing at 0.45 m/s: no room after t = 1/9 s
GROWING = """
agents: {positions: [[0.3, 0.0], [0.7, 0.0]], radius: 0.2,
         radius_law: {kind: linear, rate: 0.45}}
walls: [{kind: halfplane, normal: [1, 0], offset: 0.0},
        {kind: halfplane, normal: [-1, 0], offset: -1.0}]
"""


def _scene(tmp_path: Path, text: str = SCENE) -> Path:
    p = tmp_path / "scene.yaml"
    p.write_text(text)
    return p


def _start_run(tmp_path: Path, out: Path) -> subprocess.Popen:
    """`sweep run` of the 3-agent scene for far longer than the test, in a subprocess."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(REPO)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    return subprocess.Popen(
        [sys.executable, "-m", "sweep_core.cli", "run", str(_scene(tmp_path)), "--t-end", "1000",
         "--dt", "0.001", "--out", str(out), "--quiet"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=tmp_path)


def _wait_for_messages(proc: subprocess.Popen, out: Path, at_least: int = 100) -> int:
    """Waits until the running recording holds at least ``at_least`` messages (it flushes
    every second); returns how many it held."""
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        if out.exists():
            n = scan_recording(out).message_count
            if n >= at_least:
                return n
        time.sleep(0.2)
    raise AssertionError("the run wrote nothing in 120 s")


def _stop(proc: subprocess.Popen, sig: int) -> tuple[str, str]:
    try:
        os.kill(proc.pid, sig)
        return proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


def _standard_counts(path: Path) -> Counter:
    """Messages per topic as rosbags' AnyReader and mcap's seeking reader see them (both
    refuse a file without its summary and footer)."""
    highlevel = pytest.importorskip("rosbags.highlevel")
    with highlevel.AnyReader([path]) as reader:
        by_rosbags = Counter(c.topic for c, _, _ in reader.messages())
    with open(path, "rb") as f:
        mcap_reader = make_reader(f)
        assert isinstance(mcap_reader, SeekingReader)
        summary = mcap_reader.get_summary()
        assert summary is not None and summary.statistics is not None
        by_mcap = Counter(ch.topic for _, ch, _ in mcap_reader.iter_messages())
        stats = {summary.channels[c].topic: n
                 for c, n in summary.statistics.channel_message_counts.items()}
    assert by_rosbags == by_mcap == Counter(stats)
    return by_rosbags


# -- 1. SIGTERM (and SIGINT) close the recording ------------------------------------------------


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_signal_closes_the_recording_and_writes_the_status(tmp_path, sig):
    """Before: SIGTERM killed `sweep run` with no footer ("File end magic is invalid" in
    rosbags), and neither signal left a status."""
    out = tmp_path / "run.mcap"
    proc = _start_run(tmp_path, out)
    _wait_for_messages(proc, out)
    _, err = _stop(proc, sig)
    assert proc.returncode == 128 + sig, err
    name = signal.Signals(sig).name
    assert f"interrupted by {name}" in err and "Traceback" not in err
    counts = _standard_counts(out)
    summary = json.loads(out.with_suffix(".summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["error"] == name
    # every step was recorded, from step 0 to the last one taken; the walls once, the markers
    # at 10 Hz of simulated time (every 100th state at dt 0.001)
    steps = summary["steps"]
    assert counts == {"/poses": steps + 1, "/agents": steps + 1, "/walls": 1,
                      "/markers": steps // 100 + 1}
    status = read_metadata(out)["sweep_status"]
    assert status == {"status": "interrupted", "error": name, "steps": str(summary["steps"]),
                      "t_s": repr(summary["t_end_s"])}


# -- 2. kill -9, then sweep recover --------------------------------------------------------------


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_kill9_then_recover_gives_a_file_the_standard_readers_open(tmp_path, capsys):
    out = tmp_path / "run.mcap"
    proc = _start_run(tmp_path, out)
    _wait_for_messages(proc, out)
    _stop(proc, signal.SIGKILL)
    assert proc.returncode == -signal.SIGKILL
    highlevel = pytest.importorskip("rosbags.highlevel")
    with pytest.raises(Exception, match="magic"):  # what users met before
        with highlevel.AnyReader([out]):
            pass
    reader = read_recording(out)
    ours = Counter(m.topic for m in reader)
    assert reader.truncated is True and ours["/poses"] >= 50
    before = _sha(out)

    # analyze reads it as before, says how the run ended, and suggests recover
    assert main(["analyze", str(out), "--no-plots", "--quiet"]) == 0
    cap = capsys.readouterr()
    assert "unknown (no status record: the run was cut short)" in cap.out
    assert f"sweep recover {out}" in cap.err and len(cap.err.strip().splitlines()) == 1

    assert main(["recover", str(out)]) == 0
    printed = capsys.readouterr().out
    fixed = tmp_path / "run.recovered.mcap"
    assert _sha(out) == before  # the input is never modified
    assert _standard_counts(fixed) == ours
    assert f"/poses {ours['/poses']}" in printed and f"/agents {ours['/agents']}" in printed
    assert "lost" in printed and "the run was to reach t = 1000 s" in printed
    md = read_metadata(fixed)
    assert md["sweep_ros"] == read_metadata(out)["sweep_ros"]
    assert md["sweep_recover"]["complete"] == "false"
    # bit for bit the same messages, in the same order
    got = [(m.topic, m.log_time_ns, m.data) for m in read_recording(fixed)]
    assert got == [(m.topic, m.log_time_ns, m.data) for m in read_recording(out)]

    assert main(["analyze", str(fixed), "--no-plots", "--quiet"]) == 0
    cap = capsys.readouterr()
    assert "the run was cut short, then recovered" in cap.out and "hint" not in cap.err
    # never over its input, and an explicit OUT works
    assert main(["recover", str(out), str(out)]) == 2
    assert "never overwrites its input" in capsys.readouterr().err and _sha(out) == before
    other = tmp_path / "other.mcap"
    assert main(["recover", str(out), str(other)]) == 0
    assert _standard_counts(other) == ours


def _complete_run(tmp_path: Path, name: str = "c.mcap", *extra: str) -> Path:
    out = tmp_path / name
    main(["run", str(_scene(tmp_path)), "--t-end", "0.5", "--dt", "0.01", "--out", str(out),
          "--quiet", *extra])
    return out


def test_cut_at_every_chunk_boundary_recovers_what_sweep_reads(tmp_path, capsys):
    """Cuts inside and between chunks: recover keeps exactly the messages sweep's reader
    reads, and the standard readers open the result."""
    out = _complete_run(tmp_path)
    data = out.read_bytes()
    with open(out, "rb") as f:
        summary = SeekingReader(f).get_summary()
        first_chunk = min(ci.chunk_start_offset for ci in summary.chunk_indexes)
    for cut in (len(data) - 40, len(data) // 2, first_chunk + 30):
        p = tmp_path / f"cut{cut}.mcap"
        p.write_bytes(data[:cut])
        ours = Counter(m.topic for m in read_recording(p))
        assert main(["recover", str(p)]) == 0
        assert _standard_counts(p.with_name(p.stem + ".recovered.mcap")) == ours, cut
    capsys.readouterr()
    # a complete file is copied whole
    assert main(["recover", str(out)]) == 0
    assert "nothing (the file's data section was complete)" in capsys.readouterr().out
    assert _standard_counts(tmp_path / "c.recovered.mcap") == Counter(
        m.topic for m in read_recording(out))


def test_file_cut_before_its_first_chunk_is_reported_as_cut_short(tmp_path, capsys):
    """Before: "no geometry_msgs/msg/PoseArray topic '/poses' (topics: [])"."""
    out = _complete_run(tmp_path)
    with open(out, "rb") as f:
        first_chunk = min(ci.chunk_start_offset for ci in SeekingReader(f).get_summary()
                          .chunk_indexes)
    cut = tmp_path / "early.mcap"
    cut.write_bytes(out.read_bytes()[:first_chunk + 5])
    capsys.readouterr()
    for cmd in (["analyze", str(cut), "--no-plots"], ["replay", str(cut)],
                ["compare", str(cut), str(out), "--no-plots"]):
        assert main([*cmd, "--quiet"]) == 2
        err = capsys.readouterr().err
        assert (f"no messages: the file ends at byte {first_chunk + 5} before its first chunk; "
                "it was cut short") in err, cmd
        assert "/poses" not in err and len(err.strip().splitlines()) == 1
    assert main(["recover", str(cut)]) == 0
    printed = capsys.readouterr().out
    assert "kept       0 messages" in printed and "before its first chunk" in printed
    fixed = tmp_path / "early.recovered.mcap"
    assert _standard_counts(fixed) == Counter()
    assert read_metadata(fixed)["sweep_ros"] == read_metadata(out)["sweep_ros"]


def test_replay_and_compare_suggest_recover_for_a_cut_file(tmp_path, capsys):
    out = _complete_run(tmp_path)
    data = out.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:len(data) - 40])
    capsys.readouterr()
    assert main(["replay", str(cut), "--quiet"]) == 0
    assert f"sweep recover {cut}" in capsys.readouterr().err
    assert main(["compare", str(out), str(cut), "--no-plots", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert f"sweep recover {cut}" in err and f"sweep recover {out}" not in err


# -- 3. the run's status ---------------------------------------------------------------------


def test_completed_run_has_status_completed(tmp_path, capsys):
    out = _complete_run(tmp_path)
    assert read_metadata(out)["sweep_status"]["status"] == "completed"
    summary = json.loads(out.with_suffix(".summary.json").read_text())
    assert summary["status"] == "completed" and summary["error"] == ""
    capsys.readouterr()
    assert main(["analyze", str(out), "--no-plots", "--quiet"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [ln.split() for ln in lines if ln.startswith("status")] == [["status", "completed"]]


def test_failed_run_says_why_in_the_recording_and_the_summary(tmp_path, capsys):
    """Before: an InfeasibleError left no summary JSON and nothing in the recording."""
    out = tmp_path / "g.mcap"
    assert main(["run", str(_scene(tmp_path, GROWING)), "--t-end", "0.5", "--out", str(out),
                 "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "no feasible configuration at t = 0.12 s" in err
    summary = json.loads(out.with_suffix(".summary.json").read_text())
    assert summary["status"] == "failed" and summary["steps"] == 11
    assert summary["error"].startswith("no feasible configuration at t = 0.12 s")
    status = read_metadata(out)["sweep_status"]
    assert status["status"] == "failed" and status["error"] == summary["error"]
    # closed properly: 12 states, the walls once, the markers at 10 Hz (states 0 and 10)
    assert _standard_counts(out) == {"/poses": 12, "/agents": 12, "/walls": 1, "/markers": 2}
    assert main(["analyze", str(out), "--no-plots", "--quiet"]) == 0
    assert "failed (no feasible configuration at t = 0.12 s" in capsys.readouterr().out


# -- 4. input limits ---------------------------------------------------------------------------


@pytest.mark.parametrize("args, message", [
    (["--dt", "1e-9"], "--dt: 1e-09 s is outside [1e-05, 1] s"),
    (["--dt", "2"], "--dt: 2 s is outside [1e-05, 1] s"),
    (["--dt", "1e-5", "--t-end", "100"],
     "--t-end/--dt: 100 s at dt = 1e-05 s is 1e+07 steps, more than the limit 1e+06 (fix: a "
     "larger --dt (>= 0.0001 s), a shorter --t-end (<= 10 s), or --force)"),
    (["--dt", "0.01", "--t-end", "2000"],
     "--record-every: 1 records 200001 states of 200 agents, about 3.58 GB uncompressed, more "
     "than the limit 2 GB (fix: --record-every 2 or more, a shorter --t-end, or --force)"),
    (["--dt", "0.001", "--t-end", "10", "--path-dt", "1e-6"],
     "--path-dt: 1e-06 s over 10 s draws 1e+07 fine increments"),
    (["--path-dt", "0.003"], "path_dt: dt = 0.01 s is not a whole multiple of path_dt"),
])
def test_run_refuses_runs_beyond_its_bounds(tmp_path, capsys, args, message):
    """Before: dt = 1e-9 started 1e9 steps, dt = 2 ran, a 3.6 GB recording started."""
    out = tmp_path / "x.mcap"
    assert main(["run", *args, "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1 and "fix:" in err
    assert not out.exists()


def test_force_lifts_the_size_bounds_not_the_dt_range():
    size = limits.check_run_size(200, 0.01, 2000.0, force=True)
    assert size.steps == 200_000 and size.frames == 200_001
    assert size.recording_bytes == 200_001 * limits.frame_bytes(200)
    assert limits.frame_bytes(200) == 11228 + 6629 + 2 * 31  # measured CDR sizes + records
    with pytest.raises(Exception, match="--record-every 8 or more"):
        limits.check_run_size(200, 0.01, 8000.0, record_every=3)
    assert limits.check_run_size(200, 0.01, 8000.0, record_every=8).frames == 100_001
    with pytest.raises(Exception, match="outside"):
        limits.check_dt(2.0)


def test_cli_dt_range_is_the_nodes():
    params = pytest.importorskip("sweep_ros.params")
    dt = next(s for s in params.SPECS if s.name == "dt")
    assert (dt.lo, dt.hi) == (limits.DT_MIN, limits.DT_MAX)


# -- 5. density grid bound ------------------------------------------------------------------


def test_analyze_refuses_a_density_grid_too_fine(tmp_path, capsys):
    """Before: --cell 1e-4 on a room died with a 52 GiB allocation traceback."""
    out = _complete_run(tmp_path)
    capsys.readouterr()
    assert main(["analyze", str(out), "--cell", "1e-5", "--no-plots", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("sweep: error: --cell: 1e-05 m makes a density grid of ")
    assert "more than the limit 4e+06 (fix: --cell " in err and "Traceback" not in err
    fix = float(err.split("fix: --cell ")[1].split()[0])
    assert main(["analyze", str(out), "--cell", str(fix), "--no-plots", "--quiet"]) == 0
    assert "density.cell_m" in capsys.readouterr().out


# -- 6. the two contact counts ----------------------------------------------------------------


def test_contact_counts_have_different_names(tmp_path, capsys):
    out = _complete_run(tmp_path)
    summary = json.loads(out.with_suffix(".summary.json").read_text())
    assert {"active_rows_mean", "active_rows_max"} <= set(summary)
    assert not any(k.startswith("contacts") for k in summary)
    capsys.readouterr()
    assert main(["analyze", str(out), "--no-plots", "--quiet", "--json"]) == 0
    an = json.loads(capsys.readouterr().out)
    assert an["touching"]["max"] == an["contacts"]["max"]  # old key kept for JSON readers
    assert main(["analyze", str(out), "--no-plots", "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "touching.max" in text and "contacts" not in text
    header = (tmp_path / "c.analysis.csv").read_text().splitlines()[0].split(",")
    assert header[3] == "touching"
