"""Careless or hostile input to the flow features, refused in one line or read correctly.

Scenes with ``flows`` (distributions, sources, sinks, exit choices, the csm speed law), ``sweep
verify``'s options, outputs inside the package, and recordings with entering and leaving
agents cut short: each case fails on the code before its fix (a traceback, a source that
waits for ever, agents that stop or get NaN velocities, ids renumbered, a bundled file
overwritten, a report written only after every run).
"""
from __future__ import annotations

import copy
import math
import os
import re
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from sweep_core import Scene, SceneError, Simulator, checks
from sweep_core.analysis.frames import FrameReader
from sweep_core.analysis.pedpy_export import read_trajectories
from sweep_core.analysis.run import load_run
from sweep_core.cli import main
from sweep_core.ensemble.cluster import check_workers
from sweep_core.errors import OutputError, RecordingError
from sweep_core.io.outputs import PACKAGE, check_folder, check_output
from sweep_core.io.recording import read_recording
from sweep_core.model import flow_checks, flows, speed_law
from sweep_core.model.geometry import single_values
from sweep_core.model.neighbours import pairs_within
from sweep_core.model.regions import region_from_spec
from sweep_core.model.yaml_files import dump_yaml
from sweep_core.numerics.csm import csm, directions, wall_terms

ROOM = [{"kind": "polyline", "points": [[0, 0], [10, 0], [10, 4], [0, 4]], "closed": True}]
SOURCE = {"region": {"kind": "rectangle", "min": [0.3, 0.3], "max": [1.5, 3.7]},
          "rate": 4.0, "count": 8}
SINK = {"kind": "rectangle", "min": [8.5, 0.0], "max": [10.0, 4.0]}


def corridor(flow: dict, **more) -> dict:
    """A 10 m x 4 m room, three agents walking east, and ``flow`` as its flows key."""
    return {"name": "corridor",
            "agents": {"positions": [[1.0, 1.0], [1.0, 2.0], [2.0, 1.5]], "radius": 0.2},
            "walls": copy.deepcopy(ROOM), "drift": {"kind": "goal", "goal": [9.5, 2.0],
                                                     "speed": 1.3},
            "flows": flow, **more}


def refused(data: dict) -> SceneError:
    with pytest.raises(SceneError) as err:
        Scene.from_dict(data)
    assert err.value.problem and err.value.fix
    return err.value


# -- values of the wrong kind and size ------------------------------------------------------


@pytest.mark.parametrize("dist", [["normal"], {"kind": "normal"}])
def test_a_distribution_that_is_no_name_is_refused(dist):
    """Before: TypeError (unhashable) from the dict lookup."""
    err = refused(corridor({"speeds": {"distribution": dist, "min": 1.0, "max": 2.0}}))
    assert err.field == "flows.speeds.distribution"


def test_exit_capacities_are_counted_as_exits():
    """Before: 'one per agent, 2 agents' for a list of capacities of 2 exits."""
    exits = [{"goal": [9.5, 1.0]}, {"goal": [9.5, 3.0]}]
    err = refused(corridor({"exit_choice": [{"exits": exits, "capacity": [1.0]}]}))
    assert err.field == "flows.exit_choice[0].capacity"
    assert "agent" not in str(err) and "one per exit" in str(err) and "2 exits" in str(err)
    err = refused(corridor({"exit_choice": [{"exits": exits, "capacity": [1.0, -2.0]}]}))
    assert err.field == "flows.exit_choice[0].capacity[1]"


@pytest.mark.parametrize("flow, field", [
    ({"speeds": 1e300}, "flows.speeds"),
    ({"speeds": [1.0, 2e4, 1.0]}, "flows.speeds[1]"),
    ({"speeds": {"distribution": "uniform", "min": 1.0, "max": 1e300}}, "flows.speeds.max"),
    ({"sources": [{**SOURCE, "speeds": 1e300}]}, "flows.sources[0].speeds"),
])
def test_a_preferred_speed_beyond_the_bound_is_refused(flow, field):
    """Before: accepted; at 1e300 m/s the first step stopped with 'agents cannot be placed
    without overlap' (fix: smaller radii), the projection's rows having overflowed."""
    err = refused(corridor(flow))
    assert err.field == field and str(int(flows.MAX_SPEED)) in str(err)


