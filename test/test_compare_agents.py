"""``sweep compare`` of runs whose agents differ: agents in one run only get no distance (the
per-agent table marks where they are), and the note on matching by id says agents enter and
leave only when a scene has sources or sinks."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from sweep_core import Scene
from sweep_core.analysis import compare
from sweep_core.cli import main

ROOM = [{"kind": "polyline", "points": [[0, 0], [10, 0], [10, 4], [0, 4]], "closed": True}]
SINK = {"kind": "rectangle", "min": [8.5, 0.0], "max": [10.0, 4.0]}


def run(tmp: Path, name: str, flows: dict, positions: list[list[float]]) -> Path:
    """A 0.5 s run (dt 0.05) of a corridor with ``flows`` and agents at ``positions``."""
    scene = tmp / f"{name}.yaml"
    scene.write_text(Scene.from_dict({
        "name": name, "agents": {"positions": positions, "radius": 0.2}, "walls": ROOM,
        "drift": {"kind": "goal", "goal": [9.5, 2.0], "speed": 1.3}, "flows": flows,
    }).to_yaml())
    out = tmp / f"{name}.mcap"
    assert main(["run", str(scene), "--t-end", "0.5", "--dt", "0.05", "--seed", "1",
                 "--out", str(out), "--quiet"]) == 0
    return out


THREE = [[1.0, 1.0], [1.0, 2.0], [2.0, 1.5]]


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("compare_agents")
    return {"three": run(d, "three", {"sinks": [SINK]}, THREE),
            "two": run(d, "two", {"sinks": [SINK]}, THREE[:2]),
            "headway": run(d, "headway", {"headway": {}}, THREE),
            "headway2": run(d, "headway2", {"headway": {}}, THREE)}


def test_agents_in_one_run_only_get_no_distance(runs, capsys):
    c = compare.compare(runs["three"], runs["two"])
    assert c.present_in == ["A and B", "A and B", "A"]
    assert np.isfinite(c.per_agent_sup_m[:2]).all() and np.isnan(c.per_agent_sup_m[2])
    assert np.isnan(c.per_agent_t_s[2]) and c.agents_compared == 2
    assert c.sup_agent in (0, 1)
    text = compare.format_comparison(c)
    assert "agents compared    2 (in both runs at a common time); in one run only: 1 in A, " \
           "0 in B" in text
    median = float(np.median(c.per_agent_sup_m[:2]))
    assert f"median {median:.6g} m" in text

    assert main(["compare", str(runs["three"]), str(runs["two"]), "--no-plots", "--quiet"]) == 0
    capsys.readouterr()
    agents_csv = runs["three"].with_name("three_vs_two.agents.csv")
    with open(agents_csv, newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["present_in"] for r in rows] == ["A and B", "A and B", "A"]
    assert rows[2]["sup_distance_m"] == "" and rows[2]["t_of_sup_s"] == ""
    assert float(rows[0]["sup_distance_m"]) == pytest.approx(c.per_agent_sup_m[0])

    assert main(["compare", str(runs["two"]), str(runs["three"]), "--no-plots", "--quiet",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["agents_compared"] == 2 and out["agents_in_one_run"] == {"A": 0, "B": 1}
    assert out["per_agent_sup_m"][2] is None and out["present_in"][2] == "B"


def test_the_id_note_says_agents_enter_and_leave_only_with_sources_or_sinks(runs):
    moving = compare.compare(runs["three"], runs["two"]).notes
    assert moving == ["agents matched by their /agents ids (flows: agents enter and leave)"]
    fixed = compare.compare(runs["headway"], runs["headway2"])
    assert fixed.notes == ["agents matched by their /agents ids"]
    assert fixed.sup_m == 0.0 and fixed.present_in == ["A and B"] * 3


def test_a_time_with_no_agent_in_both_runs_has_no_distance(tmp_path, capsys):
    """Once every agent has left at the sink, no distance is measured: the final distance is
    none (not 0 m), the CSV's rows are empty there, and the sup is over the times with
    agents."""
    near = [[8.3, 1.0], [8.3, 2.5]]  # 0.2 m from the sink: both leave within the 0.5 s
    a = run(tmp_path, "leave_a", {"sinks": [SINK]}, near)
    b = run(tmp_path, "leave_b", {"sinks": [SINK]}, near)
    c = compare.compare(a, b)
    assert np.isnan(c.final_max_m) and np.isnan(c.final_mean_m)
    held = np.isfinite(c.table[:, 1])
    assert held[0] and not held[-1]
    assert c.sup_m == np.nanmax(c.table[:, 1]) and np.isfinite(c.sup_t_s)
    text = compare.format_comparison(c)
    assert f"final distance     none: no agent is in both runs at t = {c.t_last_s:.6g} s" \
        in text
    assert main(["compare", str(a), str(b), "--no-plots", "--quiet"]) == 0
    capsys.readouterr()
    with open(a.with_name("leave_a_vs_leave_b.compare.csv"), newline="") as f:
        rows = list(csv.DictReader(f))
    assert rows[-1]["max_distance_m"] == "" and rows[-1]["mean_distance_m"] == ""
    assert rows[0]["max_distance_m"] != ""
