"""Speeds measured over a window (sweep_core.analysis.speed): against PedPy's own
compute_individual_speed on the same exported trajectories, against the exact mean speed of a
freely drifting crowd with noise (the Rice mean), on uneven frame times, and the window's
refusals."""
from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from scipy import stats

from sweep_core.analysis import metrics
from sweep_core.analysis.lines import crossing_flows
from sweep_core.analysis.pedpy_export import read_trajectories, write_pedpy_txt
from sweep_core.analysis.speed import WindowSpeeds, window_speeds
from sweep_core.cli import main

#: a crowd drifting freely: 60 agents 4.5 m apart, 1.2 m/s along x, noise sigma 0.3 m/sqrt(s);
#: in 6 s two neighbours' relative displacement has a standard deviation of 1 m per component,
#: so their 4.1 m gap is 4 standard deviations: the disks move freely
U, SIGMA, DT, T_END, SEED = 1.2, 0.3, 0.02, 6.0, 3
DRIFTING = {
    "name": "drifting_corridor",
    "agents": {"positions": [[4.5 * i, 4.5 * j] for i in range(12) for j in range(5)],
               "radius": 0.2},
    "drift": {"kind": "uniform", "velocity": [U, 0.0]},
    "noise": {"sigma": SIGMA},
}
#: a window of 2 n frames exactly (n = 15 frames of DT either side)
N_STEP = 15
WINDOW = 2 * N_STEP * DT


@pytest.fixture(scope="module")
def drifting(tmp_path_factory):
    d = tmp_path_factory.mktemp("speed")
    scene = d / "drifting.yaml"
    scene.write_text(yaml.safe_dump(DRIFTING))
    out = d / "run.mcap"
    assert main(["run", str(scene), "--t-end", str(T_END), "--dt", str(DT), "--seed",
                 str(SEED), "--out", str(out), "--quiet"]) == 0
    return out


def _rice_mean_speed(u: float, sigma: float, w: float) -> float:
    """E|X| / w for X ~ N((u w, 0), sigma^2 w I): the mean speed over a window w."""
    s = sigma * math.sqrt(w)
    return float(stats.rice(b=u * w / s, scale=s).mean()) / w


def test_windowed_speed_agrees_with_pedpy_on_the_exported_trajectories(drifting):
    pedpy = pytest.importorskip("pedpy")
    an = metrics.analyze(drifting, speed_window=WINDOW)
    # the trajectories as sweep export --pedpy writes them, read back by PedPy itself
    txt = write_pedpy_txt(read_trajectories(drifting), drifting.with_name("run.txt"))
    ped = pedpy.compute_individual_speed(
        traj_data=pedpy.load_trajectory_from_txt(trajectory_file=txt), frame_step=N_STEP,
        speed_calculation=pedpy.SpeedCalculation.BORDER_SINGLE_SIDED)
    ped_mean = float(ped["speed"].mean())
    assert an.summary["speed"]["window_s"] == pytest.approx(WINDOW)
    assert an.summary["speed"]["samples"] == len(ped)
    assert an.summary["speed"]["mean_m_per_s"] == pytest.approx(ped_mean, rel=0.02)
    # frame by frame the same numbers, to the export's 1e-6 m
    per_frame = ped.groupby("frame")["speed"].mean().to_numpy()
    assert np.allclose(an.table[:, 6], per_frame, rtol=0, atol=1e-5)


def test_mean_speed_of_a_drifting_crowd_is_the_rice_mean(drifting):
    an = metrics.analyze(drifting, speed_window=WINDOW)
    # 301 frames: 271 with the whole window (0.6 s), 30 one-sided (0.3 s) at the run's ends
    frames = round(T_END / DT) + 1
    both = frames - 2 * N_STEP
    assert an.summary["speed"]["span_mean_s"] == pytest.approx(
        (both * WINDOW + (frames - both) * WINDOW / 2) / frames)
    t, mean = an.table[:, 0], an.table[:, 6]
    inside = (t >= WINDOW / 2 - 1e-9) & (t <= t[-1] - WINDOW / 2 + 1e-9)  # two-sided windows
    measured = float(mean[inside].mean())
    exact = _rice_mean_speed(U, SIGMA, WINDOW)
    # Monte Carlo error: 60 agents x (5.4 s / 0.6 s) independent windows each; the speed's
    # standard deviation over a window is at most sigma sqrt(2 / w) (both components)
    independent = 60 * (t[-1] - WINDOW) / WINDOW
    se = SIGMA * math.sqrt(2.0 / WINDOW) / math.sqrt(independent)
    assert abs(measured - exact) <= 4 * se, (measured, exact, se)
    # the one-step increment would read sigma / sqrt(dt) level speeds (the definition refused)
    one_step = _rice_mean_speed(U, SIGMA, DT)
    assert abs(measured - one_step) > 20 * se


def test_uneven_frames_use_the_recorded_times():
    # an agent at constant velocity (1, 0.5) m/s recorded at uneven times: the speed is exact
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.05, 0.15, 80))
    q = np.stack([t, 0.5 * t], axis=1)[:, None, :]
    v = window_speeds(t, q, 0.6)
    assert np.allclose(v, math.hypot(1.0, 0.5), rtol=1e-12)


