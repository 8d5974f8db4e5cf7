"""`sweep ensemble` / `sweep_core.ensemble.run`: seeded identity with `sweep run`, the same
table on 1 and 2 workers, a grid, failing runs, resume, an external scheduler, bad input.

Small on purpose: six agents, t_end <= 0.5 s, Dask on 127.0.0.1 only, at most 2 workers."""
from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("distributed")

from distributed import Client, LocalCluster  # noqa: E402

from sweep_core.analysis.frames import FrameReader  # noqa: E402
from sweep_core.analysis.metrics import analyze, parse_line  # noqa: E402
from sweep_core.analysis.run import load_run  # noqa: E402
from sweep_core.cli import main  # noqa: E402
from sweep_core.ensemble import cluster, run, store  # noqa: E402
from sweep_core.ensemble.task import Task, digest, flatten, simulate  # noqa: E402
from sweep_core.errors import SceneError, SweepError  # noqa: E402
from sweep_core.io.recording import read_metadata

SCENE = """
name: small
agents:
  positions: [[0.0, 0.0], [0.6, 0.0], [1.2, 0.0], [0.3, 0.6], [0.9, 0.6], [0.6, 1.2]]
  radius: 0.25
drift: {kind: goal, goal: [3.0, 0.5], speed: 1.0, slow_radius: 0.5}
noise: {sigma: 0.1}
"""
#: two agents between walls 1 m apart: radii 0.4 m growing at `rate` m/s fit until t = 0.1 / rate
CORRIDOR = """
name: corridor
agents: {positions: [[0.5, 0.0], [0.5, 1.0]], radius: 0.4,
         radius_law: {kind: linear, rate: 0.0}}
walls: [{kind: halfplane, normal: [1, 0], offset: 0.0},
        {kind: halfplane, normal: [-1, 0], offset: -1.0}]
noise: {sigma: 0.1}
"""
LINE = "2,-1,2,2"
#: columns that depend on where and how fast a run went, not on what it computed
WHERE = ["wall_time_s", "worker"]


@pytest.fixture(scope="module")
def client():
    """Two single-threaded worker processes on 127.0.0.1, shared by the tests of this module."""
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address="127.0.0.1:0") as lc, Client(lc) as cl:
        yield cl


@pytest.fixture
def scene(tmp_path):
    path = tmp_path / "small.yaml"
    path.write_text(SCENE)
    return path


def last_positions(mcap) -> np.ndarray:
    frames = list(FrameReader(load_run(mcap), agents=False))
    return frames[-1].positions


def test_run_k_is_sweep_run_with_seed0_plus_k(tmp_path, scene, client, capsys):
    out = tmp_path / "ens"
    table = run(scene, runs=3, seed0=5, t_end=0.5, client=client, record="full", out=out,
                line=LINE)
    assert list(table["seed"]) == [5, 6, 7] and list(table["run"]) == [0, 1, 2]
    assert (table["status"] == "ok").all()
    for _, row in table.iterrows():
        mcap = tmp_path / f"run{row['seed']}.mcap"
        assert main(["run", str(scene), "--seed", str(row["seed"]), "--t-end", "0.5",
                     "--out", str(mcap), "--quiet"]) == 0
        q = last_positions(mcap)
        ens_mcap = row["recording"]
        assert ens_mcap.startswith(str(out / "mcap"))
        assert np.array_equal(last_positions(ens_mcap), q)  # the ensemble's own recording
        # recorded by the same code as sweep run's: with its status record
        assert read_metadata(ens_mcap)["sweep_status"]["status"] == "completed"
        assert row["final_sha256"] == digest(q)  # and the row: the same final positions
        metrics = flatten(analyze(mcap, line=parse_line(LINE)).summary)
        assert metrics["flow.net"] >= 0 and "arrivals.t_first_s" in metrics
        for key, value in metrics.items():  # every metric of sweep analyze, bit for bit
            assert (math.isnan(value) and math.isnan(row[key])) or row[key] == value, key
    # run 0 is not run 1: the seeds differ
    assert table["final_sha256"].nunique() == 3
    capsys.readouterr()


