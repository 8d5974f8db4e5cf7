"""A recording's metadata is data: what it claims never sizes what is built.

Each case rewrites the ``sweep_ros`` metadata of a real small recording (a corridor with a
source and a sink) to claim a scene that would be costly to rebuild: thousands of sources of
100 000 agents each, journeys of many legs on fine grids, a map of isolated blocked cells, a
spawn of agents, /agents ids far beyond what the scene can number. Every command that rebuilds
the scene (analyze, replay, export, render, compare) refuses it in one line naming the
recording, the field and the bound (exit 2), with its peak memory (RSS, measured by the
process itself) under 500 MB: the bound is checked before the cost is paid. Before the
bounds: 6000 sources of 100 000 agents drove analyze to 3.3 GB and a MemoryError traceback.
"""
from __future__ import annotations

import base64
import copy
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from sweep_core.analysis.run import RECORDED_BASE_NODES
from sweep_core.cli import main
from sweep_core.io import cdr
from sweep_core.model.budget import MAX_GROUPS, MAX_PIECES, MAX_SEGMENTS
from sweep_core.model.json_text import dump_json
from sweep_core.model.outlines import MAX_OUTLINE_PAIRS
from sweep_core.model.scene import scene_data
from sweep_core.model.yaml_files import MAX_RECORDED_YAML_NODES, dump_yaml

REPO = Path(__file__).resolve().parents[1]
#: peak resident memory (MB) a refusal may reach: the interpreter, numpy, numba and the
#: recording's own bytes, far below what any of the claims would cost
PEAK_MB = 500
ROOM = [{"kind": "polyline", "points": [[0, 0], [10, 0], [10, 4], [0, 4]], "closed": True}]
SOURCE = {"region": {"kind": "rectangle", "min": [0.3, 0.3], "max": [1.5, 3.7]},
          "rate": 4.0, "count": 8}
SCENE = {"name": "corridor",
         "agents": {"positions": [[1.0, 1.0], [1.0, 2.0], [2.0, 1.5]], "radius": 0.2},
         "walls": ROOM, "drift": {"kind": "goal", "goal": [9.5, 2.0], "speed": 1.3},
         "flows": {"sources": [SOURCE],
                   "sinks": [{"kind": "rectangle", "min": [8.5, 0.0], "max": [10.0, 4.0]}]}}


@pytest.fixture(scope="module")
def run_file(tmp_path_factory) -> Path:
    """A 1 s recording (21 states) of the corridor, agents entering and leaving."""
    folder = tmp_path_factory.mktemp("hostile_recordings")
    scene = folder / "corridor.yaml"
    scene.write_text(dump_yaml(SCENE))
    out = folder / "run.mcap"
    assert main(["run", str(scene), "--t-end", "1.0", "--dt", "0.05", "--out", str(out),
                 "--quiet"]) == 0
    return out


def rewrite(src: Path, dst: Path, edit=None, agent_ids=None, dump=dump_json) -> Path:
    """``src`` written again with its recorded scene replaced by ``edit(scene dict)`` (as
    text by ``dump``: JSON, as sweep records it, or YAML) and, with ``agent_ids``, the
    /agents ids of every state replaced by ``agent_ids(ids)``."""
    with open(src, "rb") as f, open(dst, "wb") as o:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        w = Writer(o, compression=CompressionType.NONE)
        w.start(profile="ros2", library="test hostile")
        sids = {k: w.register_schema(s.name, s.encoding, s.data)
                for k, s in summary.schemas.items()}
        cids = {k: w.register_channel(c.topic, c.message_encoding, sids[c.schema_id],
                                      dict(c.metadata)) for k, c in summary.channels.items()}
        for md in reader.iter_metadata():
            meta = dict(md.metadata)
            if md.name == "sweep_ros" and edit is not None:
                meta["scene"] = dump(edit(scene_data(meta["scene"])))
            w.add_metadata(md.name, meta)
        for _, ch, m in reader.iter_messages(log_time_order=False):
            data = m.data
            if agent_ids is not None and ch.topic == "/agents":
                cloud = cdr.decode_point_cloud2(data)
                fields = dict(cloud.fields)
                fields["id"] = np.asarray(agent_ids(fields["id"]), dtype=np.float32)
                data = cdr.encode_point_cloud2(cloud.stamp_ns, cloud.frame_id, fields)
            w.add_message(cids[ch.id], m.log_time, data, m.publish_time, m.sequence)
        w.finish()
    return dst


#: runs each command line of argv (JSON) in this one process, then prints per command its
#: exit code and stderr, and the process's peak resident memory (MB, Linux's VmHWM: the largest
#: any of the commands reached; getrusage's ru_maxrss would also count the test process that
#: forked it, as Linux keeps it across execve)
RUNNER = """
import contextlib, io, json, sys
from sweep_core.analysis.run import RECORDED_BASE_NODES
from sweep_core.cli import main
out = []
for args in json.loads(sys.argv[1]):
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(args)
        except SystemExit as e:
            code = e.code
    out.append([code, err.getvalue()])
with open("/proc/self/status") as fh:
    peak = next(int(ln.split()[1]) for ln in fh if ln.startswith("VmHWM:")) / 1024
print(json.dumps({"runs": out, "peak_mb": peak}))
"""


