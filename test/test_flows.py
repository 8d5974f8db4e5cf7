"""Flows (scene key ``flows``): per-agent speeds, start delays, sinks, sources, journeys and
the headway law; ids kept through recording, analysis, replay and compare."""
from __future__ import annotations

import copy

import numpy as np
import pytest

from sweep_core import Scene, SceneError, Simulator
from sweep_core.analysis import compare, replay
from sweep_core.analysis.frames import FrameReader
from sweep_core.analysis.metrics import analyze
from sweep_core.analysis.run import load_run
from sweep_core.cli import main
from sweep_core.model.speed_law import DEFAULT_TIME_GAP
from sweep_core.numerics.headway import headway

ROOM = [{"kind": "polyline", "points": [[0, 0], [10, 0], [10, 4], [0, 4]], "closed": True}]


def corridor(flows: dict | None, sigma: float = 0.0, positions=None) -> dict:
    scene = {"name": "corridor",
             "agents": {"positions": positions or [[1.0, 1.0], [1.0, 2.0], [2.0, 1.5]],
                        "radius": 0.2},
             "walls": copy.deepcopy(ROOM),
             "drift": {"kind": "goal", "goal": [9.5, 2.0], "speed": 1.3},
             "noise": {"sigma": sigma}}
    if flows is not None:
        scene["flows"] = flows
    return scene


SOURCE = {"region": {"kind": "rectangle", "min": [0.3, 0.3], "max": [1.5, 3.7]},
          "rate": 2.0, "count": 6}
SINK = {"kind": "rectangle", "min": [8.5, 0.0], "max": [10.0, 4.0]}
FULL = {"speeds": {"distribution": "normal", "mean": 1.34, "std": 0.26, "min": 0.46,
                   "max": 1.61},
        "delays": [0.0, 0.5, 1.0], "sinks": [SINK], "sources": [SOURCE],
        "headway": {"time_gap": 0.5}}


@pytest.mark.parametrize("flows, field", [
    ({"speeds": [1.0, 2.0]}, "flows.speeds"),
    ({"speeds": -1.0}, "flows.speeds"),
    ({"speeds": {"distribution": "gamma", "min": 1, "max": 2}}, "flows.speeds.distribution"),
    ({"speeds": {"distribution": "normal", "mean": 3.0, "std": 0.1, "min": 1, "max": 2}},
     "flows.speeds.mean"),
    ({"speeds": {"distribution": "uniform", "min": 2, "max": 1}}, "flows.speeds.max"),
    ({"delays": [0, 1, -1]}, "flows.delays"),
    ({"sinks": [{"kind": "rectangle", "min": [1, 1], "max": [0, 2]}]}, "flows.sinks[0]"),
    ({"sinks": {"kind": "rectangle"}}, "flows.sinks"),
    ({"sources": [{"region": SOURCE["region"]}]}, "flows.sources[0]"),
    ({"sources": [{"region": SOURCE["region"], "rate": 1.0}]}, "flows.sources[0].count"),
    ({"sources": [{"region": SOURCE["region"], "times": [1.0, 0.5]}]},
     "flows.sources[0].times"),
    ({"sources": [{**SOURCE, "group": "nobody"}]}, "flows.sources[0].group"),
    ({"sources": [{**SOURCE, "speeds": [1.0, 1.2]}]}, "flows.sources[0].speeds"),
    ({"journeys": [{"legs": []}]}, "flows.journeys[0].legs"),
    ({"journeys": [{"legs": [{"goal": [1, 1], "region": SINK}]}]}, "flows.journeys[0].legs[0]"),
    ({"journeys": [{"legs": [{"goal": [1, 1]}]}, {"legs": [{"goal": [2, 2]}]}]},
     "flows.journeys[1].group"),
    ({"headway": {"time_gap": 0}}, "flows.headway.time_gap"),
    ({"headway": {"gap": 1}}, "flows.headway"),
    ({"other": 1}, "flows"),
])
def test_bad_flows_are_refused_with_field_and_fix(flows, field):
    with pytest.raises(SceneError) as err:
        Scene.from_dict(corridor(flows))
    assert err.value.field == field
    assert err.value.problem and err.value.fix