def test_same_table_with_one_and_two_workers(tmp_path, scene, client):
    two = run(scene, runs=4, t_end=0.3, client=client, line=LINE)
    assert two["worker"].nunique() == 2  # both workers took runs
    one = run(scene, runs=4, t_end=0.3, workers=1, line=LINE)  # a LocalCluster of its own
    assert one["worker"].nunique() == 1
    pd.testing.assert_frame_equal(one.drop(columns=WHERE), two.drop(columns=WHERE))


def test_grid_over_sigma(tmp_path, scene, client):
    out = tmp_path / "grid"
    table = run(scene, runs=2, t_end=0.5, vary={"noise.sigma": [0.0, 0.1]}, client=client,
                out=out, line="0.7,-1,0.7,2")
    assert list(table["noise.sigma"]) == [0.0, 0.0, 0.1, 0.1]
    assert list(table["point"]) == [0, 0, 1, 1]
    quiet, noisy = table[table["noise.sigma"] == 0.0], table[table["noise.sigma"] == 0.1]
    assert quiet["final_sha256"].nunique() == 1  # no noise: the seed does not matter
    assert noisy["final_sha256"].nunique() == 2
    summary = pd.read_csv(out / "summary.csv")
    gap = summary[summary["metric"] == "min_gap.min_m"]
    assert list(gap["noise.sigma"]) == [0.0, 0.1] and list(gap["completed"]) == [2, 2]
    row = summary[(summary["metric"] == "speed.mean_m_per_s") & (summary["point"] == 1)].iloc[0]
    vals = noisy["speed.mean_m_per_s"]
    half = 1.959963984540054 * vals.std(ddof=1) / math.sqrt(2)
    assert row["mean"] == pytest.approx(vals.mean(), rel=1e-8)
    assert row["ci95_high"] == pytest.approx(vals.mean() + half, rel=1e-8)
    assert pd.read_parquet(out / "runs.parquet").shape[0] == 4
    for png in ("hist_evacuation.png", "hist_min_gap.png", "vs_noise.sigma.png"):
        assert (out / png).stat().st_size > 0


def test_failing_runs_are_rows_and_the_ensemble_completes(tmp_path, client):
    out = tmp_path / "fail"
    table = run(_scene_dict(CORRIDOR), runs=2, t_end=0.3,
                vary={"agents.radius_law.rate": [0.0, 1.0]}, client=client, out=out)
    ok, grown = table[table["point"] == 0], table[table["point"] == 1]
    assert (ok["status"] == "ok").all() and ok["error"].isna().all()
    assert (grown["status"] == "failed").all()
    assert grown["error"].str.startswith("no feasible configuration at t = 0.1 s").all()
    assert list(grown["t_reached_s"]) == pytest.approx([0.09, 0.09])
    assert grown["min_gap.min_m"].isna().all()
    summary = pd.read_csv(out / "summary.csv")
    assert set(zip(summary["point"], summary["completed"], summary["failed"])) == {(0, 2, 0),
                                                                                   (1, 0, 2)}
    # a grid value that makes the scene invalid fails its runs the same way
    bad = run(_scene_dict(CORRIDOR), runs=1, t_end=0.1, vary={"agents.radius": [0.4, 0.7]},
              client=client)
    assert list(bad["status"]) == ["ok", "failed"]
    assert bad["error"].iloc[1].startswith("agents.positions: agents 0 and 1 overlap by 0.400 m")


def _scene_dict(text: str) -> dict:
    import yaml
    return yaml.safe_load(text)