def test_agents_entering_and_leaving_take_one_sided_windows():
    ws = WindowSpeeds(0.4)  # 2 frames of 0.1 s either side
    out = []
    for k in range(10):
        ids = np.array([0, 1]) if 3 <= k <= 6 else np.array([0])  # agent 1 in frames 3-6
        q = np.column_stack([ids * 10.0 + k * 0.1 * (1 + ids), np.zeros(len(ids))])
        out += ws.push(k * 0.1, ids, q, k)
    out += ws.finish()
    assert [r.payload for r in out] == list(range(10))
    # agent 1 moves 0.2 m per frame: every frame of its presence has a one-sided window
    for r in out[3:7]:
        assert r.speed[1] == pytest.approx(2.0)
        assert r.span[1] == pytest.approx(0.2)
    assert all(r.speed[0] == pytest.approx(1.0) for r in out)
    assert out[5].span[0] == pytest.approx(0.4)
    # a one-frame presence has no window at all
    lone = WindowSpeeds(0.4)
    got = lone.push(0.0, np.array([5]), np.zeros((1, 2))) + lone.finish()
    assert np.isnan(got[0].speed[0])


def test_flow_counts_between_the_first_and_last_crossing():
    times = np.array([5.0, 6.0, 7.0, 8.0, 9.0])
    assert crossing_flows(times)["per_s"] == pytest.approx(4 / 4.0)
    assert crossing_flows(times)["steady_per_s"] is None
    assert crossing_flows(np.arange(20.0) * 0.5 + 3)["steady_per_s"] == pytest.approx(2.0)


@pytest.mark.parametrize("value, words", [
    ("0", "must be a positive number of seconds, got 0.0"),
    ("-1", "must be a positive number of seconds, got -1.0"),
    ("nan", "must be a positive number of seconds, got nan"),
    ("1000", "1000 s is longer than the recording (6 s"),
    ("0.03", "0.03 s is shorter than two of the recording's frame intervals (0.02 s"),
])
def test_bad_windows_are_refused_in_one_line(drifting, capsys, value, words):
    assert main(["analyze", str(drifting), "--speed-window", value, "--quiet",
                 "--no-plots"]) == 2
    text = capsys.readouterr().err
    err = [ln for ln in text.splitlines() if "--speed-window" in ln]
    assert len(err) == 1 and words in err[0] and "fix:" in err[0], text
    assert "Traceback" not in text
    assert not drifting.with_name("run.analysis.csv").exists()


def test_a_line_of_zero_length_is_refused(drifting, capsys):
    assert main(["analyze", str(drifting), "--line", "1,2,1,2", "--quiet", "--no-plots"]) == 2
    text = capsys.readouterr().err
    err = [ln for ln in text.splitlines() if "--line" in ln]
    assert len(err) == 1 and "'1,2,1,2'" in err[0], text
    assert "zero length" in err[0] and "fix:" in err[0] and "Traceback" not in text


def test_a_recording_shorter_than_the_default_window_says_so(tmp_path, capsys):
    """A 0.3 s run against the default 0.625 s window: no frame has a recorded frame on both
    sides, so no speed; the summary says why and how to get one (a given window that long is
    refused; a recording longer than the window carries no note)."""
    scene = tmp_path / "drifting.yaml"
    scene.write_text(yaml.safe_dump(DRIFTING))
    out = tmp_path / "short.mcap"
    assert main(["run", str(scene), "--t-end", "0.3", "--dt", str(DT), "--seed", str(SEED),
                 "--out", str(out), "--quiet"]) == 0
    speed = metrics.analyze(out).summary["speed"]
    assert speed["samples"] == 0 and speed["window_s"] == 0.625
    assert speed["note"] == ("the default window 0.625 s is longer than the recording (0.3 s "
                             "from its first to its last frame): every speed is one-sided or "
                             "missing (fix: give --speed-window of at most 0.3 s)")
    assert main(["analyze", str(out), "--no-plots", "--quiet"]) == 0
    assert "speed.note" in capsys.readouterr().out
    given = metrics.analyze(out, speed_window=0.3).summary["speed"]
    assert given["samples"] > 0 and "note" not in given


def test_a_line_crossed_mostly_backwards_says_so_and_how_to_turn_it():
    """A line drawn the other way round: every crossing negative, so no flow and no evacuation
    time; the summary says why, with the line's ends swapped. A line crossed mostly forwards
    has no note."""
    from sweep_core.analysis.lines import flow_summary

    times = np.array([1.0, 2.0])
    back = flow_summary((10.0, 3.0, 10.0, 0.0), (-16, 0, 16), np.zeros(0),
                        np.full(16, np.nan), 16)
    assert back["per_s"] is None and back["evacuated"] == 0
    assert back["note"] == ("16 of the 16 crossings are negative (right to left): per_s, "
                            "steady_per_s and the evacuation times count the positive ones "
                            "only (fix: for the other direction give the ends swapped, --line "
                            "10,0,10,3)")
    ahead = flow_summary((10.0, 0.0, 10.0, 3.0), (1, 2, 1), times, np.array([1.0, 2.0]), 2)
    assert "note" not in ahead and ahead["per_s"] == pytest.approx(1.0)
