"""The metadata record ``sweep_ros`` that makes a recording re-simulable (``sweep replay``)."""
from __future__ import annotations

import json
from dataclasses import asdict

from sweep_core.io.versions import versions
from sweep_core.model.scene import Scene
from sweep_core.numerics.simulator import Simulator


def run_metadata(scene: Scene, sim: Simulator, t_end: float | None,
                 record_every: int | None = None) -> dict[str, str]:
    """What a recording needs to be re-simulated: scene, seed, dt, scheme, solver, versions."""
    return {"scene": scene.to_yaml(), "seed": str(sim.seed), "dt": repr(sim.dt),
            "t_end": "" if t_end is None else repr(t_end),
            "record_every": "" if record_every is None else str(record_every),
            "scheme": sim.scheme.name,
            "solver": json.dumps(asdict(sim.scheme.solver)), "versions": json.dumps(versions())}
