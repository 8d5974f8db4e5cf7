"""``sweep export --pedpy``: frames from the recorded times. A recording whose states are not
evenly spaced (a node's ticks: one cut short by ``initialpose``, several steps in one under
``real_time_factor``) is put on even frames by linear interpolation, and PedPy's speeds on the
export equal the true speeds; a recording without a frame, or cut short, is refused."""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from sweep_core.cli import main
from sweep_core.io import topics
from sweep_core.io.metadata import run_metadata
from sweep_core.io.recording.background import BackgroundRecorder
from sweep_core.model.scene import Scene
from sweep_core.numerics.simulator import Simulator

pedpy = pytest.importorskip("pedpy")

#: each agent's constant velocity (m/s): no walls, no noise, disks far apart, so the centres
#: move on straight lines at these velocities and every window's true speed is |v|
VELOCITIES = [[1.2, 0.0], [0.0, 0.7], [-0.9, 0.4], [0.3, -1.5]]
DT = 0.05
#: steps between the recorded states, as a node's ticks give them (mostly 5)
TICKS = [5, 5, 5, 4, 5, 5, 5, 5, 5, 8, 3, 5]


def _node_like_recording(path, ticks, t_end=6.0, record_every=None, **options):
    """States recorded after ``ticks`` steps each (cycled) up to t_end, with the node's
    metadata (no record_every unless given); ``options`` for the recorder (chunk size)."""
    scene = Scene.from_dict({
        "agents": {"positions": [[0.0, 0.0], [10.0, 0.0], [20.0, 0.0], [30.0, 0.0]],
                   "radius": 0.2},
        "drift": {"kind": "per_agent", "velocities": VELOCITIES},
    })
    sim = Simulator(scene, dt=DT, seed=0)
    with BackgroundRecorder(path, metadata=run_metadata(scene, sim, None, record_every),
                            **options) as rec:
        for name, msgtype in topics.TYPES.items():
            rec.add_channel("/" + name, msgtype)
        topics.record_state(rec.write, sim.state)
        for gap in itertools.cycle(ticks):
            if sim.t + gap * DT > t_end + 1e-9:
                break
            sim.step(gap)
            topics.record_state(rec.write, sim.state)
    return path


def _pedpy_speeds(txt, frame_step):
    data = pedpy.load_trajectory_from_txt(trajectory_file=txt)
    speed = pedpy.compute_individual_speed(traj_data=data, frame_step=frame_step)
    truth = np.hypot(*np.asarray(VELOCITIES).T)[speed["id"].to_numpy()]
    return data, speed["speed"].to_numpy() / truth


def test_uneven_ticks_give_pedpy_the_true_speeds(tmp_path, capsys):
    """Before: frames numbered step // 3 (the smallest gap) at 1 / (3 dt) frames/s: PedPy's
    speeds came out 0.90-1.11 times the truth (frame_step 2), two thirds of them off by more
    than 1 %. Now every speed is the truth within the export's 1e-6 m."""
    rec = _node_like_recording(tmp_path / "node.mcap", TICKS)
    out = tmp_path / "node.txt"
    assert main(["export", str(rec), "--pedpy", str(out)]) == 0
    data, ratio = _pedpy_speeds(out, frame_step=2)
    assert len(ratio) > 80
    # positions written to 1e-6 m over windows of 4 frames (1 s): speeds within 2e-6 m/s
    np.testing.assert_allclose(ratio, 1.0, atol=5e-6)
    assert data.frame_rate == pytest.approx(1.0 / (5 * DT))  # the most common tick, 5 steps
    # frame k is the time k * 0.25 s: agent 0 (1.2 m/s from x = 0) is at x = 0.3 k
    df = data.data[data.data["id"] == 0]
    np.testing.assert_allclose(df["x"], 0.3 * df["frame"], atol=2e-6)
    printed = capsys.readouterr().out
    assert "interpolated linearly" in printed and "3-8 steps apart" in printed, printed
    assert "# frames:" in out.read_text()


def test_even_recordings_are_their_recorded_states(tmp_path, capsys):
    """Every 4th step recorded (as sweep run with --record-every 4): the frames are the
    recorded states, none interpolated, frame k the step 4 k."""
    rec = _node_like_recording(tmp_path / "even.mcap", [4], record_every=4)
    out = tmp_path / "even.txt"
    assert main(["export", str(rec), "--pedpy", str(out)]) == 0
    assert "interpolated" not in capsys.readouterr().out
    data, ratio = _pedpy_speeds(out, frame_step=1)
    assert sorted(set(data.data["frame"])) == list(range(31))  # t = 0 .. 6 s
    np.testing.assert_allclose(ratio, 1.0, atol=5e-6)


def test_missing_records_are_interpolated_at_the_recorded_rate(tmp_path, capsys):
    """record_every 4 but two states missing (8-step gaps): the frame rate stays 1 / (4 dt),
    the holes are filled, and the speeds are the truth."""
    rec = _node_like_recording(tmp_path / "holes.mcap", [4, 8, 4, 4, 8], record_every=4)
    out = tmp_path / "holes.txt"
    assert main(["export", str(rec), "--pedpy", str(out)]) == 0
    assert "interpolated linearly" in capsys.readouterr().out
    data, ratio = _pedpy_speeds(out, frame_step=1)
    assert data.frame_rate == pytest.approx(5.0)
    assert sorted(set(data.data["frame"])) == list(range(30))  # the last state: step 116
    np.testing.assert_allclose(ratio, 1.0, atol=5e-6)


def test_a_recording_without_a_frame_is_refused(tmp_path, capsys):
    """Before: an empty trajectory file PedPy rejects, and exit 0 saying PedPy reads it."""
    scene = Scene.from_dict({"agents": {"positions": [[0.0, 0.0]], "radius": 0.2}})
    sim = Simulator(scene, dt=DT, seed=0)
    rec = tmp_path / "none.mcap"
    with BackgroundRecorder(rec, metadata=run_metadata(scene, sim, None)) as r:
        for name, msgtype in topics.TYPES.items():
            r.add_channel("/" + name, msgtype)
    out = tmp_path / "none.txt"
    assert main(["export", str(rec), "--pedpy", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(rec) in err[0] and "no recorded state" in err[0], err
    assert "fix:" in err[0] and "reads it" not in err[0]
    assert not out.exists() and not list(tmp_path.glob(".*partial*"))


def test_a_recording_cut_short_is_refused(tmp_path, capsys):
    """Before: exported up to the cut, exit 0, as if the run had ended there."""
    # chunks of 16 kB, closed by size alone (not by the wall clock): the cut leaves several whole
    rec = _node_like_recording(tmp_path / "whole.mcap", [1], t_end=60.0, record_every=1,
                               chunk_size=1 << 14, flush_interval_s=None)
    cut = tmp_path / "cut.mcap"
    data = rec.read_bytes()
    cut.write_bytes(data[:len(data) * 2 // 3])
    out = tmp_path / "cut.txt"
    assert main(["export", str(cut), "--pedpy", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cut short" in err[0] and f"sweep recover {cut}" in err[0], err
    assert not out.exists()


@pytest.mark.parametrize("content, problem", [
    (b"", "empty"), (b"id frame x y z\n0 0 1.0 2.0 0.0\n", "not an MCAP file")])
def test_foreign_and_empty_files_are_refused_in_one_line(tmp_path, capsys, content, problem):
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(content)
    out = tmp_path / "bad.txt"
    assert main(["export", str(bad), "--pedpy", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0] and problem in err[0] and "fix:" in err[0], err
    assert "Traceback" not in err[0] and not out.exists()
