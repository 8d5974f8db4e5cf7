"""``sweep analyze`` of runs with flows: a speed law, speeds or delays keep the scene's agents,
so arrivals, per-group figures and the per-frame ``arrived`` column are those of a run without
flows (computed from the recorded positions here); with sinks, ``arrived`` counts the agents
that have left by each frame."""
from __future__ import annotations

import copy

import numpy as np
import pytest

from sweep_core import Scene
from sweep_core.analysis.frames import FrameReader
from sweep_core.analysis.metrics import analyze
from sweep_core.analysis.run import load_run
from sweep_core.cli import main

ROOM = [{"kind": "polyline", "points": [[0, 0], [10, 0], [10, 4], [0, 4]], "closed": True}]
GOAL = np.array([8.0, 2.0])


def _scene(flows: dict, groups: bool = False) -> dict:
    scene = {"name": "corridor",
             "agents": {"positions": [[1.0, 1.0], [1.0, 2.0], [2.0, 1.5], [2.0, 3.0]],
                        "radius": 0.2},
             "walls": copy.deepcopy(ROOM),
             "drift": {"kind": "goal", "goal": GOAL.tolist(), "speed": 1.3},
             "noise": {"sigma": 0.05}, "flows": flows}
    if groups:
        scene["agents"]["groups"] = [{"name": "front", "agents": [2, 3],
                                      "drift": scene["drift"]}]
    return scene


def _record(tmp_path, scene: dict) -> tuple:
    path = tmp_path / "s.yaml"
    path.write_text(Scene.from_dict(scene).to_yaml())
    out = tmp_path / "run.mcap"
    assert main(["run", str(path), "--t-end", "9", "--dt", "0.05", "--seed", "2",
                 "--out", str(out), "--quiet"]) == 0
    frames = list(FrameReader(load_run(out)))
    return out, frames


@pytest.mark.parametrize("flows", [{"headway": {}},
                                   {"speeds": {"distribution": "uniform", "min": 1.0,
                                               "max": 1.3}, "delays": [0.0, 0.5, 1.0, 0.2]}])
def test_arrivals_of_a_speed_law_run_are_read_from_its_positions(tmp_path, flows):
    out, frames = _record(tmp_path, _scene(flows, groups=True))
    t0 = frames[0].log_ns
    times = np.array([(fr.log_ns - t0) / 1e9 for fr in frames])
    inside = np.array([np.hypot(*(fr.positions - GOAL).T) <= 0.5 for fr in frames])  # (F, N)
    assert inside.any(axis=0).sum() >= 2  # some arrive within the run
    first = np.where(inside.any(axis=0), times[np.argmax(inside, axis=0)], np.nan)
    an = analyze(out)
    np.testing.assert_array_equal(an.arrival, first)
    arrivals = an.summary["arrivals"]
    assert arrivals["arrived"] == int(np.isfinite(first).sum()) and arrivals["radius_m"] == 0.5
    front = an.summary["per_group"]["front"]
    assert front["agents"] == 2 and front["arrived"] == int(np.isfinite(first[2:]).sum())
    arrived = an.table[:, list(an.COLUMNS).index("arrived")]
    np.testing.assert_array_equal(arrived, inside.cumsum(axis=0).astype(bool).sum(axis=1))


def test_arrived_with_sinks_counts_the_agents_that_left_by_each_frame(tmp_path):
    sink = {"kind": "rectangle", "min": [7.5, 0.0], "max": [10.0, 4.0]}
    out, frames = _record(tmp_path, _scene({"sinks": [sink], "headway": {}}))
    an = analyze(out)
    counts = np.array([len(fr.positions) for fr in frames])
    assert counts[-1] < counts[0]  # some left
    arrived = an.table[:, list(an.COLUMNS).index("arrived")]
    np.testing.assert_array_equal(arrived, counts[0] - counts)
    assert an.summary["arrivals"]["arrived"] == counts[0] - counts[-1]


def test_a_line_that_meets_a_sink_is_refused_and_one_before_it_counts_every_leaver(
        tmp_path, capsys):
    """An agent leaves as its centre enters a sink, so a line on the sink's edge (or in it)
    is never crossed in the recorded frames: its flow would read 0 while agents leave across
    it. Such a line is refused naming the sink; one just before the sink counts every agent
    that left."""
    sink = {"kind": "rectangle", "min": [7.5, 0.0], "max": [10.0, 4.0]}
    out, frames = _record(tmp_path, _scene({"sinks": [sink], "headway": {}}))
    left = len(frames[0].positions) - len(frames[-1].positions)
    assert left > 0
    for line in ("7.5,0,7.5,4", "8,1,9,1", "7,2,7.5,2"):  # on its edge, inside, touching
        assert main(["analyze", str(out), "--line", line, "--no-plots", "--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and f"--line {line}: meets the scene's " \
            "flows.sinks[0] (rectangle [7.5, 0.0] to [10.0, 4.0])" in err and "(fix: " in err
    before = analyze(out, line=(7.4, 0.0, 7.4, 4.0))
    assert before.summary["flow"]["positive"] == left


@pytest.mark.parametrize("flows, words", [
    ({"sinks": [{"kind": "rectangle", "min": [7.5, 0.0], "max": [10.0, 4.0]}]},
     "has sinks or sources: an arrival is an agent leaving at a sink"),
    ({"journeys": [{"legs": [{"goal": [5.0, 2.0]}, {"goal": GOAL.tolist()}]}]},
     "has journeys or exit choices"),
])
def test_an_arrive_radius_that_would_be_ignored_is_refused(tmp_path, capsys, flows, words):
    """With sinks an arrival is leaving at a sink, and with journeys no arrivals are
    reported: a given --arrive-radius would change nothing, so it is refused in one line."""
    out, _ = _record(tmp_path, _scene(flows))
    assert main(["analyze", str(out), "--arrive-radius", "3", "--no-plots", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--arrive-radius 3: the scene " + words in err
    assert "(fix: leave out --arrive-radius)" in err
    assert main(["analyze", str(out), "--no-plots", "--quiet"]) == 0


def test_population_says_how_many_source_agents_were_due_and_still_wait(tmp_path):
    """A source of 60 agents at 50 per second into a 0.6 m square: all are due by 1.2 s, but
    one disk fits at a time, so most wait. The population gives the due count from the
    recorded scene's schedule and the ones still waiting (due minus entered)."""
    source = {"region": {"kind": "rectangle", "min": [0.3, 0.3], "max": [0.9, 0.9]},
              "rate": 50, "count": 60, "radius": 0.2}
    out, frames = _record(tmp_path, _scene({"sources": [source]}))
    seen = set()
    for fr in frames:
        seen.update(int(i) for i in fr.agents["id"])
    entered = len([i for i in seen if i >= 4])
    pop = analyze(out).summary["population"]
    assert pop["entered"] == entered and 0 < entered < 60
    assert pop["due"] == 60 and pop["waiting_at_end"] == 60 - entered
