"""The metadata record ``sweep_ros`` that makes a recording re-simulable (``sweep replay``)."""
from __future__ import annotations

import json
from dataclasses import asdict

from sweep_core.io.versions import platform_record, versions
from sweep_core.model.scene import Scene
from sweep_core.numerics.simulator import Simulator


def run_metadata(scene: Scene, sim: Simulator, t_end: float | None,
                 record_every: int | None = None) -> dict[str, str]:
    """What a recording needs to be re-simulated: scene, seed, dt, scheme, solver, versions,
    and the platform it was made on (``sweep replay`` elsewhere names the differences)."""
    return {"scene": scene.to_json(), "seed": str(sim.seed), "dt": repr(sim.dt),
            "t_end": "" if t_end is None else repr(t_end),
            "record_every": "" if record_every is None else str(record_every),
            "scheme": sim.scheme.name,
            "solver": json.dumps(asdict(sim.scheme.solver)), "versions": json.dumps(versions()),
            "platform": json.dumps(platform_record())}


#: name of the metadata record that says how a run ended; written last, before the summary
STATUS_RECORD = "sweep_status"
#: the values of its ``status`` key
STATUSES = ("completed", "interrupted", "failed")
#: name of the metadata record ``sweep recover`` adds to the copy it writes
RECOVER_RECORD = "sweep_recover"


def status_metadata(status: str, *, steps: int, t: float, error: str = "") -> dict[str, str]:
    """The ``sweep_status`` record: ``status`` (completed, interrupted or failed), ``error``
    (what stopped the run: the signal or the error message; empty when completed), ``steps``
    taken and the simulated time ``t_s`` reached (s)."""
    if status not in STATUSES:
        raise ValueError(f"status: {status!r} is not one of {STATUSES}")
    return {"status": status, "error": error, "steps": str(steps), "t_s": repr(float(t))}


def describe_status(metadata: dict[str, dict[str, str]], truncated: bool) -> str:
    """One line saying how the run of a recording ended, from its ``sweep_status`` record:
    ``completed``, ``interrupted (SIGTERM)``, ``failed (no feasible ...)`` or ``unknown (...)``
    when the record is missing (cut short, or written by a version without it)."""
    rec = metadata.get(STATUS_RECORD)
    if rec is None:
        if truncated:
            return "unknown (no status record: the run was cut short)"
        if RECOVER_RECORD in metadata:
            return "unknown (no status record: the run was cut short, then recovered)"
        return "unknown (no status record: written by a version of sweep without one)"
    status = rec.get("status", "") or "unknown"
    error = rec.get("error", "")
    return f"{status} ({error})" if error else status
