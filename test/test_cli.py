"""`sweep run`: the recording it writes is read by rosbags and mcap_ros2, the summary is right."""
from __future__ import annotations

import json

import numpy as np
import pytest

import sweep_core as sc
from sweep_core.cli import main
from sweep_core.io import topics
from sweep_core.io.recording import read_metadata

SCENE = """
agents: {positions: [[0.0, 0.0], [0.6, 0.0], [1.2, 0.0]], radius: 0.25}
walls: [{kind: halfplane, normal: [1, 0], offset: -0.5}]
drift: {kind: uniform, velocity: [-1.0, 0.0]}
noise: {sigma: 0.05}
"""


def test_run_records_every_step_and_reports(tmp_path, capsys):
    scene = tmp_path / "s.yaml"
    scene.write_text(SCENE)
    out = tmp_path / "r.mcap"
    assert main(["run", str(scene), "--t-end", "0.5", "--dt", "0.01", "--seed", "4",
                 "--out", str(out), "--quiet"]) == 0
    summary = json.loads(out.with_suffix(".summary.json").read_text())
    assert summary["steps"] == 50 and summary["agents"] == 3
    assert summary["max_overlap_m"] <= 1e-9
    assert summary["backend_agents_max"] == 0  # 3 agents: every cluster solved exactly
    assert "steps_per_s" in capsys.readouterr().out

    # the same run in-process, to compare against the recording
    sim = sc.Simulator(sc.Scene.from_yaml(scene), dt=0.01, seed=4)
    states = [sim.positions]
    sim.run(0.5, callback=lambda s: states.append(s.positions))

    rosbags = pytest.importorskip("rosbags.highlevel")
    with rosbags.AnyReader([out]) as reader:
        conns = {c.topic: c for c in reader.connections}
        assert set(conns) == {"/poses", "/agents", "/walls", "/markers"}
        poses = [reader.deserialize(raw, conns["/poses"].msgtype)
                 for _, _, raw in reader.messages(connections=[conns["/poses"]])]
    assert len(poses) == 51
    for k, msg in enumerate(poses):
        got = np.array([[p.position.x, p.position.y] for p in msg.poses])
        assert np.array_equal(got, states[k])
        assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == round(k * 0.01 * 1e9)

    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    with open(out, "rb") as f:
        clouds = [m for _, _, _, m in make_reader(f, decoder_factories=[DecoderFactory()])
                  .iter_decoded_messages(topics=["/agents"])]
    assert [fl.name for fl in clouds[-1].fields] == list(topics.AGENT_FIELDS)
    meta = read_metadata(out)["sweep_ros"]
    assert meta["seed"] == "4" and float(meta["dt"]) == 0.01
    assert sc.Scene.from_dict(__import__("yaml").safe_load(meta["scene"])).n_agents == 3


