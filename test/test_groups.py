"""Groups with their own drift and preferred speed (issue 15): ``agents.groups`` in the scene,
the ``groups`` drift kind, ``Groups.with_member_drift`` (a goal command for one group), and
recordings of them replaying."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

import sweep_core as sc
from sweep_core.analysis import replay
from sweep_core.errors import SceneError
from sweep_core.io import topics
from sweep_core.io.metadata import run_metadata
from sweep_core.io.recording import Recorder
from sweep_core.model.fields import Goal, Groups, Uniform, field_from_spec

CORRIDOR = [{"kind": "polyline", "closed": True, "points": [[0, 0], [20, 0], [20, 3], [0, 3]]}]
EAST = {"kind": "rectangle", "min": [16.5, 0.0], "max": [20.0, 3.0]}
WEST = {"kind": "rectangle", "min": [0.0, 0.0], "max": [3.5, 3.0]}
#: four agents going east, three going west and one in the middle of the corridor
THREE = ([[1.0 + 0.7 * k, 0.8] for k in range(4)] + [[19.0 - 0.7 * k, 2.2] for k in range(3)]
         + [[10.0, 1.5]])


def corridor(groups, drift=None, positions=None, speed=1.3, sigma=0.02):
    left = [[1.0 + 0.7 * k, 0.8] for k in range(4)]
    right = [[19.0 - 0.7 * k, 2.2] for k in range(4)]
    data = {"agents": {"positions": positions or left + right, "radius": 0.25, "speed": speed,
                       "groups": groups},
            "walls": CORRIDOR, "noise": {"sigma": sigma}}
    if drift is not None:
        data["drift"] = drift
    return sc.Scene.from_dict(data)


def crossing_groups():
    """Four agents at x 1 .. 3.1 (y 0.8) going east at 1.3 m/s, four at x 19 .. 16.9 (y 2.2)
    going west at 0.9 m/s, both by geodesic fields to goals at the far ends; the drifts give
    no speed: the groups' speeds fill it in."""
    return [{"name": "eastbound", "agents": {"range": [0, 4]}, "speed": 1.3,
             "drift": {"kind": "geodesic", "goal": [19.5, 0.8]}},
            {"name": "westbound", "agents": [4, 5, 6, 7], "speed": 0.9,
             "drift": {"kind": "geodesic", "goal": [0.5, 2.2]}}]


def test_two_groups_crossing_in_a_corridor_both_arrive_in_time():
    s = corridor(crossing_groups())
    f = s.drift
    assert isinstance(f, Groups) and f.names == ("eastbound", "westbound")
    assert f.speeds == (1.3, 0.9) and [g.speed for g in f.fields] == [1.3, 0.9]
    # an agent has arrived when it is past x = 16.5 (east) or x = 3.5 (west), 3 m before
    # its goal, still at full speed: 15.5 m from the start for the farthest (x = 1 and 19),
    # 11.9 s at 1.3 m/s and 17.2 s at 0.9 m/s along a grid axis (no metrication error);
    # 10 % and 1 s more for the noise and passing the other group, so a drift to the wrong
    # place, or at the other group's speed, misses it
    def limit(d: float, v: float) -> float:
        return 1.1 * d / v + 1.0

    sim = sc.Simulator(s, dt=0.05, seed=2)
    arrived = np.full(8, np.nan)
    while sim.t < limit(15.5, 0.9):
        sim.step()
        q = sim.positions
        inside = np.where(np.arange(8) < 4, q[:, 0] >= 16.5, q[:, 0] <= 3.5)
        arrived[inside & np.isnan(arrived)] = sim.t
    start = s.positions[:, 0]
    need = np.array([limit(16.5 - x, 1.3) for x in start[:4]]
                    + [limit(x - 3.5, 0.9) for x in start[4:]])
    assert np.all(arrived <= need), (arrived, need)
    # and not faster than the group's speed allows (so each went at its own speed)
    least = np.array([(16.5 - x) / 1.3 for x in start[:4]] + [(x - 3.5) / 0.9 for x in start[4:]])
    assert np.all(arrived >= 0.95 * least), (arrived, least)


def test_each_group_progresses_at_its_own_speed_in_open_space():
    """Two groups of five, 1 m apart, heading for goals 100 m away (no slowing, no contact):
    the mean speed along x over T = 4 s is the group's speed up to the noise, whose mean over
    m agents has standard deviation sigma / sqrt(m T), and the goal's angle (cos >= 0.9995)."""
    m, sigma, T, dt = 5, 0.05, 4.0, 0.01
    q = [[0.0, float(k)] for k in range(m)] + [[0.0, 10.0 + k] for k in range(m)]
    s = sc.Scene.from_dict({
        "agents": {"positions": q, "radius": 0.2, "speed": 1.3, "groups": [
            {"name": "slow", "agents": {"range": [0, m]}, "speed": 0.6,
             "drift": {"kind": "goal", "goal": [100.0, 2.0]}},
            {"name": "fast", "agents": {"range": [m, 2 * m]}, "speed": 1.4,
             "drift": {"kind": "goal", "goal": [100.0, 12.0]}}]},
        "noise": {"sigma": sigma}})
    sim = sc.Simulator(s, dt=dt, seed=5)
    sim.step(int(round(T / dt)))
    v = (sim.positions[:, 0] - s.positions[:, 0]) / T
    tol = 4 * sigma / math.sqrt(m * T) + 1e-3 * 1.4
    assert abs(v[:m].mean() - 0.6) < tol and abs(v[m:].mean() - 1.4) < tol, (v, tol)


