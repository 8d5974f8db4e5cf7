"""`sweep analyze`: every metric against values computed directly from the engine's states.

The recordings are made here with `sweep run`; the same seeded run is repeated in-process
(bit-identical, see test_cli) to get the engine's State objects. The reference values below
are computed from those states by brute force (all pairs, all walls), independently of
sweep_core.analysis.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

import sweep_core as sc
from sweep_core.analysis import metrics as analysis
from sweep_core.cli import main

DT, SEED, T_END = 0.01, 7, 3.0
LINE = (1.0, -1.0, 1.0, 3.0)       # vertical, positive direction +x
GOAL = np.array([3.0, 0.75])
ARRIVE = 0.8
SCENE = {
    "name": "corridor_goal",
    "agents": {"positions": [[x, y] for x in (0.0, 0.5) for y in (0.0, 0.5, 1.0, 1.5)],
               "radius": 0.2, "radius_law": {"kind": "sine", "amplitude": 0.01, "period": 1.0}},
    "walls": [{"kind": "halfplane", "normal": [0, 1], "offset": -0.5},
              {"kind": "segment", "a": [-1.0, 2.2], "b": [4.0, 2.2]}],
    "obstacles": [{"kind": "circle", "center": [1.6, 0.75], "radius": 0.3}],
    "drift": {"kind": "goal", "goal": GOAL.tolist(), "speed": 1.3, "slow_radius": 0.5},
    "noise": {"sigma": 0.05},
}


def _states(scene_path: Path) -> list[sc.State]:
    sim = sc.Simulator(sc.Scene.from_yaml(scene_path), dt=DT, seed=SEED)
    states = [sim.state]
    sim.run(T_END, callback=lambda s: states.append(s.state))
    return states


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    d = tmp_path_factory.mktemp("analyze")
    scene = d / "corridor.yaml"
    scene.write_text(yaml.safe_dump(SCENE))
    out = d / "run.mcap"
    assert main(["run", str(scene), "--t-end", str(T_END), "--dt", str(DT), "--seed", str(SEED),
                 "--out", str(out), "--quiet"]) == 0
    return out, _states(scene), sc.Scene.from_yaml(scene)


def _brute_gaps(scene: sc.Scene, st: sc.State) -> np.ndarray:
    """Every constraint value at a state, from the scene's raw parameters (float64)."""
    q, r = st.positions, scene.radii(st.t)
    i, j = np.triu_indices(len(q), 1)
    pair = np.linalg.norm(q[i] - q[j], axis=1) - r[i] - r[j]
    floor = q[:, 1] - (-0.5) - r                       # halfplane y >= -0.5
    ceiling = 2.2 - q[:, 1] - r                         # segment y = 2.2, x in [-1, 4]
    x_out = np.clip(q[:, 0], -1.0, 4.0) - q[:, 0]
    ceiling = np.where(x_out == 0, ceiling, np.hypot(x_out, 2.2 - q[:, 1]) - r)
    disk = np.linalg.norm(q - [1.6, 0.75], axis=1) - 0.3 - r
    return np.concatenate([pair, floor, ceiling, disk])