def test_resume_skips_finished_runs(tmp_path, scene, client):
    out = tmp_path / "resume"
    first = run(scene, runs=4, t_end=0.3, client=client, out=out)
    runs_dir = out / "runs"
    files = sorted(runs_dir.glob("*.parquet"))
    assert len(files) == 4
    # as if killed: two runs never finished, one was being written, runs.parquet not yet made
    files[1].unlink()
    files[3].unlink()
    (runs_dir / f".{files[3].stem}.parquet.tmp").write_bytes(b"half a file")
    (out / "runs.parquet").unlink()
    kept = {f.name: f.stat().st_mtime_ns for f in (files[0], files[2])}
    again = run(scene, runs=4, t_end=0.3, client=client, out=out)
    assert {f.name: f.stat().st_mtime_ns for f in (files[0], files[2])} == kept
    assert (runs_dir / files[1].name).exists() and (runs_dir / files[3].name).exists()
    by_seed = first.set_index("seed")["wall_time_s"]
    again_wall = again.set_index("seed")["wall_time_s"]
    seeds = {int(f.stem.rsplit("_s", 1)[1]) for f in (files[0], files[2])}
    for seed in seeds:  # skipped: their rows (wall times) come back from DIR unchanged
        assert again_wall[seed] == by_seed[seed]
    pd.testing.assert_frame_equal(again.drop(columns=WHERE), first.drop(columns=WHERE))
    assert len(pd.read_parquet(out / "runs.parquet")) == 4
    # a run the cluster lost (status lost) is run again; more runs extend the directory
    store.write_row(out, files[0].stem, {"status": "lost", "error": "KilledWorker: x",
                                         "wall_time_s": math.nan})
    lost_seed = int(files[0].stem.rsplit("_s", 1)[1])
    more = run(scene, runs=5, t_end=0.3, client=client, out=out)
    assert list(more["seed"]) == [0, 1, 2, 3, 4] and (more["status"] == "ok").all()
    assert more.set_index("seed")["wall_time_s"].drop([lost_seed, 4]).equals(
        again_wall.drop(lost_seed))
    assert pd.read_parquet(files[0])["status"].iloc[0] == "ok"
    pd.testing.assert_frame_equal(more.drop(columns=WHERE).iloc[:4], first.drop(columns=WHERE))
    # another configuration in the same directory is refused
    with pytest.raises(Exception, match=r"--out: .* another configuration \(t_end differ"):
        run(scene, runs=1, t_end=0.2, client=client, out=out)


def test_external_scheduler_from_the_command_line(tmp_path, scene, capsys):
    out = tmp_path / "ext"
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, protocol="tcp://",
                      host="127.0.0.1",
                      dashboard_address="127.0.0.1:0") as lc:
        code = main(["ensemble", str(scene), "--runs", "2", "--t-end", "0.2", "--scheduler",
                     lc.scheduler_address, "--vary", "dt=0.02,0.01", "--record", "summary",
                     "--out", str(out), "--quiet"])
        captured = capsys.readouterr()
        assert code == 0, captured.err
        assert f"scheduler {lc.scheduler_address}: 1 workers" in captured.err
        assert "runs 4  completed 4  failed 0  lost 0  grid points 2" in captured.out
        # the scheduler is not ours: it still runs after the ensemble
        with Client(lc.scheduler_address) as cl:
            assert len(cl.scheduler_info()["workers"]) == 1
    table = pd.read_parquet(out / "runs.parquet")
    assert list(table["dt"]) == [0.02, 0.02, 0.01, 0.01]
    assert list(table["frames"]) == [11, 11, 21, 21]
    summ = json.loads(table["summary_json"].iloc[0])
    assert summ["dt_s"] == 0.02 and len(list((out / "summaries").glob("*.json"))) == 4


def test_the_bundled_scene_by_name(client):
    table = run("room_door", runs=1, t_end=0.02, client=client)
    assert list(table["status"]) == ["ok"] and list(table["agents"]) == [200]


def test_record_full_needs_the_directory_on_the_worker(tmp_path):
    spec = _scene_dict(SCENE)
    row = simulate(Task(spec=spec, name="small", seed=0, dt=0.01, scheme="projected_euler",
                        t_end=0.1, mcap=str(tmp_path / "r.mcap"),
                        marker=str(tmp_path / "elsewhere" / ".shared-x")))
    assert row["status"] == "failed" and not (tmp_path / "r.mcap").exists()
    assert row["error"].startswith("--record full: the output directory ")
    assert "is not visible on worker" in row["error"] and "fix:" in row["error"]