def test_with_member_drift_changes_that_group_only():
    groups = crossing_groups()
    groups[1]["agents"] = [4, 5, 6]  # agent 7 follows the scene's drift
    s = corridor(groups, drift={"kind": "uniform", "velocity": [0.0, 0.1]}, positions=THREE)
    g = s.drift
    assert isinstance(g, Groups)
    before = g(0.0, s.positions)
    cmd = Goal(goal=np.array([10.0, 1.5]), speed=g.speeds[1], slow_radius=0.5)
    h = g.with_member_drift(1, cmd)
    after = h(0.0, s.positions)
    np.testing.assert_array_equal(after[:4], before[:4])  # the other group
    np.testing.assert_array_equal(after[7], before[7])  # the rest
    np.testing.assert_array_equal(after[4:7], cmd(0.0, s.positions[4:7]))
    assert h.fields[0] is g.fields[0] and h.rest is g.rest and g.fields[1] is not cmd
    assert (h.names, h.speeds) == (g.names, g.speeds)
    spec = h.to_spec()
    assert spec["groups"][1] == {"name": "westbound", "agents": [4, 5, 6],
                                 "drift": cmd.to_spec(), "speed": 0.9}
    assert spec["groups"][0]["drift"] == g.fields[0].to_spec()
    # the recorded spec rebuilds the same field (against the scene, as replay does)
    again = s.drift_from_spec(spec)
    assert isinstance(again, Groups) and again.to_spec() == spec
    np.testing.assert_array_equal(again(0.0, s.positions), after)
    assert h.index("westbound") == 1
    with pytest.raises(SceneError, match=r"^group: 2 is not a group index"):
        h.with_member_drift(2, cmd)
    with pytest.raises(SceneError, match=r"^group: 'north' is not a group of the scene"):
        h.index("north")
    with pytest.raises(SceneError, match=r"^groups\[0\].drift: must be a plain"):
        h.with_member_drift(0, h)


def test_spec_round_trip_keeps_names_speeds_and_the_rest():
    groups = crossing_groups()
    del groups[1]["name"]  # the default name
    groups[1]["agents"] = [4, 5, 6]
    s = corridor(groups, drift={"kind": "uniform", "velocity": [0.1, 0.0]}, positions=THREE)
    a = s.spec["agents"]["groups"]
    assert [g["name"] for g in a] == ["eastbound", "group1"]
    assert [g["speed"] for g in a] == [1.3, 0.9] and a[1]["drift"]["speed"] == 0.9
    assert a[0]["agents"] == {"range": [0, 4]} and a[1]["agents"] == [4, 5, 6]
    assert s.spec["drift"] == {"kind": "uniform", "velocity": [0.1, 0.0]}
    again = sc.Scene.from_yaml_text(s.to_yaml())
    assert again.spec == s.spec
    assert again.drift.names == s.drift.names and again.drift.speeds == s.drift.speeds
    np.testing.assert_array_equal(again.drift(0.0, s.positions), s.drift(0.0, s.positions))
    # the drift kind groups takes names and speeds too, and its spec is what commands carry
    d = s.drift.to_spec()
    assert d["kind"] == "groups" and d["rest"] == s.spec["drift"]
    t = sc.Scene.from_dict({**s.spec, "agents": {k: v for k, v in s.spec["agents"].items()
                                                 if k != "groups"}, "drift": d})
    assert t.drift.to_spec() == d and t.drift.names == ("eastbound", "group1")


def test_a_group_speed_fills_goal_drifts_and_defaults_to_the_drift_or_agents_speed():
    s = corridor([{"agents": [0], "drift": {"kind": "goal", "goal": [10, 1.5]}},
                  {"agents": [1], "drift": {"kind": "goal", "goal": [10, 1.5], "speed": 0.7}},
                  {"agents": [2], "drift": {"kind": "uniform", "velocity": [0.2, 0]}},
                  {"agents": [3], "speed": 0.5, "drift": {"kind": "uniform", "velocity": [0, 0]}}],
                 positions=[[1.0 + 0.7 * k, 0.8] for k in range(4)], speed=1.1)
    assert s.drift.speeds == (1.1, 0.7, 1.1, 0.5)
    assert s.drift.fields[0].speed == 1.1
    assert s.drift.names == ("group0", "group1", "group2", "group3")


