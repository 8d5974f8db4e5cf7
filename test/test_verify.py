"""``sweep verify --quick`` (the fast RiMEA tests pass; a corner with a gap in its wall fails
them) and ``sweep export --pedpy`` (a recording with agents leaving, read back by PedPy)."""
from __future__ import annotations

import numpy as np
import pytest

from sweep_core.cli import main
from sweep_core.model.yaml_files import dump_yaml, load_yaml
from sweep_core.verify.base import scene_text

pedpy = pytest.importorskip("pedpy")

FAST = ["rimea1", "rimea6", "rimea10"]


def _lines(out: str) -> dict[str, str]:
    return {ln.split()[0]: ln for ln in out.splitlines() if ln.startswith("rimea")}


def test_quick_passes(tmp_path, capsys):
    rc = main(["verify", "--quick", "--tests", *FAST, "--out", str(tmp_path / "rep")])
    out = capsys.readouterr().out
    lines = _lines(out)
    assert sorted(lines) == sorted(FAST), out
    for name in FAST:
        assert lines[name].split()[1] == "PASS", lines[name]
    assert rc == 0
    assert "criterion 26-34 s" in lines["rimea1"]
    summary = (tmp_path / "rep" / "summary.csv").read_text().splitlines()
    assert summary[0].startswith("test,status") and len(summary) == 1 + len(FAST)
    assert (tmp_path / "rep" / "rimea6_corner_trajectories.png").stat().st_size > 0


def test_corner_with_gap_fails(tmp_path, capsys):
    """A 2 m gap in the inner wall of the first corridor: the shortest way to the exit leaves
    the corridors through it, and test 6 must say FAIL with exit status 1."""
    spec = load_yaml(scene_text("rimea06_corner"))
    inner = spec["walls"][0]
    assert inner["points"][:2] == [[0.0, 2.0], [10.0, 2.0]]
    spec["walls"][0] = {"kind": "polyline", "points": [[6.0, 2.0], [10.0, 2.0], [10.0, 14.0]]}
    spec["walls"].append({"kind": "segment", "a": [0.0, 2.0], "b": [4.0, 2.0]})
    folder = tmp_path / "scenes"
    folder.mkdir()
    (folder / "rimea06_corner.yaml").write_text(dump_yaml(spec))
    rc = main(["verify", "--quick", "--tests", "rimea6", "--scenes", str(folder),
               "--no-report"])
    line = _lines(capsys.readouterr().out)["rimea6"]
    assert rc == 1
    assert line.split()[1] == "FAIL", line
    outside = float(line.split("| ")[2].split()[0])  # the mean count of people outside
    assert outside > 0, line
    # the failing seeds name the condition that failed, with the count
    assert "FAILED seed 0: " in line and "people left the corridors" in line, line


def test_unknown_test_is_refused(capsys):
    assert main(["verify", "--quick", "--tests", "rimea99"]) == 2
    err = capsys.readouterr().err
    assert "--tests: 'rimea99' is not a test" in err and "rimea1" in err


def test_export_pedpy_keeps_ids(tmp_path, capsys):
    """Three agents in a corridor, the front one leaves at a sink: PedPy reads the export
    with the recording's frame rate, every id, and the leaver's rows ending when it left."""
    scene = {
        "agents": {"positions": [[3.0, 1.0], [1.5, 1.0], [0.5, 1.0]], "radius": 0.2},
        "walls": [{"kind": "polyline", "points": [[8.0, 0.0], [0.0, 0.0], [0.0, 2.0],
                                                    [8.0, 2.0]]}],
        "drift": {"kind": "uniform", "velocity": [1.0, 0.0]},
        "flows": {"sinks": [{"kind": "rectangle", "min": [4.0, 0.0], "max": [8.0, 2.0]}]},
    }
    path = tmp_path / "s.yaml"
    path.write_text(dump_yaml(scene))
    rec = tmp_path / "run.mcap"
    assert main(["run", str(path), "--t-end", "3", "--dt", "0.05", "--record-every", "2",
                 "--out", str(rec), "--quiet"]) == 0
    out = tmp_path / "traj.txt"
    assert main(["export", str(rec), "--pedpy", str(out)]) == 0
    data = pedpy.load_trajectory_from_txt(trajectory_file=out)
    assert data.frame_rate == pytest.approx(10.0)
    df = data.data
    assert sorted(set(df["id"])) == [0, 1, 2]
    # agent 0 starts 1 m before the sink and walks 1 m/s: it is gone after t = 1 s
    last0 = df[df["id"] == 0]["frame"].max() / data.frame_rate
    assert 0.8 <= last0 < 1.05
    assert df[df["id"] == 2]["frame"].max() == df["frame"].max()
    first = df[df["frame"] == 0].sort_values("id")
    np.testing.assert_allclose(first[["x", "y"]].to_numpy(),
                               [[3.0, 1.0], [1.5, 1.0], [0.5, 1.0]], atol=1e-6)
    assert "3 agents" in capsys.readouterr().out


def test_pedpy_measurements_on_exact_trajectories():
    """Agents walking at 1 m/s through a line, one every 0.5 s: PedPy's crossings give the
    flow 2/s exactly; the classic density of a 2 m x 2 m area holding k of them is k / 4."""
    from sweep_core.analysis.pedpy_export import Trajectories, classic_density, line_flow

    rate = 10.0  # frames per second
    frames = []
    for k in range(60):
        t = k / rate
        ids = np.arange(8)
        x = t - 0.5 * ids - 0.05  # agent i is at x = 0 at t = 0.5 i + 0.05
        frames.append((k, ids, np.column_stack([x, np.zeros(8)])))
    traj = Trajectories.from_frames(frames, rate)
    flow = line_flow(traj, [(0.0, -1.0), (0.0, 1.0)])
    assert flow["crossed"] == 8
    assert flow["flow"] == pytest.approx(2.0)
    assert flow["first_s"] == pytest.approx(0.1)  # the first frame beyond the line
    dens = classic_density(traj, [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)])
    inside = [int(np.sum(np.abs(q[:, 0]) <= 1.0)) for _, _, q in frames]
    np.testing.assert_allclose(dens, np.asarray(inside) / 4.0)