def sweep(commands: list[list[str]], cwd: Path) -> tuple[list[tuple[int, str]], float]:
    """The ``sweep`` command lines run one after the other in one fresh process: (exit code,
    stderr) of each, and the process's peak resident memory (MB)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(REPO)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    done = subprocess.run([sys.executable, "-c", RUNNER, json.dumps(commands)], cwd=cwd,
                          env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout.splitlines()[-1])
    return [(c, e) for c, e in result["runs"]], result["peak_mb"]


def refused_everywhere(bad: Path, good: Path, words: list[str], tmp_path: Path,
                       commands: tuple[str, ...] = ("analyze", "replay", "export", "render",
                                                    "compare")) -> None:
    """Every command that rebuilds the recorded scene refuses ``bad`` in one line holding the
    recording's path and ``words`` (the field and the bound), exit 2, all of them together
    under PEAK_MB."""
    args = {"analyze": ["analyze", str(bad), "--no-plots", "--quiet"],
            "replay": ["replay", str(bad)],
            "export": ["export", str(bad), "--pedpy", str(tmp_path / "out.txt")],
            "render": ["render", str(bad), "--out", str(tmp_path / "out.gif"), "--size", "160",
                       "--quiet"],
            "compare": ["compare", str(good), str(bad)]}
    runs, peak = sweep([args[name] for name in commands], tmp_path)
    for name, (code, err) in zip(commands, runs):
        errors = [ln for ln in err.splitlines() if ln.startswith("sweep: error:")]
        assert code == 2 and len(errors) == 1 and "Traceback" not in err, (name, err)
        assert str(bad) in errors[0] and all(w in errors[0] for w in words), (name, errors[0])
    assert peak < PEAK_MB, peak
    assert not (tmp_path / "out.txt").exists() and not (tmp_path / "out.gif").exists()


def test_thousands_of_sources_are_refused_before_any_is_built(run_file, tmp_path):
    """6000 sources of 100 000 agents: each source's entry times alone would be 800 kB."""
    def many(scene: dict) -> dict:
        big = {**SOURCE, "count": 100_000}
        scene["flows"]["sources"] = [copy.deepcopy(big) for _ in range(6000)]  # no aliases
        return scene

    bad = rewrite(run_file, tmp_path / "sources.mcap", many)
    refused_everywhere(bad, run_file, ["flows.sources", "6000", "64"], tmp_path)


def test_a_source_beyond_the_count_bound_is_refused(run_file, tmp_path):
    def big(scene: dict) -> dict:
        scene["flows"]["sources"][0]["count"] = 10**9
        return scene

    bad = rewrite(run_file, tmp_path / "count.mcap", big)
    refused_everywhere(bad, run_file, ["flows.sources[0].count", "100000"], tmp_path,
                       ("analyze",))


def test_journeys_of_many_legs_on_fine_grids_are_refused_before_any_grid(run_file, tmp_path):
    """64 legs of 0.8 million grid nodes each: 70 s and 2 GB to build before the bound."""
    def legs(scene: dict) -> dict:
        scene["walls"] = [{"kind": "polyline", "points": [[0, 0], [99, 0], [99, 99], [0, 99]],
                           "closed": True}]
        legs = [{"goal": [9.0 if k % 2 else 1.0, 2.0]} for k in range(64)]
        scene["flows"] = {"journeys": [{"legs": legs, "cell": 0.11}]}
        return scene

    bad = rewrite(run_file, tmp_path / "legs.mcap", legs)
    refused_everywhere(bad, run_file, ["flows.journeys[0].cell", "4000000"], tmp_path,
                       ("analyze", "replay"))


def test_a_map_of_isolated_cells_is_refused_before_its_walls_are_built(run_file, tmp_path):
    """A 1000 x 1000 map whose every other cell is blocked (166 kB packed) makes a million
    walls: 7.7 s and 0.45 GB to build before the bound."""
    n, res = 1000, 0.05
    blocked = np.zeros((n, n), bool)
    blocked[1::2, 1::2] = True
    blocked[: int(4.5 / res), : int(10.5 / res)] = False  # the corridor stays free
    packed = base64.b64encode(np.packbits(blocked.ravel()).tobytes()).decode()

    def mapped(scene: dict) -> dict:
        scene["map"] = {"source": "x", "resolution": res, "origin": [0.0, 0.0, 0.0],
                        "width": n, "height": n, "blocked": packed}
        return scene

    bad = rewrite(run_file, tmp_path / "map.mcap", mapped)
    refused_everywhere(bad, run_file, ["map", "250000"], tmp_path, ("analyze", "replay"))