def test_every_metric_matches_the_engine(run):
    out, states, scene = run
    an = analysis.analyze(out, line=LINE, arrive_radius=ARRIVE)
    s, tab = an.summary, an.table
    n, frames = scene.n_agents, len(states)
    assert (s["agents"], s["frames"], s["last_step"]) == (n, frames, frames - 1)
    assert s["duration_s"] == pytest.approx(T_END, abs=1e-9) and not s["truncated"]
    assert np.allclose(tab[:, 0], [st.t for st in states], atol=1e-9)

    # minimum gap: the engine's own State.min_gap, bit for bit (float64 poses, scene radii)
    assert np.array_equal(tab[:, 2], [st.min_gap for st in states])
    brute = [_brute_gaps(scene, st) for st in states]
    assert s["min_gap"]["min_m"] == pytest.approx(min(float(g.min()) for g in brute), abs=1e-12)
    assert s["min_gap"]["min_m"] >= -1e-9

    # contacts: constraints within 1e-6 m, all pairs and walls by brute force
    contacts = np.array([np.count_nonzero(g <= analysis.CONTACT_TOL) for g in brute])
    assert contacts.max() > 0, "the scene must make contacts for this test to mean anything"
    assert np.array_equal(tab[:, 3], contacts)
    assert s["contacts"]["max"] == contacts.max()
    assert s["contacts"]["mean"] == pytest.approx(contacts.mean())

    # reaction (float32 in the recording): sum of |prediction - result| per frame
    react = np.array([np.linalg.norm(st.reaction, axis=1).sum() for st in states])
    assert react.max() > 0
    assert np.allclose(tab[:, 4], react, rtol=1e-6, atol=1e-7)
    assert np.allclose(tab[:, 5], react / DT, rtol=1e-6, atol=1e-5)

    # speeds: each agent's displacement between the states n = 31 steps either side (the
    # nearest to t -+ 0.625 / 2 s), one-sided where the run starts or ends within that
    assert s["speed"]["window_s"] == 0.625
    q = np.array([st.positions for st in states])
    k = np.arange(len(q))
    m = 31
    a, b = np.where(k >= m, k - m, k), np.where(k + m < len(q), k + m, k)
    v = np.linalg.norm(q[b] - q[a], axis=2) / ((b - a) * DT)[:, None]
    assert np.allclose(tab[:, 6], v.mean(axis=1), rtol=1e-9)
    assert np.allclose(tab[:, 7], v.max(axis=1), rtol=1e-9)
    assert s["speed"]["mean_m_per_s"] == pytest.approx(v.mean(), rel=1e-9)
    assert s["speed"]["max_m_per_s"] == pytest.approx(v.max(), rel=1e-9)
    assert s["speed"]["samples"] == v.size
    for p in (10, 50, 90):
        ref = np.quantile(v, p / 100, method="inverted_cdf")
        assert abs(s["speed"][f"p{p}_m_per_s"] - ref) <= analysis.SPEED_BIN / 2 + 1e-6

    # flow through x = 1: sign changes of x - 1 between consecutive states
    x = np.array([st.positions[:, 0] for st in states])
    up = (x[:-1] < 1.0) & (x[1:] >= 1.0)
    down = (x[:-1] >= 1.0) & (x[1:] < 1.0)
    net = np.concatenate([[0], np.cumsum(up.sum(1) - down.sum(1))])
    assert net[-1] > 0
    assert np.array_equal(tab[:, 8], net)
    fl = s["flow"]
    assert (fl["net"], fl["positive"], fl["negative"]) == (net[-1], up.sum(), down.sum())
    t = np.array([st.t for st in states])
    # the flow: positive crossings after the first over the time from the first to the last
    times = np.sort(np.repeat(t[1:], up.sum(1)))
    assert fl["per_s"] == pytest.approx((len(times) - 1) / (times[-1] - times[0]))
    assert fl["width_m"] == pytest.approx(4.0)
    assert fl["reference"]["note"].startswith("no reference: the line is 4 m wide")
    first_up = [t[1:][up[:, i]].min() if up[:, i].any() else np.nan for i in range(n)]
    assert np.allclose(np.sort(an.evacuation), np.sort(first_up), equal_nan=True)
    assert fl["evacuated"] == np.count_nonzero(np.isfinite(first_up))
    assert fl["t_first_s"] == pytest.approx(np.nanmin(first_up))

    # arrivals within ARRIVE of the goal
    d = np.array([np.linalg.norm(st.positions - GOAL, axis=1) for st in states])
    arrived = np.array([t[d[:, i] <= ARRIVE].min() if (d[:, i] <= ARRIVE).any() else np.nan
                        for i in range(n)])
    assert np.isfinite(arrived).sum() >= 2
    assert np.allclose(an.arrival, arrived, equal_nan=True)
    ar = s["arrivals"]
    assert ar["arrived"] == np.isfinite(arrived).sum() and ar["radius_m"] == ARRIVE
    assert ar["t_first_s"] == pytest.approx(np.nanmin(arrived))
    assert ar["t_mean_s"] == pytest.approx(np.nanmean(arrived))
    done = np.sort(arrived[np.isfinite(arrived)])
    assert ar["t_50_s"] == (pytest.approx(done[3]) if len(done) >= 4 else None)
    assert np.array_equal(tab[:, 9], (d <= ARRIVE).cumsum(0).clip(0, 1).sum(1))

    # density: time-averaged centres per m^2, per 0.5 m cell
    cell = s["density"]["cell_m"]
    pts = np.concatenate([st.positions for st in states])
    assert an.density.sum() * cell**2 == pytest.approx(n)
    x0, y0 = an.density_origin
    ix, iy = np.floor(pts[:, 0] / cell).astype(int), np.floor(pts[:, 1] / cell).astype(int)
    ref = np.zeros_like(an.density)
    np.add.at(ref, (iy - round(y0 / cell), ix - round(x0 / cell)), 1.0 / (frames * cell**2))
    assert np.allclose(an.density, ref)