@pytest.mark.parametrize("edit, field", [
    (lambda d: d["drift"].update(speed=1e20), "drift.speed"),
    (lambda d: d["agents"].update(speed=1e20), "agents.speed"),
    (lambda d: d.update(drift={"kind": "geodesic", "goal": [9.5, 2.0], "speed": 2e4}),
     "drift.speed"),
    (lambda d: d.update(drift={"kind": "groups", "groups": [
        {"name": "a", "agents": [0, 1, 2], "speed": 1e20,
         "drift": {"kind": "goal", "goal": [9.5, 2.0]}}]}), "drift.groups[0].speed"),
    # a uniform or per-agent velocity is a drift speed too (before: accepted; at 1e20 m/s the
    # first step stopped with 'cannot be placed without overlap, fix: smaller radii')
    (lambda d: d.update(drift={"kind": "uniform", "velocity": [1e20, 0.0]}), "drift.velocity"),
    (lambda d: d.update(drift={"kind": "uniform", "velocity": [8e3, 8e3]}), "drift.velocity"),
    (lambda d: d.update(drift={"kind": "per_agent", "velocities": [[1.0, 0.0], [0.0, 0.0],
                                                                   [0.0, -1e300]]}),
     "drift.velocities[2]"),
    # a moving wall or obstacle too (before: a half-plane at 1e20 m/s "completed" its run
    # with the agents pushed to y = 1e19 m, far beyond the position bound)
    (lambda d: d["walls"].append({"kind": "halfplane", "normal": [0, 1], "offset": -5.0,
                                  "velocity": 1e20}), "walls[1].velocity"),
    (lambda d: d["walls"].append({"kind": "halfplane", "normal": [0, 1], "offset": -5.0,
                                  "velocity": -2e4}), "walls[1].velocity"),
    (lambda d: d.update(obstacles=[{"kind": "circle", "center": [5, 3], "radius": 0.3,
                                    "velocity": [0.0, 1e20]}]), "obstacles[0].velocity"),
])
def test_a_drift_speed_beyond_the_bound_is_refused(edit, field):
    """Before: accepted; a goal drift at 1e20 m/s stopped at its first step with 'agents
    cannot be placed without overlap' (fix: smaller radii), naming the radii, not the speed."""
    data = corridor({})
    del data["flows"]
    edit(data)
    err = refused(data)
    assert err.field == field and str(int(checks.MAX_SPEED)) in str(err)
    edit_ok = corridor({})
    del edit_ok["flows"]
    edit_ok["drift"]["speed"] = checks.MAX_SPEED  # the bound itself is accepted
    Scene.from_dict(edit_ok)


def test_a_radius_beyond_the_bound_is_named_in_the_plural_correctly():
    """Before: 'use radiuss within +-10000 m' (a wall offset of 1e5 m)."""
    with pytest.raises(SceneError, match="use offsets within"):
        checks.length(1e5, "walls[0].offset", what="offset")
    with pytest.raises(SceneError, match="use radii within"):
        checks.within_bound(np.array([1e5]), "obstacles[0].radius", "radius")


@pytest.mark.parametrize("field, what", [("robots[0].goal_radius", "length"),
                                         ("robots[0].radius", "radius")])
def test_a_size_beyond_the_bound_is_not_told_to_shift_the_origin(field: str, what: str):
    """A radius or range of 1e5 m: no shift of the origin changes a size; the fix names the
    field and its largest value."""
    with pytest.raises(SceneError, match=rf"\(fix: set {re.escape(field)} to at most 10000 m\)$"):
        checks.length(1e5, field, positive=True, what=what)


