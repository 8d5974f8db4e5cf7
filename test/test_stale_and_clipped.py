"""Smaller reliability items, each failing on the code before its fix.

- A source region crossed by a wall is refused: part of it lies outside the room, and the
  source placed agents there, where they stayed.
- A run to an ``--out`` of an earlier run removes that run's ``OUT.summary.json`` before
  the new recording is opened (which empties it): a kill -9 of the rerun left the earlier
  summary ("completed") beside the new, cut-short recording, also when it came between the
  opening and the first recorded state.
"""
from __future__ import annotations

import copy
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from sweep_core import Scene, SceneError, Simulator
from sweep_core.cli import main
from sweep_core.model.yaml_files import dump_yaml

REPO = Path(__file__).resolve().parents[1]
ROOM = [{"kind": "polyline", "points": [[0, 0], [10, 0], [10, 4], [0, 4]], "closed": True}]
SOURCE = {"region": {"kind": "rectangle", "min": [0.3, 0.3], "max": [1.5, 3.7]},
          "rate": 4.0, "count": 8}


def corridor(source: dict) -> dict:
    return {"name": "corridor",
            "agents": {"positions": [[5.0, 1.0], [5.0, 2.0], [6.0, 1.5]], "radius": 0.2},
            "walls": copy.deepcopy(ROOM), "drift": {"kind": "goal", "goal": [9.5, 2.0],
                                                     "speed": 1.3},
            "flows": {"sources": [source]}}


@pytest.mark.parametrize("region,wall", [
    ({"kind": "rectangle", "min": [-3.0, 0.3], "max": [1.5, 3.7]}, "walls[0] (polyline piece 3)"),
    ({"kind": "polygon", "points": [[8.0, 1.0], [12.0, 1.0], [12.0, 3.0], [8.0, 3.0]]},
     "walls[0] (polyline piece 1)"),
    ({"kind": "rectangle", "min": [4.0, 3.0], "max": [5.0, 6.0]}, "walls[0] (polyline piece 2)"),
])
def test_a_source_region_partly_outside_the_room_is_refused(region, wall):
    with pytest.raises(SceneError) as err:
        Scene.from_dict(corridor({**SOURCE, "region": region}))
    assert err.value.field == "flows.sources[0].region" and wall in err.value.problem
    assert "inside the room" in err.value.fix


@pytest.mark.parametrize("region", [
    {"kind": "rectangle", "min": [0.0, 0.0], "max": [1.5, 4.0]},  # on the walls: not across
    {"kind": "rectangle", "min": [0.3, 0.3], "max": [1.5, 3.7]},
])
def test_a_source_region_inside_the_room_emits_inside_it(region):
    scene = Scene.from_dict(corridor({**SOURCE, "region": region}))
    sim = Simulator(scene, dt=0.05, seed=1)
    for _ in range(40):
        sim.step()
    q = sim.state.positions
    assert len(q) > 3 and np.all((q > 0) & (q < [10.0, 4.0]))


def _env() -> dict[str, str]:
    return dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(REPO)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))


def test_a_rerun_killed_leaves_no_summary_of_the_earlier_run(tmp_path):
    """The earlier run's summary says "completed"; the rerun is killed (SIGKILL) once its
    recording holds states: no summary may describe the cut-short recording."""
    scene = tmp_path / "scene.yaml"
    data = corridor(SOURCE)
    data.pop("flows")
    scene.write_text(dump_yaml(data))
    out, summary = tmp_path / "run.mcap", tmp_path / "run.summary.json"
    cmd = [sys.executable, "-m", "sweep_core.cli", "run", str(scene), "--dt", "0.01",
           "--out", str(out), "--quiet"]
    first = subprocess.run([*cmd, "--t-end", "0.1"], env=_env(), capture_output=True,
                           text=True, timeout=600)
    assert first.returncode == 0, first.stderr
    assert json.loads(summary.read_text())["status"] == "completed"
    size = out.stat().st_size
    rerun = subprocess.Popen([*cmd, "--t-end", "10000", "--force", "--overwrite"], env=_env(),
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        # the rerun's recording replaces the earlier one at its first flush (a new file
        # written at the name); it then holds states of the rerun
        end = time.monotonic() + 300
        while time.monotonic() < end and rerun.poll() is None:
            if out.exists() and out.stat().st_size != size and out.stat().st_size > 4096:
                break
            time.sleep(0.1)
        assert rerun.poll() is None, "the rerun ended before it was killed"
    finally:
        rerun.send_signal(signal.SIGKILL)
        rerun.wait()
    assert not summary.exists(), summary.read_text()


#: runs ``sweep run`` with the process killed (os._exit, as SIGKILL: nothing cleaned up) right
#: after the recording is opened, which empties it, before any state is recorded
KILLED_AT_OPEN = """
import os, sys
from sweep_core.io.recording import runs
opened = runs.BackgroundRecorder.__enter__
def enter(self):
    opened(self)
    os._exit(9)
runs.BackgroundRecorder.__enter__ = enter
from sweep_core.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_a_rerun_killed_as_its_recording_opens_leaves_no_summary(tmp_path):
    """The rerun is killed once its recording is opened (emptied) and before its first state
    is recorded, the seconds a large scene's walls and navigation field take: the earlier
    run's summary ("completed") went only with the first recorded state, and stayed beside
    the emptied recording."""
    scene = tmp_path / "scene.yaml"
    data = corridor(SOURCE)
    data.pop("flows")
    scene.write_text(dump_yaml(data))
    out, summary = tmp_path / "run.mcap", tmp_path / "run.summary.json"
    args = ["run", str(scene), "--dt", "0.01", "--t-end", "0.05", "--out", str(out), "--quiet"]
    assert main(args) == 0
    assert json.loads(summary.read_text())["status"] == "completed"
    size = out.stat().st_size
    killed = subprocess.run([sys.executable, "-c", KILLED_AT_OPEN, *args, "--overwrite"],
                            env=_env(), capture_output=True, text=True, timeout=600)
    assert killed.returncode == 9, killed.stderr
    assert out.stat().st_size < size  # emptied: the earlier recording is gone
    assert not summary.exists(), summary.read_text()