def test_per_agent_noise_is_refused_when_sources_add_agents():
    data = corridor({"sources": [SOURCE]})
    data["noise"] = {"sigma": [0.1, 0.2, 0.1]}
    with pytest.raises(SceneError) as err:
        Scene.from_dict(data)
    assert err.value.field == "noise.sigma"


def test_without_headway_or_population_change_the_step_is_the_pure_model_bit_for_bit():
    pure = Simulator(Scene.from_dict(corridor(None, sigma=0.1)), dt=0.05, seed=7)
    # flows that change nothing for these agents: a sink nobody reaches in 2 s
    far = {"sinks": [{"kind": "rectangle", "min": [9.8, 3.8], "max": [10.0, 4.0]}]}
    same = Simulator(Scene.from_dict(corridor(far, sigma=0.1)), dt=0.05, seed=7)
    for _ in range(40):
        pure.step()
        same.step()
        assert np.array_equal(pure.positions.view(np.uint64), same.positions.view(np.uint64))


def test_sources_and_sinks_conserve_agents_and_keep_ids():
    sim = Simulator(Scene.from_dict(corridor(FULL, sigma=0.05)), dt=0.05, seed=3)
    seen_left: set[int] = set()
    for _ in range(260):
        sim.step()
        p = sim.flows
        ids = sim.ids
        assert 3 + p.entered == len(ids) + p.left
        assert np.all(np.diff(ids) > 0)  # present agents in increasing id order
        assert not (set(ids.tolist()) & set(p.left_at))  # a departed id never comes back
        assert set(p.left_at) >= seen_left
        seen_left = set(p.left_at)
        assert len(sim.positions) == len(ids) == len(sim.radii)
    assert p.entered == 6 and p.left >= 5
    assert set(p.left_at) | set(sim.ids.tolist()) == set(range(9))


def test_speeds_are_drawn_with_the_seed_and_walked_in_free_flight():
    data = corridor({"speeds": {"distribution": "uniform", "min": 0.8, "max": 1.6}})
    scene = Scene.from_dict(data)
    a, b, c = (Simulator(scene, dt=0.05, seed=s) for s in (1, 1, 2))
    assert np.array_equal(a.flows.speed, b.flows.speed)
    assert not np.array_equal(a.flows.speed, c.flows.speed)
    assert np.all((a.flows.speed >= 0.8) & (a.flows.speed <= 1.6))
    a.reset()
    assert np.array_equal(a.flows.speed, b.flows.speed)  # a reset draws them again alike
    a.step()  # far from the goal and from one another: |v| = v0
    assert np.allclose(np.hypot(*a.velocities.T), a.flows.speed, rtol=1e-12, atol=0)
    given = Simulator(Scene.from_dict(corridor({"speeds": [0.5, 1.0, 1.5]})), dt=0.05)
    given.step()
    assert np.allclose(np.hypot(*given.velocities.T), [0.5, 1.0, 1.5], rtol=1e-12, atol=0)


def test_start_delays_are_respected():
    # apart, so nobody pushes a waiting agent (waiting agents are still projected)
    sim = Simulator(Scene.from_dict(corridor({"delays": [0.0, 0.5, 1.0]},
                                             positions=[[1, 0.5], [1, 2], [1, 3.5]])), dt=0.05)
    start = sim.positions
    for k in range(1, 31):
        sim.step()
        t0 = sim.t - sim.dt  # the wished velocity is that of the step's start
        moved = np.any(sim.positions != start, axis=1)
        assert moved.tolist() == [t0 >= 0.0, t0 >= 0.5 - 1e-12, t0 >= 1.0 - 1e-12], k