@pytest.mark.parametrize("key, value", [("repulsion", 1e160), ("repulsion", 1e300),
                                        ("repulsion_range", 1e-300), ("repulsion_range", 1e-9),
                                        ("wall_repulsion", 1e300), ("wall_range", 1e-300)])
def test_repulsion_beyond_its_bounds_is_refused(key, value):
    """Before: accepted; a = 1e160 stopped every agent near another (a_w = 1e300 every agent
    at a wall), D = 1e-300 gave NaN."""
    err = refused(corridor({"headway": {key: value}}))
    assert err.field == f"flows.headway.{key}"


@pytest.mark.parametrize("law, key, value", [("csm", "time_gap", 1e6), ("csm", "time_gap", 10.5),
                                              ("lanes", "time_gap", 1e6),
                                              ("lanes", "margin", 1e3)])
def test_a_time_gap_or_margin_that_makes_every_pair_a_neighbour_is_refused(law, key, value):
    """Before: accepted; the laws search the pairs within max|u| T + 2 max r (+ w), so
    T = 1e6 s or w = 1e3 m made every pair of the crowd a candidate (memory N^2 / 2)."""
    err = refused(corridor({"headway": {"law": law, key: value}}))
    assert err.field == f"flows.headway.{key}"
    assert "at most" in err.problem or "between" in err.problem


def test_the_largest_time_gap_and_margin_are_accepted():
    scene = Scene.from_dict(corridor({"headway": {"time_gap": speed_law.MAX_TIME_GAP}}))
    assert scene.spec["flows"]["headway"]["time_gap"] == speed_law.MAX_TIME_GAP
    scene = Scene.from_dict(corridor({"headway": {"law": "lanes",
                                                  "margin": speed_law.MAX_MARGIN}}))
    assert scene.spec["flows"]["headway"]["margin"] == speed_law.MAX_MARGIN


def test_the_direction_rule_stays_finite_at_the_bounds():
    """At the largest repulsion and the smallest range, with two disks overlapping by the
    1e-9 m the rows allow and a crowd pressing on one agent, every direction is a unit vector
    (the agents keep moving): the sum cannot overflow."""
    ring = 0.4 * np.stack([np.cos(np.arange(6) * np.pi / 3), np.sin(np.arange(6) * np.pi / 3)],
                          axis=1)
    q = np.concatenate([[[0.0, 0.0]], ring * (1 - 2.5e-9)])  # each neighbour 1e-9 m inside
    r = np.full(len(q), 0.2)
    u = np.tile([1.0, 0.3], (len(q), 1))
    v = csm(q, r, u, 2.1, speed_law.MAX_REPULSION, speed_law.MIN_REPULSION_RANGE, 1.0)
    assert np.all(np.isfinite(v))
    pi, pj = pairs_within(q, 1.0)
    # the walls' terms at the bounds: gaps down to -1e-9 m, normals from every side
    g = np.full(len(q), -1e-9)
    normal = np.stack([np.cos(np.arange(len(q))), np.sin(np.arange(len(q)))], axis=1)
    walls = wall_terms([(np.arange(len(q)), None, g, normal, None)] * 3, len(q),
                       speed_law.MAX_REPULSION, speed_law.MIN_REPULSION_RANGE)
    assert np.all(np.isfinite(walls))
    e = directions(q, r, u, pi, pj, speed_law.MAX_REPULSION, speed_law.MIN_REPULSION_RANGE,
                   walls)
    assert np.allclose(np.hypot(e[:, 0], e[:, 1]), 1.0)


