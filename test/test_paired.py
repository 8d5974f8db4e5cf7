"""Paired runs with and without the robots (sweep_core.ensemble.paired): the differences seed
by seed and their summary, against values computed by hand."""
import math

import pandas as pd
import pytest

from sweep_core.ensemble import grid, paired
from sweep_core.errors import SceneError


def table() -> pd.DataFrame:
    rows = []
    # seeds 0, 1, 2; evacuation (flow.t_all_s) with: 10, 12, 14, without: 9, 10, 11;
    # flow per s with: 1.0, 0.9, 0.8, without: 1.1, 1.1, 1.1; seed 3 failed with the robot
    for seed, (tw, to, fw, fo) in enumerate([(10, 9, 1.0, 1.1), (12, 10, 0.9, 1.1),
                                             (14, 11, 0.8, 1.1)]):
        for which, t, f in (("with", tw, fw), ("without", to, fo)):
            rows.append({"point": 0 if which == "with" else 1, "robots": which, "seed": seed,
                         "status": "ok", "flow.t_all_s": float(t), "flow.per_s": f,
                         "reaction.pressure_mean_m_per_s": 0.5 if which == "with" else 0.25})
    rows.append({"point": 0, "robots": "with", "seed": 3, "status": "failed"})
    rows.append({"point": 1, "robots": "without", "seed": 3, "status": "ok",
                 "flow.t_all_s": 8.0, "flow.per_s": 1.0,
                 "reaction.pressure_mean_m_per_s": 0.25})
    return pd.DataFrame(rows)


def test_differences_pair_the_runs_of_each_seed():
    diff = paired.differences(table(), ["robots"])
    assert list(diff["seed"]) == [0, 1, 2]  # seed 3 has no run with the robot
    assert list(diff["evacuation_s.difference"]) == [1.0, 2.0, 3.0]
    assert list(diff["flow_per_s.difference"]) == pytest.approx([-0.1, -0.2, -0.3])
    assert list(diff["pressure_mean_m_per_s.difference"]) == [0.25] * 3
    summ = paired.summary(diff, ["robots"]).set_index("metric")
    ev = summ.loc["evacuation_s"]
    # differences 1, 2, 3: mean 2, sample std 1, half-width 1.96 / sqrt(3)
    assert ev["pairs"] == 3 and ev["mean_difference"] == 2.0 and ev["std"] == 1.0
    assert ev["ci95_low"] == pytest.approx(2.0 - 1.959963984540054 / math.sqrt(3), rel=1e-12)
    assert summ.loc["pressure_mean_m_per_s", "std"] == 0.0


def test_the_robots_key_of_the_grid():
    spec = {"name": "s", "robots": [{"name": "bot"}], "crowd_reaction": {"kind": "avoid"}}
    points = grid.grid(grid.parse_vary(["robots=with,without"]), spec)
    assert paired.is_paired(["robots"], points)
    assert grid.apply(spec, points[0]) == spec
    assert grid.apply(spec, points[1]) == {"name": "s", "robots": []}
    with pytest.raises(SceneError, match="neither with nor without"):
        grid.parse_vary(["robots=with,none"])
    with pytest.raises(SceneError, match="no robots"):
        grid.grid({"robots": ["with", "without"]}, {"name": "s"})