def test_headway_speed_is_the_free_distance_over_the_time_gap():
    q = np.array([[0.0, 0.0], [1.0, 0.1], [5.0, 0.0]])
    r = np.array([0.2, 0.2, 0.2])
    u = np.array([[1.3, 0.0], [0.0, 0.0], [1.3, 0.0]])
    out = headway(q, r, u, 0.5)
    s = 1.0 - np.sqrt(0.4 ** 2 - 0.1 ** 2)  # travel along x before touching agent 1
    assert out[0, 1] == 0.0 and np.isclose(out[0, 0], s / 0.5, rtol=1e-12)
    assert np.array_equal(out[1:], u[1:])  # standing and free agents unchanged
    # a person beside the path (offset beyond r_i + r_j) does not slow, unless within the
    # lateral margin w: then s is the distance along the path, a = 1 m
    beside = np.array([[0.0, 0.0], [1.0, 0.41]])
    assert np.array_equal(headway(beside, r[:2], u[[0, 1]], 0.5), u[[0, 1]])
    slowed = headway(beside, r[:2], u[[0, 1]], 1.0, margin=0.1)
    assert np.isclose(slowed[0, 0], 1.0, rtol=1e-12) and slowed[0, 1] == 0.0
    assert np.array_equal(headway(beside, r[:2], u[[0, 1]], 1.0, margin=0.005), u[[0, 1]])


def test_journeys_follow_their_legs_in_order():
    legs = [{"region": {"kind": "rectangle", "min": [4.0, 3.0], "max": [5.0, 4.0]}},
            {"goal": [8.0, 0.6]}]
    sim = Simulator(Scene.from_dict(corridor({"journeys": [{"legs": legs}]},
                                             positions=[[1.0, 1.0]])), dt=0.05)
    visited = False
    for _ in range(240):
        sim.step()
        visited |= bool(np.hypot(*(sim.positions[0] - [4.5, 3.0])) < 1.0)
    assert visited and sim.flows.leg[0] == 1
    assert np.hypot(*(sim.positions[0] - [8.0, 0.6])) < 0.5


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    d = tmp_path_factory.mktemp("flows")
    scene = d / "s.yaml"
    scene.write_text(Scene.from_dict(corridor(FULL, sigma=0.05)).to_yaml())
    out = d / "run.mcap"
    assert main(["run", str(scene), "--t-end", "13", "--dt", "0.05", "--seed", "3",
                 "--out", str(out), "--quiet"]) == 0
    sim = Simulator(Scene.from_yaml(scene), dt=0.05, seed=3)
    ids = [sim.ids]
    for _ in range(260):
        sim.step()
        ids.append(sim.ids)
    return d, scene, out, sim, ids


def test_a_seeded_run_with_sources_and_sinks_records_ids_and_replays(recorded):
    _, _, out, sim, ids = recorded
    frames = list(FrameReader(load_run(out)))
    assert len(frames) == len(ids) == 261
    for fr, want in zip(frames, ids):
        got = np.rint(fr.agents["id"].astype(np.float64)).astype(np.int64)
        assert np.array_equal(got, want) and len(fr.positions) == len(want)
    res = replay.replay(out)
    assert res.identical and res.frames_compared == 261


def test_analysis_counts_agents_that_left(recorded):
    _, _, out, sim, _ = recorded
    an = analyze(out)
    pop = an.summary["population"]
    p = sim.flows
    assert pop["initial"] == 3 and pop["entered"] == p.entered and pop["left"] == p.left
    assert pop["present_at_end"] == len(sim.ids) and pop["conserved"]
    left = an.arrival  # by id: the time each agent left
    for i, t in p.left_at.items():
        assert left[i] == pytest.approx(t, abs=1e-9)
    assert an.summary["arrivals"]["arrived"] == p.left


def test_analysis_agents_are_every_agent_seen_and_present_max_the_most_at_once(recorded):
    """``agents``: the distinct agents the recording holds (the scene's and those that
    entered); ``population.present_max``: the most in one frame (docs/recordings.md)."""
    _, _, out, _, ids = recorded
    summary = analyze(out).summary
    pop = summary["population"]
    seen = set(np.concatenate(ids).tolist())
    assert summary["agents"] == len(seen) == pop["initial"] + pop["entered"]
    assert pop["present_max"] == max(len(i) for i in ids)