def test_too_many_sinks_or_sources_are_refused():
    """Before: 1e5 sinks took 1.4 s a step, 1e4 sources more than 1.5 s a step, and 256
    sources of 1e5 agents each (2.56e7 ids, past the 2^24 that /agents' float32 carries
    exactly) were accepted."""
    err = refused(corridor({"sinks": [SINK] * (flows.MAX_SINKS + 1)}))
    assert err.field == "flows.sinks" and str(flows.MAX_SINKS) in str(err)
    err = refused(corridor({"sources": [SOURCE] * (flows.MAX_SOURCES + 1)}))
    assert err.field == "flows.sources" and str(flows.MAX_SOURCES) in str(err)
    assert flows.MAX_SOURCES * flows.MAX_SOURCE_COUNT < 2 ** 24  # every id exact in float32


# -- sources that could never emit, or whose agents would leave at once ----------------------


@pytest.mark.parametrize("source, obstacles", [
    ({"region": {"kind": "rectangle", "min": [4, 1], "max": [5, 2]}},   # inside a circle
     [{"kind": "circle", "center": [4.5, 1.5], "radius": 1.5}]),
    ({"region": {"kind": "rectangle", "min": [-0.1, 1], "max": [0.1, 2]}}, []),  # on the wall
    ({"region": {"kind": "rectangle", "min": [0.1, 0.1], "max": [0.15, 0.15]}}, []),  # corner
    ({"radius": 3.0}, []),                    # wider than the 4 m room
    ({"radius": [0.1, 1e4]}, []),             # the largest draws never fit
])
def test_a_source_without_room_is_refused(source, obstacles):
    """Before: the scene ran and every due agent waited for ever (``waiting`` grew)."""
    err = refused(corridor({"sources": [{**SOURCE, **source}], "sinks": [SINK]},
                           obstacles=obstacles))
    assert err.field == "flows.sources[0].region"


def test_a_source_with_room_is_kept_and_emits():
    """The room test never refuses a source that can emit: a 1.9 m disk in the 4 m room."""
    scene = Scene.from_dict(corridor({"sources": [{
        "region": {"kind": "rectangle", "min": [3, 1], "max": [6, 3]}, "times": [0.0],
        "radius": 1.9}]}, agents={"positions": [[9.0, 0.5]], "radius": 0.2}))
    sim = Simulator(scene, dt=0.05, seed=0)
    sim.run(0.1)
    assert sim.flows is not None and sim.flows.entered == 1


def test_the_room_test_is_sound_on_random_regions():
    """Whenever has_room says False, no point of a fine sample of the region has the
    clearance r (its proof, on 300 seeded regions near walls and a circle)."""
    scene = Scene.from_dict(corridor({}, obstacles=[{"kind": "circle", "center": [5.0, 2.0],
                                                     "radius": 1.0}]))
    rng = np.random.default_rng(7)
    refusals = 0
    for _ in range(300):
        lo = rng.uniform([-0.5, -0.5], [10.0, 4.0])
        hi = lo + rng.uniform(0.01, 1.5, 2)
        r = float(rng.uniform(0.05, 1.5))
        region = region_from_spec({"kind": "rectangle", "min": lo.tolist(), "max": hi.tolist()},
                                  "region")
        if flow_checks.has_room(region, r, scene.geometry) is not False:
            continue
        refusals += 1
        g = np.stack(np.meshgrid(np.linspace(lo[0], hi[0], 60), np.linspace(lo[1], hi[1], 60)),
                     axis=-1).reshape(-1, 2)
        clearance = np.min(np.concatenate(
            [v.reshape(len(g), -1) for v, _, _ in single_values(scene.geometry, 0.0, g,
                                                                np.zeros(len(g)))], axis=1),
            axis=1)
        assert clearance.max() < r
    assert refusals > 20  # the test refused enough regions to mean something


