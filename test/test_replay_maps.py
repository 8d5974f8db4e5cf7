"""sweep replay of node runs that received maps (metadata map_*, issue 13): the walls are
rebuilt from the recorded map at its step, and stay over resets, as the node does.

The recordings are made here the way sweep_ros/node.py makes them (Simulator.set_scene with
the scene's spec and the packed map, a map_NNNNNN record at that step's log time)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

import sweep_core as sc
from sweep_core.analysis import replay
from sweep_core.analysis.run import Schedule, load_run, scene_with_map
from sweep_core.io import topics
from sweep_core.io.metadata import run_metadata
from sweep_core.io.recording import Recorder
from sweep_core.model.maps import OccupancyMap

DT, SEED = 0.01, 4
SCENE = sc.Scene.from_dict({
    "name": "six_east",
    "agents": {"positions": [[0.5, 0.5], [1.0, 0.5], [1.5, 0.5], [0.5, 1.0], [1.0, 1.0],
                             [1.5, 1.0]], "radius": 0.2},
    "drift": {"kind": "uniform", "velocity": [1.0, 0.0]},
    "noise": {"sigma": 0.1},
})


def room(width_cells: int) -> dict:
    """A packed room of 0.25 m cells from (-0.5, -0.5), a blocked border: free x up to
    -0.5 + 0.25 (width_cells - 1), free y in [-0.25, 1.75]."""
    cells = np.zeros((10, width_cells), dtype=np.int8)
    cells[0, :] = cells[-1, :] = cells[:, 0] = cells[:, -1] = 100
    return OccupancyMap.from_occupancy_grid(cells.ravel(), width_cells, 10, 0.25,
                                            (-0.5, -0.5, 0.0), source="/map").to_spec()


def record(path: Path, segments, drop_maps: bool = False) -> None:
    """Runs and records segments of (steps, {step: packed map}) separated by resets."""
    sim = sc.Simulator(SCENE, dt=DT, seed=SEED)
    meta = run_metadata(SCENE, sim, None, 1)
    dt_ns = topics.stamp_ns(DT)
    maps = 0
    with Recorder(path, metadata=meta, flush_interval_s=None) as rec:
        for name, msgtype in topics.TYPES.items():
            rec.add_channel("/" + name, msgtype)
        epoch, last = 0, 0
        for s, (steps, new_maps) in enumerate(segments):
            if s:
                epoch = last + dt_ns
                sim.reset()
                rec.add_metadata(f"reset_{s:06d}", {"log_time_ns": str(epoch),
                                                    "seed": str(sim.seed)})
            for k in range(steps + 1):
                last = epoch + topics.stamp_ns(sim.t)
                for name, data in topics.encode_state(sim.state).items():
                    rec.write("/" + name, last, data)
                if k in new_maps:
                    sim.set_scene(scene_with_map(SCENE, new_maps[k]))
                    maps += 1
                    if not drop_maps:
                        rec.add_metadata(f"map_{maps:06d}", {
                            "topic": "/map", "step": str(k), "t": repr(sim.t),
                            "log_time_ns": str(last), "map": json.dumps(new_maps[k])})
                if k < steps:
                    sim.step()


SEGMENTS = [(120, {20: room(12)}), (150, {60: room(16)})]


def test_maps_over_a_reset_replay_bit_for_bit(tmp_path: Path) -> None:
    f = tmp_path / "maps.mcap"
    record(f, SEGMENTS)
    res = replay.replay(f)
    assert res.identical, replay.format_replay(res)
    assert res.maps_applied == 2 and res.frames_compared == 121 + 151
    assert "2 map(s)" in replay.format_replay(res)
    meta = load_run(f)
    assert [(m.segment, m.step) for m in meta.maps] == [(0, 20), (1, 60)]
    sched = Schedule(meta)
    assert sched.map_at(0, 19) is None
    assert sched.map_at(0, 20) == sched.map_at(1, 59) == room(12)  # kept over the reset
    assert sched.map_at(1, 60) == room(16)


def test_a_recording_without_its_map_records_diverges(tmp_path: Path) -> None:
    """The maps matter: the crowd is held by the first map's east wall at x = 2.25."""
    f = tmp_path / "nomaps.mcap"
    record(f, SEGMENTS, drop_maps=True)
    res = replay.replay(f)
    assert not res.identical and res.divergence is not None
    assert res.divergence.segment == 0 and res.divergence.step > 20


def test_analyze_checks_the_walls_of_the_received_maps(tmp_path: Path) -> None:
    """sweep analyze holds each frame against the walls in effect at its step: the crowd
    pressed on the received map's east wall touches it, which the scene's own (no) walls
    cannot show; the same positions without the map records touch less."""
    from sweep_core.analysis.metrics import analyze

    with_maps, without = tmp_path / "maps.mcap", tmp_path / "nomaps.mcap"
    record(with_maps, SEGMENTS)
    record(without, SEGMENTS, drop_maps=True)
    a, b = analyze(with_maps), analyze(without)
    assert a.summary["touching"]["max"] > b.summary["touching"]["max"]
    assert a.summary["min_gap"]["min_m"] >= -1e-9