def test_default_arrival_radius_is_the_goal_slow_radius(run):
    out, states, _ = run
    an = analysis.analyze(out)
    assert an.summary["arrivals"]["radius_m"] == 0.5 and an.summary["flow"] is None
    d = np.array([np.linalg.norm(st.positions - GOAL, axis=1) for st in states])
    assert an.summary["arrivals"]["arrived"] == np.count_nonzero((d <= 0.5).any(axis=0))


def test_cli_writes_csv_png_and_json(run, capsys):
    out, states, _ = run
    assert main(["analyze", str(out), "--line", ",".join(map(str, LINE)), "--json",
                 "--quiet"]) == 0
    summary = json.loads(capsys.readouterr().out)
    files = summary["outputs"]
    assert Path(files["csv"]) == out.with_name("run.analysis.csv")
    png = Path(files["png"])
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size < 300_000
    rows = np.genfromtxt(files["csv"], delimiter=",", names=True)
    assert rows.dtype.names == analysis.Analysis.COLUMNS
    assert len(rows) == len(states)
    assert np.array_equal(rows["min_gap_m"], [st.min_gap for st in states])
    dens = np.genfromtxt(files["density_csv"], delimiter=",", names=True)
    assert dens["agents_per_m2"].sum() * 0.25 == pytest.approx(len(states[0].positions))
    assert summary["flow"]["net"] > 0 and summary["truncated"] is False

    assert main(["analyze", str(out), "--quiet", "--no-plots"]) == 0
    text = capsys.readouterr().out
    assert "min_gap.min_m" in text and "speed.p50_m_per_s" in text
    assert main(["analyze", str(out), "--line", "1,2,3"]) == 2
    assert "--line" in capsys.readouterr().err


def test_record_every_k_analyses_recorded_steps_only(tmp_path, run):
    _, states, _ = run
    scene = tmp_path / "s.yaml"
    scene.write_text(yaml.safe_dump(SCENE))
    out = tmp_path / "k3.mcap"
    assert main(["run", str(scene), "--t-end", str(T_END), "--dt", str(DT), "--seed", str(SEED),
                 "--out", str(out), "--quiet", "--record-every", "3"]) == 0
    an = analysis.analyze(out, line=LINE)
    kept = states[::3]
    assert an.summary["frames"] == len(kept) and an.meta.record_every == 3
    assert np.array_equal(an.table[:, 1], [st.step for st in kept])
    assert np.array_equal(an.table[:, 2], [st.min_gap for st in kept])
    x = np.array([st.positions[:, 0] for st in kept])
    up = ((x[:-1] < 1.0) & (x[1:] >= 1.0)).sum()
    down = ((x[:-1] >= 1.0) & (x[1:] < 1.0)).sum()
    assert an.summary["flow"]["net"] == up - down