def test_a_source_inside_a_sink_is_refused():
    """Before: its agents entered and left at once (entered 3, left 5 in a second)."""
    cover = {"kind": "rectangle", "min": [0, 0], "max": [3, 4]}
    err = refused(corridor({"sources": [SOURCE], "sinks": [SINK, cover]}))
    assert err.field == "flows.sources[0].region" and "flows.sinks[1]" in str(err)
    poly = {"kind": "polygon", "points": [[0, 0], [3, 0], [3, 4], [0, 4]]}
    assert refused(corridor({"sources": [SOURCE], "sinks": [poly]})).field == \
        "flows.sources[0].region"
    half = {"kind": "rectangle", "min": [1, 0], "max": [3, 4]}  # overlapping is allowed
    Scene.from_dict(corridor({"sources": [SOURCE], "sinks": [half]}))


@pytest.mark.parametrize("legs, field", [
    ([{"goal": [20.0, 2.0]}], "flows.journeys[0].legs[0]"),               # outside the room
    ([{"region": {"kind": "rectangle", "min": [20, 20], "max": [21, 21]}}],
     "flows.journeys[0].legs[0]"),
    ([{"goal": [5.0, 2.0]}, {"goal": [20.0, 2.0]}], "flows.journeys[0].legs[1]"),
])
def test_a_journey_its_agents_cannot_walk_is_refused(legs, field):
    """Before: accepted; the agents stood still for ever before the unreachable target."""
    err = refused(corridor({"journeys": [{"legs": legs}]}))
    assert err.field == field and "has no way to the goal" in err.problem
    Scene.from_dict(corridor({"journeys": [{"legs": [{"goal": [5.0, 2.0]}, {"goal": [8, 2]}]}]}))


def test_an_exit_choice_with_no_exit_its_agents_can_reach_is_refused():
    """Before: accepted; with both exits outside the room the agents walked 2.5 m in 2 s
    towards neither. One unreachable exit among reachable ones is allowed."""
    out = [{"goal": [20.0, 1.0]}, {"goal": [20.0, 3.0]}]
    err = refused(corridor({"exit_choice": [{"exits": out}]}))
    assert err.field == "flows.exit_choice[0].exits" and "any of the exits" in err.problem
    Scene.from_dict(corridor({"exit_choice": [{"exits": [out[0], {"goal": [9.5, 3.0]}]}]}))


#: a wall across the corridor at x = 5 m: the east half cannot reach the west half
SPLIT = [{"kind": "segment", "a": [5.0, -0.5], "b": [5.0, 4.5]}]
EAST = {"region": {"kind": "rectangle", "min": [7.0, 1.0], "max": [8.5, 3.0]}, "rate": 4.0,
        "count": 8}


@pytest.mark.parametrize("flow, drift, what", [
    ({"journeys": [{"legs": [{"goal": [3.0, 2.0]}, {"goal": [1.0, 3.0]}]}]}, None,
     "flows.journeys[0].legs[0]"),
    ({"exit_choice": [{"exits": [{"goal": [3.0, 1.0]}, {"goal": [3.0, 3.0]}]}]}, None,
     "any of flows.exit_choice[0].exits"),
    ({}, {"kind": "geodesic", "goal": [3.0, 2.0], "speed": 1.3}, "the drift's goal"),
])
def test_a_source_whose_agents_cannot_walk_to_their_target_is_refused(flow, drift, what):
    """Before: accepted; the agents the source emitted in the walled-off half walked west
    into the wall between them and their target and stayed pressed against it (x 5.2 to
    5.6 m after 10 s); the initial agents, in the other half, were checked. The same source
    in their half is accepted, and so is one across the wall (some of its points have a way:
    only a source none of whose points has one is refused)."""
    more = {"walls": copy.deepcopy(ROOM) + SPLIT, **({"drift": drift} if drift else {})}
    err = refused(corridor({**flow, "sources": [SOURCE, EAST]}, **more))
    assert err.field == "flows.sources[1].region" and what in err.problem
    Scene.from_dict(corridor({**flow, "sources": [SOURCE]}, **more))
    across = {**EAST, "region": {"kind": "rectangle", "min": [4.0, 1.0], "max": [6.0, 3.0]}}
    Scene.from_dict(corridor({**flow, "sources": [across]}, **more))


