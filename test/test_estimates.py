"""Estimates that refuse work before it starts hold: each is checked against what the work
measurably takes on a small case scaled up, within a factor 1.5 either way.

- ``sweep render``'s GIF memory (:func:`sweep_core.analysis.render.gif_memory`) against the
  increase of the render's peak resident memory (Linux's VmHWM, reset before the render):
  the estimate of a byte per pixel per frame undercounted it about 3.4 times.
- ``sweep run``'s recording size (:func:`sweep_core.io.limits.check_run_size`) of a scene with
  a source against the bytes its recording holds: counting every agent the source may ever
  emit as present from the start overcounted it thousands of times.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from sweep_core.cli import main
from sweep_core.io import limits
from sweep_core.model.scene import load_scene
from sweep_core.model.yaml_files import dump_yaml

REPO = Path(__file__).resolve().parents[1]
#: an estimate and its measure agree within this factor either way
FACTOR = 1.5
ROOM = [{"kind": "polyline", "points": [[0, 0], [10, 0], [10, 4], [0, 4]], "closed": True}]
SOURCE = {"region": {"kind": "rectangle", "min": [0.3, 0.3], "max": [1.5, 3.7]},
          "rate": 10.0, "count": 100_000}
SCENE = {"name": "corridor",
         "agents": {"positions": [[5.0, 1.0], [5.0, 2.0], [6.0, 1.5]], "radius": 0.2},
         "walls": ROOM, "drift": {"kind": "goal", "goal": [9.5, 2.0], "speed": 1.3},
         "flows": {"sources": [SOURCE]}}


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory) -> Path:
    p = tmp_path_factory.mktemp("estimates") / "corridor.yaml"
    p.write_text(dump_yaml(SCENE))
    return p


def _env() -> dict[str, str]:
    return dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(REPO)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))


#: renders a GIF in a fresh process and prints the increase of its peak resident memory (MB)
#: over the render: a small render first (imports, kernels), then the peak reset
#: (/proc/self/clear_refs 5) and the render measured
GIF_RUN = """
import json, re, sys
from sweep_core.analysis.render import RenderOptions, gif_memory, render
def status(key):
    text = open("/proc/self/status").read()
    return int(re.search(key + r":\\s+(\\d+)", text).group(1)) * 1024
rec, out, size, frames = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
render(rec, out + ".warm.gif", RenderOptions(width=160, end=0.0), progress=False)
with open("/proc/self/clear_refs", "w") as f:
    f.write("5")
before = status("VmRSS")
render(rec, out, RenderOptions(width=size, height=size, end=(frames - 1) / 10, fps=10),
       progress=False)
print(json.dumps({"measured": status("VmHWM") - before,
                  "estimated": gif_memory(frames, (size, size))}))
"""


@pytest.mark.parametrize("size,frames", [(1200, 4), (1200, 16)])
def test_the_gif_memory_estimate_holds(scene_file, tmp_path, size, frames):
    """4 and 16 frames of 1200 x 1200 px: 43 and 78 MB estimated, 40-51 and 81 MB measured
    (the old estimate: 6 and 23 MB)."""
    run = tmp_path / "run.mcap"
    assert main(["run", str(scene_file), "--t-end", "2.0", "--dt", "0.05", "--out", str(run),
                 "--quiet"]) == 0
    done = subprocess.run([sys.executable, "-c", GIF_RUN, str(run), str(tmp_path / "a.gif"),
                           str(size), str(frames)], env=_env(), capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    got = json.loads(done.stdout.splitlines()[-1])
    ratio = got["estimated"] / got["measured"]
    assert 1 / FACTOR <= ratio <= FACTOR, got


def _payload_bytes(path: Path) -> int:
    """Bytes of the recorded states: the /poses and /agents payloads (the estimate adds about
    31 bytes of MCAP record to each)."""
    total = 0
    with open(path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages():
            if channel.topic in ("/poses", "/agents"):
                total += len(message.data)
    return total


def test_the_recording_estimate_counts_source_agents_when_they_enter(scene_file, tmp_path,
                                                                     capsys):
    """A source of 100 000 agents at 10 agents/s over 3 s: about 30 enter. Before: the
    estimate counted all 100 003 agents in every state."""
    scene = load_scene(str(scene_file))
    assert scene.flows is not None
    entries = np.concatenate([s.times for s in scene.flows.sources])
    size = limits.check_run_size(scene.n_agents, 0.05, 3.0, 2, entries=entries)
    run = tmp_path / "run.mcap"
    assert main(["run", str(scene_file), "--t-end", "3.0", "--dt", "0.05", "--record-every",
                 "2", "--out", str(run), "--quiet"]) == 0
    capsys.readouterr()
    measured = _payload_bytes(run)
    assert 1 / FACTOR <= size.recording_bytes / measured <= FACTOR, (size, measured)
