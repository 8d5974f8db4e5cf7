"""`sweep replay` of a robot recording with one damaged chunk: the robot's commands in it are
lost, so the comparison stops before it (exit 2, one line) instead of reporting a divergence."""
from __future__ import annotations

from pathlib import Path

import pytest
from mcap.reader import SeekingReader

from sweep_core.cli import main


def test_replay_stops_where_robot_commands_were_lost(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    good = tmp_path / "rr.mcap"
    assert main(["run", "robot_crowd", "--t-end", "2", "--out", str(good), "--quiet"]) == 0
    assert main(["replay", str(good), "--quiet"]) == 0
    with good.open("rb") as f:
        summary = SeekingReader(f).get_summary()
    assert summary is not None and len(summary.chunk_indexes) >= 3
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    start = chunks[len(chunks) // 2].chunk_start_offset  # a chunk in the middle: its record's
    data = bytearray(good.read_bytes())  # opcode and length damaged, the chunk unreadable
    for i in range(start, start + 9):
        data[i] ^= 0xFF
    bad = tmp_path / "copy.mcap"
    bad.write_bytes(bytes(data))
    capsys.readouterr()
    rc = main(["replay", str(bad), "--quiet"])
    captured = capsys.readouterr()
    assert rc == 2, captured.out + captured.err
    assert "DIVERGED" not in captured.out and "NOT COMPARED" in captured.out, captured.out
    errors = [line for line in captured.err.splitlines() if line.startswith("sweep: error: ")]
    assert len(errors) == 1 and "commands" in errors[0] and "(fix: " in errors[0], captured.err