# -- sweep verify's options and outputs ------------------------------------------------------


def _cli(args: list[str], capsys) -> tuple[int, str]:
    capsys.readouterr()
    code = main(args)
    return code, capsys.readouterr().err


@pytest.mark.parametrize("args, words", [
    (["--seeds", "1000000000"], "--seeds: 1000000000"),
    (["--seed", "-1", "--seeds", "1"], "--seed: -1"),
])
def test_verify_refuses_bad_seeds_before_running(args, words, capsys, tmp_path):
    """Before: --seeds 1e9 built a list of 1e9 seeds; --seed -1 ran and failed every run
    (exit status 1)."""
    code, err = _cli(["verify", "--quick", "--tests", "rimea1", "--out", str(tmp_path / "v"),
                      *args], capsys)
    assert code == 2 and words in err and "fix:" in err and "runs done" not in err, err


def test_verify_refuses_a_worker_count_beyond_the_machine(capsys, tmp_path):
    """Before: --workers 100000 started a LocalCluster of 100000 processes (2.4 TB)."""
    code, err = _cli(["verify", "--quick", "--tests", "rimea1", "--workers", "100000",
                      "--out", str(tmp_path / "v")], capsys)
    assert code == 2 and "--workers: 100000" in err and "fix:" in err, err
    assert check_workers(None) >= 1 and check_workers(8) == 8


def test_verify_refuses_an_output_that_is_no_folder_before_running(tmp_path, capsys):
    """Before: every run first, then a FileExistsError traceback (exit status 1)."""
    existing = tmp_path / "report.txt"
    existing.write_text("keep me\n")
    for out in (existing, existing / "sub"):
        code, err = _cli(["verify", "--quick", "--tests", "rimea1", "--seeds", "1", "--out",
                          str(out)], capsys)
        assert code == 2 and str(out) in err and "runs done" not in err, err
    assert existing.read_text() == "keep me\n"


def test_verify_refuses_a_replacement_scene_that_is_no_file(tmp_path, capsys):
    """Before: a FIFO or a folder named as a bundled scene in --scenes was passed over and the
    bundled scene ran instead, silently."""
    folder = tmp_path / "scenes"
    folder.mkdir()
    os.mkfifo(folder / "rimea01_corridor.yaml")
    code, err = _cli(["verify", "--quick", "--tests", "rimea1", "--seeds", "1", "--scenes",
                      str(folder), "--out", str(tmp_path / "v")], capsys)
    assert code == 2 and "rimea01_corridor.yaml" in err and "FIFO" in err, err
    assert "runs done" not in err


def test_no_output_goes_inside_the_package(tmp_path, capsys):
    """Before: `sweep run S --out sweep_core/scenes/gallery.yaml` replaced the bundled
    index with an MCAP recording, and verify wrote its report among the bundled scenes."""
    index = Path(PACKAGE) / "scenes" / "gallery.yaml"
    before = index.read_bytes()
    scene = tmp_path / "s.yaml"
    scene.write_text("agents: {positions: [[0, 0]], radius: 0.2}\n")
    code, err = _cli(["run", str(scene), "--t-end", "0.05", "--out", str(index), "--quiet"],
                     capsys)
    assert code == 2 and "inside the installed sweep_core package" in err, err
    assert index.read_bytes() == before
    with pytest.raises(OutputError):
        check_output(Path(PACKAGE) / "scenes" / "x.mcap")
    with pytest.raises(OutputError):
        check_folder(Path(PACKAGE) / "scenes" / "rimea")
    assert check_folder(tmp_path / "a" / "b").is_dir()


# -- recordings with agents entering and leaving, cut short -----------------------------------