def test_bad_scene_is_one_line_error(tmp_path, capsys):
    scene = tmp_path / "bad.yaml"
    scene.write_text("agents: {positions: [[0, 0], [0.1, 0]], radius: 0.25}\n")
    assert main(["run", str(scene), "--out", str(tmp_path / "x.mcap"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "agents.positions: agents 0 and 1 overlap by 0.400 m" in err
    assert "Traceback" not in err


def test_default_scene_runs(tmp_path):
    out = tmp_path / "d.mcap"
    assert main(["run", "--t-end", "0.05", "--out", str(out), "--quiet"]) == 0
    assert json.loads(out.with_suffix(".summary.json").read_text())["agents"] == 200


def _csv_rows(path):
    import csv
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        return reader.fieldnames, list(reader)


def test_bench_speed_writes_finite_numbers(tmp_path, capsys):
    from sweep_core.bench import speed
    out = tmp_path / "speed.csv"
    assert main(["bench", "speed", "--sizes", "50", "--steps", "3", "--warmup", "1",
                 "--scenes", "hex", "disordered", "free", "--backend-qps", "0",
                 "--timeout", "20", "--tols", "1e-3", "--csv", str(out)]) == 0
    printed = capsys.readouterr().out
    names, rows = _csv_rows(out)
    assert tuple(names) == speed.COLUMNS
    assert [(r["N"], r["scene"], float(r["tol"])) for r in rows] == [
        ("50", "hex", 1e-6), ("50", "hex", 1e-3), ("50", "disordered", 1e-6),
        ("50", "disordered", 1e-3), ("50", "free", 1e-6)]
    for r in rows:
        # the certified bound is at most the tolerance wherever every cluster was certified
        assert 0.0 <= float(r["bound_max_m"])
        if float(r["tol"]) != 1e-6:
            continue  # the Pareto rows run without the baselines
        for key in ("floor_median_ms", "step_median_ms", "step_min_ms", "step_max_ms",
                    "step_over_floor", "clarabel_median_ms", "step_over_clarabel"):
            assert np.isfinite(float(r[key])) and float(r[key]) > 0, key
        # proxsuite 0.8.0 may stall on a jam: then the column is n/a and the note says why
        if "proxsuite n/a" not in r["notes"]:
            assert np.isfinite(float(r["proxsuite_median_ms"]))
            assert float(r["proxsuite_max_dist_m"]) >= 0.0
    assert rows[-1]["proxsuite_solved"] == "no QP" and int(rows[-1]["contacts"]) == 0
    measured = [r for r in rows if float(r["tol"]) == 1e-6]
    if speed.cromosim_missing():
        assert "cromosim: skipped" in printed
        assert all(np.isnan(float(r["cromosim_median_ms"])) for r in rows)
    else:
        assert all(np.isfinite(float(r["cromosim_median_ms"])) for r in measured)


def test_bench_speed_evacuation_and_backend_table(tmp_path, capsys):
    """The evacuation scene at a small size: its run columns (p99, max / median, certified
    share, run time) are finite, the same run with mixed radii follows with the ratio of the
    two runs' times, both again at each further tolerance, and the backend table has one row
    per installed backend."""
    from sweep_core.numerics.projection import backends
    out = tmp_path / "speed.csv"
    assert main(["bench", "speed", "--scenes", "evacuation", "--evacuation-sizes", "60",
                 "--evacuation-warmup", "60", "--evacuation-steps", "4", "--backend-qps", "1",
                 "--tols", "1e-4", "--timeout", "20", "--backend-timeout", "20",
                 "--csv", str(out)]) == 0
    _, rows = _csv_rows(out)
    assert [(r["N"], r["scene"], float(r["tol"])) for r in rows] == [
        ("60", "evacuation", 1e-6), ("60", "evacuation_mixed", 1e-6),
        ("60", "evacuation", 1e-4), ("60", "evacuation_mixed", 1e-4)]
    for r in rows:
        for key in ("step_median_ms", "step_p99_ms", "step_max_ms", "max_over_median", "run_s"):
            assert np.isfinite(float(r[key])) and float(r[key]) > 0, key
        assert float(r["step_p99_ms"]) <= float(r["step_max_ms"])
        assert 0.0 <= float(r["certified_share"]) <= 1.0
    printed = capsys.readouterr().out
    for equal, mixed in (rows[:2], rows[2:]):
        assert f"ratio {float(equal['run_s']) / float(mixed['run_s']):.2f}" in printed
    names, table = _csv_rows(tmp_path / "speed_backends.csv")
    assert [t["backend"] for t in table] == backends.available()
    assert "max_dist_m" in names


def test_bench_recording_writes_finite_numbers(tmp_path):
    from sweep_core.bench import recording as recording_bench
    out = tmp_path / "rec.csv"
    assert main(["bench", "recording", "--sizes", "50", "--steps", "3", "--warmup", "1",
                 "--csv", str(out)]) == 0
    names, rows = _csv_rows(out)
    assert tuple(names) == recording_bench.COLUMNS
    assert len(rows) == 1 and rows[0]["N"] == "50"
    for key in recording_bench.COLUMNS[2:]:
        assert np.isfinite(float(rows[0][key])), key
    assert float(rows[0]["record_ms"]) > 0 and float(rows[0]["kB_per_step"]) > 0


GAP_SCENE = """
agents: {positions: [[1.0, 1.0], [1.0, 2.0], [2.0, 1.5]], radius: 0.2}
walls:
  - {kind: polyline, closed: true, points: [[0, 0], [10, 0], [10, 6], [0, 6]]}
  - {kind: segment, a: [5, 0], b: [5, 4.5]}
drift: {kind: geodesic, goal: [8.0, 1.0], speed: 1.3}
"""


def test_run_records_the_navigation_field(tmp_path):
    """A geodesic drift: sweep run records /navigation_field once (latched, as the node
    publishes it): an organised grid whose T is the drift's travel distance at the nodes and
    whose (vx, vy) is the drift there; rosbags and mcap_ros2 read it; replay is identical."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    from sweep_core.io import cdr
    from sweep_core.io.recording import read_recording, scan_recording

    scene = tmp_path / "gap.yaml"
    scene.write_text(GAP_SCENE)
    out = tmp_path / "gap.mcap"
    assert main(["run", str(scene), "--t-end", "0.2", "--dt", "0.01", "--out", str(out),
                 "--quiet"]) == 0
    info = scan_recording(out)
    assert info.channels["/navigation_field"].message_count == 1
    assert "transient_local" in info.channels["/navigation_field"].metadata[
        "offered_qos_profiles"]
    [msg] = read_recording(out, ["/navigation_field"])
    assert msg.log_time_ns == 0
    cloud = cdr.decode_point_cloud2(msg.data)
    assert list(cloud.fields) == list(topics.NAVIGATION_FIELDS)
    drift = sc.Scene.from_yaml(scene).drift
    assert (cloud.height, cloud.width) == (len(drift.y), len(drift.x))
    nodes = np.stack(np.meshgrid(drift.x, drift.y), axis=-1).reshape(-1, 2)
    np.testing.assert_allclose(cloud.fields["x"], nodes[:, 0], rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(cloud.fields["T"], drift.travel_distance(nodes), rtol=1e-6,
                               atol=1e-5)
    v = drift(0.0, nodes)
    np.testing.assert_allclose(cloud.fields["vx"], v[:, 0], atol=1e-6)
    assert set(cloud.fields["group"].tolist()) == {-1.0}
    # round the wall: just left of it, below the gap, the field heads up (+y), not at the goal
    k = int(np.argmin(np.hypot(nodes[:, 0] - 4.5, nodes[:, 1] - 1.0)))
    assert cloud.fields["vy"][k] > 0.9 * 1.3 and abs(cloud.fields["vx"][k]) < 0.3

    rosbags = pytest.importorskip("rosbags.highlevel")
    with rosbags.AnyReader([out]) as reader:
        conn = next(c for c in reader.connections if c.topic == "/navigation_field")
        [(_, _, raw)] = list(reader.messages(connections=[conn]))
        back = reader.deserialize(raw, conn.msgtype)
        assert (back.height, back.width) == (cloud.height, cloud.width)
        assert [f.name for f in back.fields] == list(topics.NAVIGATION_FIELDS)
    with open(out, "rb") as f:
        [decoded] = [m for _, _, _, m in make_reader(f, decoder_factories=[DecoderFactory()])
                     .iter_decoded_messages(topics=["/navigation_field"])]
    assert decoded.row_step == decoded.point_step * decoded.width
    assert main(["replay", str(out)]) == 0


def test_run_records_the_navigation_field_again_each_update_period(tmp_path):
    """A pillar that moves and update_every 0.1 s: /navigation_field is recorded with the first
    state of each period (t = 0, 0.1, 0.2, 0.3 s), each time the field of that period."""
    from sweep_core.io import cdr
    from sweep_core.io.recording import read_recording

    scene = tmp_path / "moving.yaml"
    scene.write_text(GAP_SCENE.replace(
        "drift: {kind: geodesic, goal: [8.0, 1.0], speed: 1.3}",
        "obstacles: [{kind: circle, center: [7.0, 2.5], radius: 0.5, velocity: [0.0, 2.0]}]\n"
        "drift: {kind: geodesic, goal: [8.0, 1.0], speed: 1.3, update_every: 0.1}"))
    out = tmp_path / "moving.mcap"
    assert main(["run", str(scene), "--t-end", "0.35", "--dt", "0.01", "--out", str(out),
                 "--quiet"]) == 0
    msgs = read_recording(out, ["/navigation_field"])
    assert [m.log_time_ns for m in msgs] == [topics.stamp_ns(t) for t in (0.0, 0.1, 0.2, 0.3)]
    drift = sc.Scene.from_yaml(scene).drift
    nodes = np.stack(np.meshgrid(drift.x, drift.y), axis=-1).reshape(-1, 2)
    previous = None
    for m, t in zip(msgs, (0.0, 0.1, 0.2, 0.3)):
        got = cdr.decode_point_cloud2(m.data).fields["T"]
        np.testing.assert_allclose(got, drift.travel_distance(nodes, t), rtol=1e-6, atol=1e-5)
        assert previous is None or np.max(np.abs(got - previous)) > 0.1  # the pillar moved
        previous = got