def test_a_spawn_in_a_recorded_scene_is_refused(run_file, tmp_path):
    """A recorded scene holds its agents' positions; a spawn of 10^7 agents in a 10 km
    square would run for hours."""
    def spawned(scene: dict) -> dict:
        scene["walls"] = []
        scene["agents"] = {"spawn": {"region": {"kind": "rectangle", "min": [0, 0],
                                                "max": [9000, 9000]},
                                     "count": 10**7, "radius": 0.2, "seed": 1}}
        scene.pop("flows")
        return scene

    bad = rewrite(run_file, tmp_path / "spawn.mcap", spawned)
    refused_everywhere(bad, run_file, ["agents.spawn"], tmp_path, ("analyze",))


def test_agent_ids_beyond_what_the_scene_numbers_are_refused(run_file, tmp_path):
    """An /agents id of 10^9 sized the arrays kept by id (8 GB each) before the bound: the
    corridor's run numbers at most 3 + 8 agents."""
    bad = rewrite(run_file, tmp_path / "ids.mcap", agent_ids=lambda ids: ids + 1e9)
    refused_everywhere(bad, run_file, ["/agents id", "[0, 11)"], tmp_path,
                       ("analyze", "compare"))


def _chain(n: int, x0: float = 12.0) -> list[list[float]]:
    """An open chain of n points east of the corridor (it touches no agent)."""
    return [[x0 + 1e-4 * k, 0.5 + 0.25 * (k % 2)] for k in range(n)]


def _circle(n: int) -> list[list[float]]:
    t = 2 * np.pi * np.arange(n) / n
    return np.c_[20 + 5 * np.cos(t), 5 + 5 * np.sin(t)].tolist()


#: recorded scenes that would cost too much to read or build, each with the words its refusal
#: names (the field and the bound) and how its text is written
COSTLY = {
    # 3 nodes a point: YAML composes about 600 B a node (19 s and 700 MB for 3e5 points)
    "yaml": (lambda s: {**s, "walls": s["walls"] + [{"kind": "polyline",
                                                       "points": _chain(90_000)}]},
             ["MAX_RECORDED_YAML_NODES", str(MAX_RECORDED_YAML_NODES)], dump_yaml),
    "segments": (lambda s: {**s, "walls": s["walls"] + [{"kind": "polyline",
                                                           "points": _chain(MAX_SEGMENTS)}]},
                 ["walls", str(MAX_SEGMENTS)], dump_json),
    "pieces": (lambda s: {**s, "walls": s["walls"] + [
        {"kind": "segment", "a": [12.0 + 1e-3 * k, 0.0], "b": [12.0 + 1e-3 * k, 1.0]}
        for k in range(MAX_PIECES)]}, ["walls", str(MAX_PIECES)], dump_json),
    "groups": (lambda s: {**s, "agents": {**s["agents"], "groups": [
        {"name": f"g{k}", "agents": [0], "drift": {"kind": "goal", "goal": [9.5, 2.0]}}
        for k in range(MAX_GROUPS + 1)]}}, ["agents.groups", str(MAX_GROUPS)], dump_json),
    # a claim of 400 000 agents beside frames of 3: read within what the frames hold
    "agents": (lambda s: {**s, "agents": {"positions": (20 + 0.5 * np.stack(np.meshgrid(
        np.arange(640), np.arange(625)), -1).reshape(-1, 2)).tolist(), "radius": 0.2}},
               ["first state holds 3 agents", str(RECORDED_BASE_NODES)], dump_json),
    "outline": (lambda s: {**s, "walls": s["walls"] + [{"kind": "polyline", "closed": True,
                                                          "points": _circle(4500)}]},
                ["walls[1].points", "MAX_OUTLINE_PAIRS", str(MAX_OUTLINE_PAIRS)], dump_json),
}


@pytest.mark.parametrize("case", list(COSTLY))
def test_recorded_scenes_that_cost_too_much_to_build_are_refused(run_file, tmp_path, case):
    """Counted before they are built: YAML nodes in a recorded scene, JSON nodes beyond what
    the recording's first state can need, wall segments and pieces, groups, and the pairs of
    edges a closed outline's simple-polygon test compares (a 10 000-point outline took 22 s
    before the bound). One line, exit 2, under PEAK_MB."""
    edit, words, dump = COSTLY[case]
    bad = rewrite(run_file, tmp_path / f"{case}.mcap", edit, dump=dump)
    refused_everywhere(bad, run_file, words, tmp_path, ("analyze", "replay"))


def test_a_large_scene_as_sweep_records_it_is_read_within_the_bound(run_file, tmp_path):
    """A recorded wall chain of 240 000 points (JSON, 5 MB), within every bound: analyze and
    replay read and rebuild it under PEAK_MB (as YAML the same text composed to 700 MB)."""
    def chained(scene: dict) -> dict:
        scene["walls"] = scene["walls"] + [{"kind": "polyline", "points": _chain(240_000)}]
        return scene

    big = rewrite(run_file, tmp_path / "big.mcap", chained)
    runs, peak = sweep([["analyze", str(big), "--no-plots", "--quiet"], ["replay", str(big)]],
                       tmp_path)
    assert [code for code, _ in runs] == [0, 0], runs
    assert peak < PEAK_MB, peak