@pytest.fixture(scope="module")
def flows_run(tmp_path_factory) -> Path:
    """A 1 s recording (21 states) with a source and a sink: agents enter and leave."""
    folder = tmp_path_factory.mktemp("flows")
    scene = folder / "flows.yaml"
    data = corridor({"sources": [SOURCE], "sinks": [{"kind": "rectangle", "min": [1.5, 0.0],
                                                     "max": [1.9, 4.0]}]})
    data["agents"]["positions"] = [[1.8, 1.0], [1.7, 2.0], [2.0, 3.0]]  # two leave at once
    scene.write_text(dump_yaml(data))
    out = folder / "flows.mcap"
    assert main(["run", str(scene), "--t-end", "1.0", "--dt", "0.05", "--out", str(out),
                 "--quiet"]) == 0
    return out


def _copy(src: Path, dst: Path, keep=lambda topic, i: True) -> list[tuple[str, int]]:
    """The recording ``src`` written again with one message per chunk, its metadata first (a
    cut file keeps them, as sweep run's own files do), the messages kept by keep(topic, k);
    returns (topic, byte offset of its chunk) of each message written."""
    with open(src, "rb") as f, open(dst, "wb") as o:
        reader = make_reader(f)
        summary = reader.get_summary()
        w = Writer(o, chunk_size=1, compression=CompressionType.NONE)
        w.start(profile="ros2", library="test cut")
        sids = {k: w.register_schema(s.name, s.encoding, s.data)
                for k, s in summary.schemas.items()}
        cids = {k: w.register_channel(c.topic, c.message_encoding, sids[c.schema_id],
                                      dict(c.metadata)) for k, c in summary.channels.items()}
        for md in reader.iter_metadata():
            if md.name != "sweep_status":
                w.add_metadata(md.name, dict(md.metadata))
        count: dict[str, int] = {}
        for _, ch, m in reader.iter_messages(log_time_order=False):
            k = count.get(ch.topic, 0)
            count[ch.topic] = k + 1
            if keep(ch.topic, k):
                w.add_message(cids[ch.id], m.log_time, m.data, m.publish_time, m.sequence)
        w.finish()
    return [(m.topic, m.offset) for m in read_recording(str(dst), ["/poses", "/agents"])]