@pytest.mark.parametrize("args, needle", [
    (["--runs", "0"], "--runs: must be an integer >= 1, got 0"),
    (["--runs", "2", "--t-end", "-1"], "--t-end: must be a positive number, got -1"),
    (["--runs", "2", "--t-end", "0.001"], "--t-end: 0.001 s at dt = 0.01 s is no step"),
    (["--runs", "2", "--t-end", "0.2", "--vary", "dt=0.01,0.5"],
     "--t-end: 0.2 s at dt = 0.5 s is no step"),
    (["--runs", "2", "--workers", "0"], "--workers: 0 is not a positive number"),
    (["--runs", "2", "--vary", "noise.sgima=0.1,0.2"], "--vary: unknown key 'noise.sgima'"),
    (["--runs", "2", "--vary", "noise.sigma=0.1,,0.2"], "--vary: noise.sigma: bad value list"),
    (["--runs", "2", "--vary", "dt=0.01,-1"], "--vary: dt: value -1 is not a positive number"),
    (["--runs", "2", "--vary", "noise.sigma=1e-2,abc"], "--vary: noise.sigma: value 'abc' is "
                                                         "not a number"),
    (["--runs", "2", "--vary", "scheme=euler"], "--vary: scheme: unknown scheme 'euler'"),
    (["--runs", "2", "--scheduler", "localhost"], "--scheduler: 'localhost' is not an address"),
    (["--runs", "2", "--scheduler", "tcp://127.0.0.1:9"], "--scheduler: cannot reach"),
])
def test_bad_input_is_one_line_naming_the_field(tmp_path, scene, capsys, monkeypatch, args,
                                                 needle):
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT", 2)
    code = main(["ensemble", str(scene), "--out", str(tmp_path / "o"), "--quiet",
                 *(args if "--t-end" in args else ["--t-end", "0.1", *args])])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert err.startswith("sweep: error: " + needle), err
    assert "\n" not in err and "fix:" in err and "Traceback" not in err


def test_bench_accuracy_crowd_paths_on_a_cluster_equal_the_local_ones() -> None:
    # the crowd's paths are pure functions of (config, path index): on Dask workers they give
    # the same errors as in-process, in path order
    import dataclasses

    from distributed import Client, LocalCluster

    from sweep_core.bench.accuracy import StudyConfig
    from sweep_core.bench.accuracy_problems import study_crowd

    cfg = dataclasses.replace(StudyConfig.make(True), levels=2, crowd_paths=2, crowd_t=0.16,
                              solver_tols=())
    local = study_crowd(cfg, log=lambda _s: None)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp://",
                      host="127.0.0.1",
                      dashboard_address="127.0.0.1:0") as cluster, Client(cluster) as client:
        remote = study_crowd(cfg, log=lambda _s: None, client=client)
    assert [(m.scheme, m.dt, m.tol) for m in local] == [(m.scheme, m.dt, m.tol) for m in remote]
    for a, b in zip(local, remote):
        assert np.array_equal(a.values, b.values) and a.error == b.error


