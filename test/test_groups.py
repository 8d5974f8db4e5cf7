"""Groups with their own drift and preferred speed (issue 15): ``agents.groups`` in the scene,
the ``groups`` drift kind, ``Groups.with_member_drift`` (a goal command for one group), and
recordings of them replaying."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import sweep_core as sc
from sweep_core.analysis import metrics, plots, replay, report
from sweep_core.cli import main
from sweep_core.errors import SceneError
from sweep_core.io import topics
from sweep_core.io.metadata import run_metadata
from sweep_core.io.recording import Recorder
from sweep_core.model.drift import field_from_spec
from sweep_core.model.fields import Goal, Groups, Uniform

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
    # analyze follows the command: westbound now heads for [10, 1.5] (within its 0.5 m
    # slow_radius), eastbound still for its geodesic goal; neither is reached in 0.8 s
    an = metrics.analyze(path)
    assert list(an.summary["per_group"]) == ["eastbound", "westbound"]
    assert an.summary["arrivals"]["radius_m"] == 0.5 and an.summary["arrivals"]["arrived"] == 0


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


# ---------------------------------------------------------------------------------------------
# sweep analyze: per exit and per group
# ---------------------------------------------------------------------------------------------

ROOM = [{"kind": "polyline", "closed": True, "points": [[0, 0], [20, 0], [20, 10], [0, 10]]}]
#: the recording interval: an arrival is seen at the first frame past it
DT = 0.05


def recorded(tmp_path, data: dict, t_end: float) -> Path:
    """A deterministic `sweep run` of the scene ``data`` recorded every step."""
    s = sc.Scene.from_dict(data)
    (tmp_path / "s.yaml").write_text(s.to_yaml())
    out = tmp_path / "run.mcap"
    assert main(["run", str(tmp_path / "s.yaml"), "--t-end", str(t_end), "--dt", str(DT),
                 "--out", str(out), "--quiet"]) == 0
    return out


def near(value, expected):
    """An arrival time seen at a recorded frame: within one frame (plus rounding) after the
    exact time."""
    return value is not None and expected - 1e-9 <= value <= expected + DT + 1e-9


def test_analyze_reports_which_exit_each_agent_took_and_when(tmp_path, capsys):
    """Four agents on the line y = 5 between an exit point at x = 1 and an exit region from
    x = 19, speed 1 m/s, no noise; arrived = within 1 m (--arrive-radius), so at full speed:
    x = 4 -> exit 0 at 2 s, x = 7 -> exit 0 at 5 s, x = 15 -> exit 1 at 3 s, x = 11.5 ->
    exit 1 (7.5 m against 10.5) at 6.5 s, after the run's 6 s."""
    door = {"kind": "rectangle", "min": [19, 4], "max": [20, 6]}
    out = recorded(tmp_path, {
        "agents": {"positions": [[4, 5], [7, 5], [15, 5], [11.5, 5]], "radius": 0.2},
        "walls": ROOM, "drift": {"kind": "exits", "exits": [{"goal": [1, 5]}, {"region": door}],
                                 "speed": 1.0}}, 6.0)
    an = metrics.analyze(out, arrive_radius=1.0)
    assert an.arrival_exit == ["exits[0]", "exits[0]", "exits[1]", None]
    e = an.summary["per_exit"]
    assert list(e) == ["exits[0]", "exits[1]"]
    assert (e["exits[0]"]["agents"], e["exits[0]"]["arrived"]) == (2, 2)
    assert (e["exits[1]"]["agents"], e["exits[1]"]["arrived"]) == (2, 1)
    assert near(e["exits[0]"]["t_first_s"], 2.0) and near(e["exits[0]"]["t_50_s"], 2.0)
    assert near(e["exits[0]"]["t_90_s"], 5.0) and near(e["exits[0]"]["t_last_s"], 5.0)
    assert near(e["exits[1]"]["t_first_s"], 3.0) and near(e["exits[1]"]["t_last_s"], 3.0)
    # agent 3 is still on its way: no exit is evacuated
    assert e["exits[0]"]["evacuation_s"] is None and e["exits[1]"]["evacuation_s"] is None
    a = an.summary["arrivals"]
    assert a["arrived"] == 3 and a["t_all_s"] is None and a["radius_m"] == 1.0
    assert near(a["t_50_s"], 3.0)
    assert an.summary["per_group"] is None
    assert main(["analyze", str(out), "--arrive-radius", "1", "--no-plots", "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "per_exit.exits[1].evacuation_s  not all arrived" in text
    assert "per_exit.exits[0].agents" in text


def test_analyze_reports_arrivals_and_evacuation_per_group(tmp_path):
    """Group west (agents 0, 1 at x = 4 and 7) by a geodesic field to [1, 5] at 1 m/s, group
    east (agents 2, 3 at x = 15 and 11) by a goal drift to [19, 5] at 0.5 m/s, both speeds
    the groups' own; arrived = within 1 m: west at 2 and 5 s (evacuated at 5 s), east at
    6 s and 14 s, after the run's 8 s."""
    out = recorded(tmp_path, {
        "agents": {"positions": [[4, 5], [7, 5], [15, 5], [11, 5]], "radius": 0.2, "groups": [
            {"name": "west", "agents": [0, 1], "speed": 1.0,
             "drift": {"kind": "geodesic", "goal": [1, 5]}},
            {"name": "east", "agents": {"range": [2, 4]}, "speed": 0.5,
             "drift": {"kind": "goal", "goal": [19, 5]}}]},
        "walls": ROOM}, 8.0)
    an = metrics.analyze(out, arrive_radius=1.0)
    g = an.summary["per_group"]
    assert list(g) == ["west", "east"]
    w, e = g["west"], g["east"]
    assert (w["agents"], w["arrived"], e["agents"], e["arrived"]) == (2, 2, 2, 1)
    assert near(w["t_first_s"], 2.0) and near(w["t_50_s"], 2.0) and near(w["t_90_s"], 5.0)
    assert near(w["t_last_s"], 5.0) and near(w["evacuation_s"], 5.0)
    assert near(e["t_first_s"], 6.0) and near(e["t_50_s"], 6.0) and e["t_90_s"] is None
    assert near(e["t_last_s"], 6.0) and e["evacuation_s"] is None
    assert an.summary["arrivals"]["arrived"] == 3 and an.summary["per_exit"] is None
    # the plot draws the west group's travel-time field under the density
    report.write_outputs(an)
    assert out.with_name("run.analysis.png").stat().st_size > 0
    assert [name for name, _ in plots.named_navigation_fields(an.meta.scene.drift)] == ["west"]
    plt = plots.pyplot()
    fig, ax = plt.subplots()
    assert plots.draw_travel_time(ax, an.meta.scene) == " and travel time"
    drawn = [c for c in ax.get_children() if type(c).__name__ in ("QuadContourSet",
                                                                  "ContourSet")]
    assert len(drawn) == 1 and len(drawn[0].levels) == plots.CONTOURS
    assert ax.get_legend().get_texts()[0].get_text().startswith("west: every")
    plt.close(fig)