def test_a_recording_cut_between_poses_and_agents_is_read_to_the_cut(flows_run, tmp_path,
                                                                      capsys):
    """Cut before the /agents of a state whose /poses is in the file: analyze (before: refused
    the whole recording) and export (before: numbered that state's agents 0 .. N - 1, other
    agents' ids) read every whole state and leave the cut one out."""
    whole = tmp_path / "whole.mcap"
    messages = _copy(flows_run, whole)
    full = read_trajectories(whole)
    agents_at = [off for topic, off in messages if topic == "/agents"]
    for k in (5, len(agents_at) // 2, len(agents_at) - 1):
        cut = tmp_path / f"cut{k}.mcap"
        cut.write_bytes(whole.read_bytes()[:agents_at[k]])
        meta = load_run(cut)
        frames = list(FrameReader(meta))
        assert len(frames) == k and all(fr.agents is not None for fr in frames)
        traj = read_trajectories(cut)
        sel = full.frames < k
        assert np.array_equal(traj.ids, full.ids[sel]) and np.array_equal(traj.xy, full.xy[sel])
    code, err = _cli(["analyze", str(cut), "--no-plots", "--quiet"], capsys)
    assert code == 0 and "that state is left out" in err, err


def test_export_refuses_a_state_without_ids_when_agents_come_and_go(flows_run, tmp_path):
    """Before: the state whose /agents message is missing got ids 0 .. N - 1, silently."""
    holed = tmp_path / "holed.mcap"
    _copy(flows_run, holed, keep=lambda topic, k: not (topic == "/agents" and k == 10))
    with pytest.raises(RecordingError, match="no readable /agents ids"):
        read_trajectories(holed)
    assert math.isfinite(load_run(holed).dt or math.nan)


# -- sweep render's options ------------------------------------------------------------------


def test_render_refuses_rates_and_names_it_cannot_honour(flows_run, tmp_path, capsys):
    """Before: --fps 1e-9 reached ffmpeg as rate 0 and failed with its many-line output (and
    the fix 'free disk space'); a GIF at --fps 1000 was written with 1 ms frames, which
    viewers show for 100 ms; --out x.avi held an MP4."""
    from sweep_core.analysis.animation import has_encoder

    cases = [(["--out", str(tmp_path / "fast.gif"), "--fps", "1000"], "--fps 1000"),
             (["--out", str(tmp_path / "x.avi")], "--out")]
    if has_encoder():
        cases.append((["--out", str(tmp_path / "slow.mp4"), "--fps", "1e-9"], "--fps 1e-09"))
    for args, words in cases:
        code, err = _cli(["render", str(flows_run), "--to", "0.1", "--size", "160", "--quiet",
                          *args], capsys)
        errors = [ln for ln in err.splitlines() if ln.strip()]
        assert code == 2 and len(errors) == 1 and words in errors[0] and "fix:" in errors[0], err
        assert not Path(args[1]).exists()


def test_recordings_of_scenes_refused_now_still_load_and_replay(tmp_path, monkeypatch, capsys):
    """A run recorded before these refusals existed (a source inside a sink, a repulsion of
    5000) still analyses and replays bit for bit: a recording's scene is held to the checks it
    was made under (the refusals are for new scenes). Before (with the refusals applied to
    recorded scenes too): replay and analyze refused the recording."""
    data = corridor({"sources": [SOURCE], "sinks": [{"kind": "rectangle", "min": [0, 0],
                                                     "max": [3, 4]}],
                     "headway": {"repulsion": 5000.0}})
    assert refused(copy.deepcopy(data)).field == "flows.sources[0].region"
    scene, run = tmp_path / "old.yaml", tmp_path / "old.mcap"
    scene.write_text(dump_yaml(data))
    with monkeypatch.context() as m:  # the code before the refusals
        m.setattr(flows, "check_sources", lambda *a: None)
        m.setattr(speed_law, "MAX_REPULSION", math.inf)
        assert main(["run", str(scene), "--t-end", "0.5", "--dt", "0.05", "--out", str(run),
                     "--quiet"]) == 0
    code, _ = _cli(["analyze", str(run), "--no-plots", "--quiet"], capsys)
    assert code == 0
    capsys.readouterr()
    assert main(["replay", str(run)]) == 0
    assert "IDENTICAL" in capsys.readouterr().out


def test_an_ensemble_folder_inside_the_package_is_refused():
    """The ensemble's folder is checked as verify's is (it was only checked for being a
    folder): nothing is made inside the installed package."""
    from pathlib import Path

    from sweep_core.ensemble import store
    from sweep_core.errors import OutputError
    from sweep_core.io import outputs

    inside = Path(outputs.PACKAGE) / "scenes" / "ensemble_out"
    with pytest.raises(OutputError, match="inside the installed sweep_core package"):
        store.lock(inside)
    assert not inside.exists()


@pytest.mark.parametrize("flow, words", [
    ({"journeys": [{"legs": [{"goal": [5, 2]}]}, {"legs": [{"goal": [6, 2]}]}]},
     "flows.journeys[1].group: gives the agents in no group a second journey"),
    ({"exit_choice": [{"exits": [{"goal": [9, 2]}, {"goal": [1, 3]}]}] * 2},
     "flows.exit_choice[1].group: gives the agents in no group a second exit choice"),
    ({"journeys": [{"legs": [{"goal": [5, 2]}]}],
      "exit_choice": [{"exits": [{"goal": [9, 2]}, {"goal": [1, 3]}]}]},
     "flows.exit_choice[0].group: gives the agents in no group an exit choice and a journey"),
])
def test_a_second_plan_for_the_agents_in_no_group_names_them(flow, words):
    """Before: 'gives group null a second ...', naming a group the scene does not have."""
    assert str(refused(corridor(flow))).startswith(words)