def test_resume_after_a_real_kill(tmp_path, scene):
    """`sweep ensemble` killed with SIGKILL (its whole process group: the command and its local
    workers) after some runs finished; the same command again runs only the rest, and the
    table equals an uninterrupted ensemble's."""
    import os
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "killed"
    cmd = [sys.executable, "-m", "sweep_core.cli", "ensemble", str(scene), "--runs", "12",
           "--t-end", "0.6", "--workers", "1", "--out", str(out), "--quiet"]
    proc = subprocess.Popen(cmd, start_new_session=True, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 240
        while len(list((out / "runs").glob("*.parquet"))) < 3:
            assert proc.poll() is None and time.monotonic() < deadline, "no runs finished"
            time.sleep(0.05)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    done = {f.name: f.stat().st_mtime_ns for f in (out / "runs").glob("*.parquet")}
    assert 3 <= len(done) < 12, "the kill came too late to test a resume"
    assert not (out / "runs.parquet").exists()
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stdout + again.stderr
    after = {f.name: f.stat().st_mtime_ns for f in (out / "runs").glob("*.parquet")}
    assert len(after) == 12 and all(after[name] == t for name, t in done.items())
    table = pd.read_parquet(out / "runs.parquet")
    assert sorted(table["seed"]) == list(range(12)) and (table["status"] == "ok").all()
    fresh = run(scene, runs=12, t_end=0.6, out=tmp_path / "fresh", workers=1)
    cols = ["seed", "final_sha256"]
    assert table.sort_values("seed")[cols].reset_index(drop=True).equals(
        fresh.sort_values("seed")[cols].reset_index(drop=True))


def test_runs_whose_recording_passes_the_bound_are_refused_before_any_starts(tmp_path):
    """Every run records every step to a temporary file on its worker: 1e4 s of the bundled
    room (200 agents) at dt 0.01 is about 18 GB per run, refused as sweep run refuses it,
    before a cluster is asked for anything (the client here answers nothing: the old code
    reached it)."""
    with pytest.raises(SceneError, match=r"^--t-end: 10000 s at dt = 0.01 s records .* GB "
                                         r"uncompressed on its worker, more than the limit 2 GB"):
        run(None, runs=2, t_end=10000.0, dt=0.01, client=object(), out=tmp_path / "o")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("t_end, vary, dt", [(0.004, None, 0.01),
                                              (0.2, {"dt": [0.001, 0.5]}, 0.5)])
def test_a_t_end_below_half_a_step_is_refused_before_any_run(tmp_path, t_end, vary, dt):
    """A run of round(t_end / dt) steps, none: refused naming --t-end, the time step and the
    shortest --t-end of one step, before a cluster is asked for anything (the client here
    answers nothing) or the folder is made."""
    with pytest.raises(SceneError, match=rf"^--t-end: {t_end:g} s at dt = {dt:g} s is no "
                                         rf"step: .* \(fix: --t-end {dt:g} or more\)$"):
        run(None, runs=2, t_end=t_end, dt=0.01, vary=vary, client=object(), out=tmp_path / "o")
    assert not (tmp_path / "o").exists()


#: a worker's peak resident memory (bytes, Linux's VmHWM)
def _worker_memory() -> int:
    with open("/proc/self/status") as f:
        return next(int(ln.split()[1]) for ln in f if ln.startswith("VmHWM:")) * 1024


def test_a_workers_memory_is_what_the_worker_bound_assumes(client):
    """After runs of the bundled room (200 agents, 1 s) each worker's peak resident memory is
    within 1.5 of cluster.WORKER_BYTES (330 MB; measured 328 MB), the figure --workers is
    bounded by."""
    table = run(None, runs=2, t_end=1.0, dt=0.05, client=client, plots=False)
    assert (table["status"] == "ok").all(), table["error"].tolist()
    peaks = client.run(_worker_memory).values()
    for peak in peaks:
        assert 1 / 1.5 <= cluster.WORKER_BYTES / peak <= 1.5, (cluster.WORKER_BYTES, peaks)


@pytest.mark.parametrize("options, words", [
    ({"line": "13,4,13,6"}, r"^--line 13,4,13,6: meets the scene's flows.sinks\[0\] "),
    ({"arrive_radius": 1.0}, r"^--arrive-radius 1: the scene has sinks or sources"),
])
def test_a_line_in_a_sink_or_an_unused_arrive_radius_is_refused_before_any_run(
        tmp_path, options, words):
    """The bundled room's agents leave at a sink (x 12-15, y 3-7): a line in it would count
    nobody and a radius would not change its arrivals (leaving at the sink). Both are refused
    as sweep analyze refuses them, before a cluster is asked for anything (the client here
    answers nothing) or the folder is made."""
    with pytest.raises(SweepError, match=words):
        run(None, runs=1, t_end=1.0, client=object(), out=tmp_path / "o", **options)
    assert not (tmp_path / "o").exists()
