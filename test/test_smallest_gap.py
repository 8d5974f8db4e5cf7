"""The smallest gap that the simulator, ``sweep run`` and ``sweep analyze`` report is the
smallest over every pair of people and every person and wall, not only over the pairs close
enough to touch (which is all a step's feasibility check searches)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from sweep_core import Scene, Simulator
from sweep_core.analysis.metrics import analyze
from sweep_core.cli import main
from sweep_core.model.gaps import gaps, smallest_gap

BOX = [{"kind": "polyline", "points": [[0, 0], [10, 0], [10, 10], [0, 10]], "closed": True}]


def _brute(q: np.ndarray, r: np.ndarray, box: bool) -> float:
    """Every pair's gap and, in the box, every person's gap to its four sides (numpy)."""
    d = np.hypot(*(q[:, None, :] - q[None, :, :]).transpose(2, 0, 1)) - r[:, None] - r[None, :]
    best = float(d[np.triu_indices(len(q), 1)].min())
    if box:
        best = min(best, float(np.min(np.concatenate([q, 10.0 - q], axis=1) - r[:, None])))
    return best


@pytest.mark.parametrize("box", [False, True])
@pytest.mark.parametrize("n", [2, 7, 80])
def test_smallest_gap_is_the_smallest_over_every_pair_and_wall(box, n):
    rng = np.random.default_rng(n)
    geom = Scene.from_dict({"agents": {"positions": [[5.0, 5.0]], "radius": 0.2},
                            "walls": BOX if box else []}).geometry
    for _ in range(20):
        r = rng.uniform(0.15, 0.3, n)
        # a feasible configuration: n nodes of a 9 x 9 grid 0.9 m apart, each moved by up to
        # 0.1 m (so every pair is at least 0.7 m apart, above 2 max(r))
        nodes = rng.choice(81, n, replace=False)
        q = 1.4 + 0.9 * np.column_stack([nodes % 9, nodes // 9]) + rng.uniform(-0.1, 0.1, (n, 2))
        g = gaps(geom, 0.0, q, r)
        value, pair = smallest_gap(g, q, r)
        assert value == pytest.approx(_brute(q, r, box), abs=1e-12)
        if pair is not None:
            i, j = pair
            assert np.hypot(*(q[i] - q[j])) - r[i] - r[j] == pytest.approx(value, abs=1e-12)


TWO = {"name": "two", "agents": {"positions": [[5, 5], [5.6, 5]], "radius": 0.25},
       "walls": BOX, "drift": {"kind": "none"}, "noise": {"sigma": 0.0}}


def test_the_simulator_reports_the_gap_between_two_people_who_do_not_touch():
    sim = Simulator(Scene.from_dict(TWO), dt=0.05)
    assert sim.min_gap == pytest.approx(0.1, abs=1e-12)  # not 4.15, the gap to a wall
    sim.step(2)
    assert sim.min_gap == pytest.approx(0.1, abs=1e-12)
    assert sim.state.min_gap == sim.min_gap


def test_run_and_analyze_report_it_too(tmp_path):
    scene = tmp_path / "two.yaml"
    scene.write_text(Scene.from_dict(TWO).to_yaml())
    out = tmp_path / "two.mcap"
    assert main(["run", str(scene), "--t-end", "0.1", "--out", str(out), "--quiet"]) == 0
    summary = json.loads(out.with_suffix(".summary.json").read_text())
    assert summary["min_gap_m"] == pytest.approx(0.1, abs=1e-12)
    an = analyze(out)
    assert an.summary["min_gap"]["min_m"] == pytest.approx(0.1, abs=1e-12)
    assert an.summary["min_gap"]["between"] == "agents 0 and 1"
    np.testing.assert_allclose(an.table[:, 2], 0.1, atol=1e-12)