def test_dask_gives_the_in_process_values():
    """The same seeds on a Dask client (in-process transport) and here: the same verdicts."""
    distributed = pytest.importorskip("distributed")
    from sweep_core.verify import TESTS
    from sweep_core.verify.runner import verify

    tests = [TESTS["rimea1"]]
    here = verify(tests, [0, 1], True, None, say=lambda _text: None)
    with distributed.LocalCluster(processes=False, n_workers=1, threads_per_worker=1,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        there = verify(tests, [0, 1], True, None, client=client, say=lambda _text: None)
    assert here[0][1].values == there[0][1].values
    assert here[0][1].status == there[0][1].status == "PASS"


def test_a_bad_replaced_scene_is_refused_in_one_line(tmp_path, capsys):
    folder = tmp_path / "scenes"
    folder.mkdir()
    (folder / "rimea01_corridor.yaml").write_text("agents: {positions: [[0, 1]], radius: -1}\n")
    assert main(["verify", "--quick", "--tests", "rimea1", "--scenes", str(folder),
                 "--no-report"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) >= 1 and "agents.radius" in err[-1] and err[-1].startswith("sweep: error")


def test_exit_choice_test_fails_when_nobody_chooses(tmp_path, capsys):
    """Test 11 without its exit choice: everyone walks to the nearer exit 1, exit 2 stays
    unused, and the test must say FAIL with exit status 1."""
    spec = load_yaml(scene_text("rimea11_exits"))
    del spec["flows"]["exit_choice"]
    folder = tmp_path / "scenes"
    folder.mkdir()
    (folder / "rimea11_exits.yaml").write_text(dump_yaml(spec))
    rc = main(["verify", "--quick", "--tests", "rimea11", "--seeds", "1", "--scenes",
               str(folder), "--no-report"])
    line = _lines(capsys.readouterr().out)["rimea11"]
    assert rc == 1
    assert line.split()[1] == "FAIL", line
    assert "exit 2 used by 0-0 people" in line


def test_experimental_line_is_the_least_squares_line_of_both_experiments():
    from sweep_core.verify.diagrams import WIDTHS, experimental_line, experiments
    pts = [(s, w, j) for s, w, j in experiments() if WIDTHS[0] <= w <= WIDTHS[-1]]
    assert {s for s, _, _ in pts} == {"seyfried2009", "kretz2006"}
    a, b = experimental_line()
    res = np.array([j - (a + b * w) for _, w, j in pts])
    ws = np.array([w for _, w, _ in pts])
    # the normal equations of the fit: residuals orthogonal to 1 and to w
    assert abs(res.sum()) < 1e-12 and abs((res * ws).sum()) < 1e-12
    # and no other line fits better: moving a or b raises the squared residuals
    base = (res ** 2).sum()
    for da, db in ((1e-3, 0.0), (-1e-3, 0.0), (0.0, 1e-3), (0.0, -1e-3)):
        moved = np.array([j - (a + da + (b + db) * w) for _, w, j in pts])
        assert (moved ** 2).sum() > base


def test_bottleneck_verdict_judges_each_seed_against_the_line():
    from sweep_core.verify.diagrams import WIDTHS, judge_flows, line_flow_at, seyfried
    line = {w: line_flow_at(w) for w in WIDTHS}
    # seed 0 just inside at both ends, seed 1 16 % over at 1.0 m, seed 2 a failed run, seed 3
    # exactly Seyfried's points
    factors = [{0.8: 1.14, 1.0: 1.0, 1.2: 0.86}, {0.8: 1.0, 1.0: 1.16, 1.2: 1.0}]
    headway = {w: [line[w] * f[w] for f in factors] + [float("nan"), seyfried(w)]
               for w in WIDTHS}
    pure = {w: [3.0 * line[w]] * 4 for w in WIDTHS}
    verdict = judge_flows({"headway": headway, "pure": pure})
    assert verdict.passed[:3] == [True, False, False]
    assert verdict.values[0] == pytest.approx(0.14) and verdict.values[1] == pytest.approx(0.16)
    assert verdict.status == "FAIL"
    # Seyfried's own points are judged against the line, and their own departure is reported
    assert verdict.values[3] == pytest.approx(max(abs(seyfried(w) / line[w] - 1)
                                                  for w in WIDTHS))
    assert "from Seyfried 2009 alone" in verdict.notes and "0.0-" in verdict.notes
    ok = judge_flows({"headway": {w: [line[w]] for w in WIDTHS},
                      "pure": {w: [line[w]] for w in WIDTHS}})
    assert ok.status == "PASS" and ok.values == [pytest.approx(0.0)]


def test_a_test_named_twice_runs_once(capsys):
    """Before: ``--tests rimea1 rimea1`` ran its cases twice and printed two lines."""
    rc = main(["verify", "--quick", "--tests", "rimea1", "rimea1", "--seeds", "1",
               "--no-report", "--in-process"])
    captured = capsys.readouterr()
    assert rc == 0
    assert [ln.split()[0] for ln in captured.out.splitlines()
            if ln.startswith("rimea")] == ["rimea1"], captured.out
    assert "1 of 1 runs done" in captured.err, captured.err