def _prefix_rows_match(short: analysis.Analysis, full: analysis.Analysis) -> None:
    k = short.summary["frames"]
    assert 0 < k < full.summary["frames"]
    assert np.array_equal(short.table[:, :4], full.table[:k, :4])


def test_cut_recording_is_read_to_its_last_complete_chunk(tmp_path, run, capsys):
    """A file whose tail is cut off (as a killed writer leaves it)."""
    _, states, scene = run
    from sweep_core.io import topics
    from sweep_core.io.metadata import run_metadata
    from sweep_core.io.recording import Recorder
    full = tmp_path / "full.mcap"
    sim = sc.Simulator(scene, dt=DT, seed=SEED)
    with Recorder(full, metadata=run_metadata(scene, sim, T_END, 1), chunk_size=4096,
                  flush_interval_s=None) as rec:
        for name, msgtype in topics.TYPES.items():
            rec.add_channel("/" + name, msgtype)
        for st in states:
            for name, data in topics.encode_state(st).items():
                rec.write("/" + name, topics.stamp_ns(st.t), data)
    data = full.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    whole = analysis.analyze(full)
    part = analysis.analyze(cut)
    assert part.summary["truncated"] and part.summary["read_until"]
    _prefix_rows_match(part, whole)
    assert main(["analyze", str(cut), "--quiet", "--no-plots"]) == 0
    assert "truncated recording: read up to its last complete chunk" in capsys.readouterr().out


def test_sigkilled_sweep_run_is_analysed(tmp_path):
    """`sweep run` killed with SIGKILL mid-run: what reached the disk is analysed. The run is
    far longer than the test (500 000 steps), so that no machine finishes it before the kill."""
    scene = tmp_path / "s.yaml"
    scene.write_text(yaml.safe_dump(SCENE))
    out = tmp_path / "killed.mcap"
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    proc = subprocess.Popen([sys.executable, "-m", "sweep_core.cli", "run", str(scene),
                             "--t-end", "5000", "--seed", str(SEED), "--out", str(out), "--quiet"],
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not (out.exists() and out.stat().st_size > 20_000):
            time.sleep(0.2)  # the first chunk reached the disk
        time.sleep(1.2)  # and a second one (chunks are flushed at least once a second)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    an = analysis.analyze(out)
    assert an.summary["truncated"] and an.summary["frames"] > 10
    states = _states_until(scene, int(an.table[-1, 1]))
    assert np.array_equal(an.table[:, 2], [st.min_gap for st in states])
    from sweep_core.analysis import replay
    res = replay.replay(out)
    assert res.identical and res.truncated and res.frames_compared == an.summary["frames"]


def _states_until(scene_path: Path, last_step: int) -> list[sc.State]:
    sim = sc.Simulator(sc.Scene.from_yaml(scene_path), dt=DT, seed=SEED)
    states = [sim.state]
    for _ in range(last_step):
        sim.step()
        states.append(sim.state)
    return states


def test_line_crossing_directions_and_ends():
    line = (0.0, 0.0, 0.0, 1.0)  # x = 0 for y in [0, 1], positive towards +x
    p0 = np.array([[-1, 0.5], [1, 0.5], [-1, 2.0], [-1, 0.5], [0.0, 0.5], [-1, -0.5],
                   [-1, 0.5], [0.0, 0.5]], float)
    p1 = np.array([[1, 0.5], [-1, 0.5], [1, 2.0], [-0.5, 0.5], [-1, 0.5], [1, 1.5],
                   [0.0, 0.5], [1.0, 0.5]], float)
    # a point on the line is on its positive side: reaching it counts, leaving it does not
    assert analysis.line_crossings(p0, p1, line).tolist() == [1, -1, 0, 0, -1, 1, 1, 0]