def test_a_groups_command_replays_bit_for_bit(tmp_path):
    """The node's way: a goal for one group (with_member_drift), recorded as the new drift's
    to_spec; the geodesic field of the other group is rebuilt from it by replay."""
    s = corridor(crossing_groups(), sigma=0.1)
    sim = sc.Simulator(s, dt=0.02, seed=4)
    path = tmp_path / "groups.mcap"
    meta = run_metadata(s, sim, None, 1)
    with Recorder(path, metadata=meta, flush_interval_s=None) as rec:
        for name, msgtype in topics.TYPES.items():
            rec.add_channel("/" + name, msgtype)

        def publish() -> None:
            for name, data in topics.encode_state(sim.state).items():
                rec.write("/" + name, topics.stamp_ns(sim.t), data)

        publish()
        for k in range(40):
            if k == 10:
                cmd = Goal(goal=np.array([10.0, 1.5]), speed=s.drift.speeds[1])
                sim.set_drift(sim.drift.with_member_drift(1, cmd))
                rec.add_metadata("command_000001", {
                    "topic": "/westbound/goal", "step": str(k), "t": repr(sim.t),
                    "log_time_ns": str(topics.stamp_ns(sim.t)),
                    "field": json.dumps(sim.drift.to_spec())})
            sim.step()
            publish()
    res = replay.replay(path)
    assert res.identical and res.commands_applied == 1, replay.format_replay(res)


@pytest.mark.parametrize("groups, drift, field, words", [
    ([{"agents": [0, 1], "drift": None}, {"agents": {"range": [1, 3]}, "drift": None}], None,
     "agents.groups[1].agents", "second group"),
    ([{"name": "1st", "agents": [0], "drift": None}], None, "agents.groups[0].name",
     "'1st' is not a valid group name"),
    ([{"name": "a b", "agents": [0], "drift": None}], None, "agents.groups[0].name", "[A-Za-z]"),
    ([{"name": 7, "agents": [0], "drift": None}], None, "agents.groups[0].name", "7 is not"),
    ([{"name": "left", "agents": [0], "drift": None},
      {"name": "left", "agents": [1], "drift": None}], None, "agents.groups[1].name",
     "'left' is the name of group 0 too"),
    ([{"agents": [0], "drift": None}], {"kind": "groups", "groups": [{"agents": [1],
                                                                      "drift": None}]},
     "agents.groups", "drift: {kind: groups}"),
    ([{"agents": [0], "speed": 0, "drift": None}], None, "agents.groups[0].speed", "> 0"),
    ([{"agents": [0], "speed": -1.0, "drift": None}], None, "agents.groups[0].speed", "> 0"),
    ([{"agents": [0], "speed": 1.0, "drift": {"kind": "goal", "goal": [5, 1], "speed": 1.5}}],
     None, "agents.groups[0].drift.speed", "1.5 m/s differs from agents.groups[0].speed 1"),
    ([{"agents": [0], "drift": None, "colour": "red"}], None, "agents.groups[0]", "colour"),
    ([], None, "agents.groups", "non-empty"),
    ([{"agents": [0], "drift": {"kind": "geodesic", "goal": [25, 1]}}], None,
     "agents.groups[0].drift", "no way to the goal"),
    ([{"agents": [0], "drift": None}], {"kind": "goal", "goal": [5, 1]}, "drift.speed", "missing"),
])
def test_bad_groups_are_refused_naming_the_field(groups, drift, field, words):
    with pytest.raises(SceneError) as err:
        corridor(groups, drift=drift, positions=[[1.0, 0.8], [2.0, 0.8], [3.0, 0.8]])
    text = str(err.value)
    assert text.startswith(field + ":") and words in text and "fix:" in text, text
    assert "\n" not in text and "np." not in text and "array(" not in text


def test_the_groups_drift_kind_refuses_bad_names_too():
    with pytest.raises(SceneError, match=r"^drift.groups\[1\].name: 'a' is the name of group 0"):
        field_from_spec({"kind": "groups", "groups": [
            {"name": "a", "agents": [0], "drift": None},
            {"name": "a", "agents": [1], "drift": None}]}, 2)
    with pytest.raises(SceneError, match=r"^drift.groups\[0\].name: 'x-y' is not"):
        field_from_spec({"kind": "groups", "groups": [
            {"name": "x-y", "agents": [0], "drift": {"kind": "uniform", "velocity": [1, 0]}}]},
            2)
    # in the drift kind (what commands and recordings carry) a drift's own speed wins
    f = field_from_spec({"kind": "groups", "groups": [
        {"agents": [0], "speed": 1.0, "drift": {"kind": "goal", "goal": [5, 1], "speed": 1.5}}]},
        2)
    assert f.speeds == (1.0,) and f.fields[0].speed == 1.5
    assert isinstance(f.rest, sc.Field) and not isinstance(f.rest, Uniform)
