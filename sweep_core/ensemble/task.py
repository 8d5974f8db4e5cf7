"""One run of an ensemble, as a Dask worker executes it: scene, simulator, recording, metrics.

The run is built exactly as ``sweep run`` builds it (``Scene.from_dict`` of the scene's dict,
``Simulator(scene, dt, seed, scheme, SolverOptions())``, every step recorded to MCAP with the
same metadata record) and its metrics are those of ``sweep analyze``: the recording is written
to a temporary MCAP file on the worker (or into DIR with ``record="full"``) and read back by
:func:`sweep_core.analysis.metrics.analyze`. So run k of an ensemble has the final positions and
metrics of ``sweep run --seed seed0+k`` bit for bit, on any worker.

Every exception of the run is caught and returned as a row with status ``failed`` and its
message: a failing run never stops the ensemble.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import socket
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sweep_core.analysis.metrics import analyze
from sweep_core.analysis.report import jsonable
from sweep_core.errors import SweepError
from sweep_core.io.metadata import run_metadata
from sweep_core.io.recording import runs
from sweep_core.model.scene import Scene
from sweep_core.numerics.projection import SolverOptions
from sweep_core.numerics.simulator import Simulator

#: what a run leaves: rows only; rows with analyze's whole summary; also its MCAP file
RECORD = ("none", "summary", "full")
#: leaves of ``sweep analyze``'s summary kept in a row (numbers only; "section.key")
SKIP = ("recording", "read_until", "scene", "truncated", "dt_s", "last_step", "t_last_s",
        "segments", "commands", "contacts.tolerance_m", "density.x0_m", "density.y0_m",
        "density.cell_m", "density.shape", "flow.line", "arrivals.radius_m")


@dataclass
class Task:
    """What a worker needs for one run (plain data, pickled to the worker).

    spec: the scene dict with the grid point applied; name: the scene's name; seed, dt (s),
    scheme, t_end (s); line (m) and arrive_radius (m) as in ``sweep analyze``; mcap: the file to
    keep (``record="full"``) or None (a temporary file, deleted); marker: a file the client
    created in DIR, that the worker must see before it writes there (a shared DIR);
    summary: return the whole analysis summary as JSON too.
    """

    spec: dict
    name: str
    seed: int
    dt: float
    scheme: str
    t_end: float
    line: tuple[float, float, float, float] | None = None
    arrive_radius: float | None = None
    mcap: str | None = None
    marker: str | None = None
    summary: bool = False


def flatten(summary: dict, prefix: str = "") -> dict[str, float]:
    """The numeric leaves of an analysis summary as ``section.key`` -> float (None -> NaN,
    True / False -> 1 / 0)."""
    out: dict[str, float] = {}
    for key, value in summary.items():
        name = prefix + key
        if name in SKIP or key == "precision" or key == "between":
            continue
        if isinstance(value, dict):
            out.update(flatten(value, name + "."))
        elif value is None:
            out[name] = math.nan
        elif isinstance(value, bool):  # e.g. a robot's success: 1 or 0, its mean a rate
            out[name] = float(value)
        elif isinstance(value, (int, float)):
            out[name] = value
    return out


def record_run(sim: Simulator, scene: Scene, t_end: float, out: Path) -> None:
    """Steps ``sim`` to ``t_end`` s recording every step to ``out`` as ``sweep run`` does
    (record_every 1, frame ``map``, the same metadata and status records); raises what
    ended the run if it did not complete."""
    meta = run_metadata(scene, sim, t_end, 1)
    meta["path_dt"] = ""
    run = runs.record_run(sim, t_end, out, meta)
    if run.failure is not None:
        raise run.failure


def digest(q: np.ndarray) -> str:
    """SHA-256 of positions as float64 C-order bytes (equal digests: bit-equal positions)."""
    return hashlib.sha256(np.ascontiguousarray(q, dtype=np.float64).tobytes()).hexdigest()


def message(err: BaseException) -> str:
    """One line: a sweep error's own message, otherwise ``Type: message``."""
    text = str(err) if isinstance(err, SweepError) else f"{type(err).__name__}: {err}"
    return " ".join(text.split())


def simulate(task: Task) -> dict[str, Any]:
    """Runs one task; returns its row (status ``ok`` or ``failed``, never raises)."""
    start = time.perf_counter()
    row: dict[str, Any] = {"status": "ok", "error": None, "worker": _worker_name(),
                           "t_reached_s": math.nan, "final_sha256": None}
    tmp = None
    sim = None
    try:
        if task.mcap is not None:
            if task.marker is not None and not os.path.exists(task.marker):
                raise SweepError(
                    f"--record full: the output directory {str(Path(task.marker).parent)!r} is "
                    f"not visible on worker {row['worker']} (fix: mount it at the same path on "
                    "every worker, or use --record summary)")
            out = Path(task.mcap)
        else:
            tmp = tempfile.mkdtemp(prefix="sweep-ensemble-")
            out = Path(tmp) / "run.mcap"
        scene = Scene.from_dict(task.spec, name=task.name)
        sim = Simulator(scene, dt=task.dt, seed=task.seed, scheme=task.scheme,
                        solver=SolverOptions())
        scene.check_horizon(task.t_end)
        record_run(sim, scene, task.t_end, out)
        row["t_reached_s"] = sim.t
        row["final_sha256"] = digest(sim.positions)
        an = analyze(out, line=task.line, arrive_radius=task.arrive_radius)
        row.update(flatten(an.summary))
        if task.summary:
            row["summary_json"] = json.dumps(jsonable(an.summary))
    except Exception as err:  # noqa: BLE001 - any failure is this run's row, never the ensemble's
        row["status"] = "failed"
        row["error"] = message(err)
        if sim is not None:
            row["t_reached_s"] = sim.t
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    row["wall_time_s"] = time.perf_counter() - start
    return row


def _worker_name() -> str:
    try:
        from distributed import get_worker
        return str(get_worker().address)
    except (ImportError, ValueError):
        return socket.gethostname()