def test_compare_matches_agents_by_id(recorded, tmp_path):
    d, scene, out, _, _ = recorded
    other = tmp_path / "other.mcap"
    assert main(["run", str(scene), "--t-end", "13", "--dt", "0.05", "--seed", "3",
                 "--out", str(other), "--quiet"]) == 0
    c = compare.compare(out, other)
    assert c.sup_m == 0.0 and c.common_frames == 261
    assert len(c.per_agent_sup_m) == 9  # every id seen


def test_path_dt_is_refused_when_agents_enter_or_leave(recorded, capsys):
    _, scene, _, _, _ = recorded
    assert main(["run", str(scene), "--t-end", "0.1", "--path-dt", "0.01",
                 "--out", str(recorded[0] / "p.mcap"), "--quiet"]) != 0
    assert "path_dt" in capsys.readouterr().err


def test_run_size_counts_the_agents_sources_may_add(tmp_path, capsys):
    """100 000 agents entering at 1000 /s into a hall that holds them all: up to 100 000
    present, 100 s at dt 0.01 is far more than 2 GB (in the 10 m x 4 m corridor at most a
    few hundred are present at once, and the same run fits: test_estimates)."""
    scene = tmp_path / "big.yaml"
    data = corridor({"sources": [{**SOURCE, "rate": 1000.0, "count": 100_000}]},
                    positions=[[5.0, 2.0]])
    data["walls"] = [{"kind": "polyline", "points": [[0, 0], [400, 0], [400, 400], [0, 400]],
                      "closed": True}]
    scene.write_text(Scene.from_dict(data).to_yaml())
    assert main(["run", str(scene), "--t-end", "100", "--dt", "0.01",
                 "--out", str(tmp_path / "big.mcap"), "--quiet"]) != 0
    err = capsys.readouterr().err
    assert "--record-every" in err and "up to 100000 entering at sources" in err
    assert not (tmp_path / "big.mcap").exists()


def test_entering_agents_follow_their_groups_journey():
    data = corridor({"sources": [{**SOURCE, "count": 2, "group": "walkers"}],
                     "journeys": [{"group": "walkers", "legs": [
                         {"region": {"kind": "rectangle", "min": [4.0, 0.0], "max": [5.0, 1.0]}},
                         {"goal": [8.0, 3.4]}]}]}, positions=[[5.0, 3.5]])
    data["agents"]["groups"] = [{"name": "walkers", "agents": [0], "drift": {
        "kind": "goal", "goal": [5.0, 3.5]}}]
    sim = Simulator(Scene.from_dict(data), dt=0.05)
    low = np.zeros(3, dtype=bool)
    for _ in range(200):
        sim.step()
        ids = sim.ids
        low[ids[sim.positions[:, 1] < 1.5]] = True
    p = sim.flows
    assert p.entered == 2 and p.group.tolist() == [0, 0, 0]
    # the entering agents went down to the first leg's region, then on to the second goal
    assert low[1:].all() and p.leg[1:].tolist() == [1, 1]
    assert np.all(np.hypot(*(sim.positions[1:] - [8.0, 3.4]).T) < 1.0)


def test_the_headway_law_slows_a_dense_ring_the_pure_model_does_not():
    from sweep_core.model.ring import ring_corridor, tangential_speed

    def speed(time_gap):
        sim = Simulator(Scene.from_dict(ring_corridor(2.0, time_gap=time_gap)), dt=0.05)
        sim.run(4.0)
        v = []
        for _ in range(20):
            sim.step()
            v.append(tangential_speed(sim.positions, sim.velocities).mean())
        return float(np.mean(v))

    pure, law = speed(None), speed(DEFAULT_TIME_GAP)
    # free speed 1.34 m/s: the pure model keeps it at 2 per m^2, the law (csm at its
    # defaults: in a uniform queue the published law with T = 1.1 s) roughly halves it
    # (Weidmann: 0.61 m/s)
    assert pure > 1.2 and law < 0.9
