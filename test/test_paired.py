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


def test_a_robot_that_never_meets_the_crowd_changes_nothing(tmp_path):
    """Runs with and without a robot parked far from everyone are paired seed by seed: the
    people's final positions are equal bit for bit, every difference is 0."""
    from distributed import Client, LocalCluster

    from sweep_core.ensemble import run

    scene = {"name": "parked",
             "agents": {"positions": [[1.0, 1.0], [2.0, 1.5]], "radius": 0.25},
             "drift": {"kind": "goal", "goal": [4.0, 1.5], "speed": 0.8},
             "noise": {"sigma": 0.1},
             "walls": [{"kind": "segment", "a": [-1.0, 0.0], "b": [6.0, 0.0]},
                       {"kind": "segment", "a": [-1.0, 3.0], "b": [6.0, 3.0]}],
             "robots": [{"name": "bot", "radius": 0.3, "pose": [-0.5, 2.5, 0.0]}]}
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address=None) as lc, Client(lc) as cl:
        table = run(scene, runs=2, t_end=1.0, dt=0.1, vary={"robots": ["with", "without"]},
                    client=cl, out=tmp_path / "ens", plots=False, line=(3.0, 0.0, 3.0, 3.0))
    assert (table["status"] == "ok").all()
    by = table.set_index(["robots", "seed"])["final_sha256"]
    assert by["with", 0] == by["without", 0] and by["with", 1] == by["without", 1]
    assert by["with", 0] != by["with", 1]  # the seeds differ
    diff = pd.read_csv(tmp_path / "ens" / "paired.csv")
    assert list(diff["seed"]) == [0, 1]
    cols = [c for c in diff if c.endswith(".difference")]
    assert "pressure_mean_m_per_s.difference" in cols
    assert (diff[cols].fillna(0.0) == 0.0).all().all()
    # the robot's own metrics are in the rows with it
    mine = table[table["robots"] == "with"]
    assert mine["robots.bot.frames"].notna().all()
    assert (mine["robots.bot.collided"] == 0.0).all()  # a flag: 1 or 0
