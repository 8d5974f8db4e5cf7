"""sweep_core: the stochastic sweeping process for crowds of rigid disks.

    dq + N(Q(t), q) ∋ U(t, q) dt + sigma dB_t,  q(0) ∈ Q(t)

discretised by the projected Euler scheme on the linearised feasible set, one convex QP per
step. No ROS import anywhere in this package. The scene schema: docs/schema.md.

The public API below is imported on first use (PEP 562), so that importing a light module of
the package (the command line's parser, the errors) does not load the engine.
"""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from sweep_core.errors import InfeasibleError, RecordingError, SceneError, SweepError
from sweep_core.version import __version__

if TYPE_CHECKING:
    from sweep_core.model.drift import field_from_spec
    from sweep_core.model.fields import FIELD_KINDS, Field, grid_field
    from sweep_core.model.scene import Scene
    from sweep_core.numerics.projection import SolverOptions
    from sweep_core.numerics.schemes import SCHEMES, Scheme
    from sweep_core.numerics.simulator import Simulator, State
    from sweep_core.numerics.skorokhod import skorokhod

#: public name -> the module that defines it
_LAZY = {
    "field_from_spec": "sweep_core.model.drift",
    "FIELD_KINDS": "sweep_core.model.fields", "Field": "sweep_core.model.fields",
    "grid_field": "sweep_core.model.fields",
    "Scene": "sweep_core.model.scene",
    "SolverOptions": "sweep_core.numerics.projection",
    "SCHEMES": "sweep_core.numerics.schemes", "Scheme": "sweep_core.numerics.schemes",
    "Simulator": "sweep_core.numerics.simulator", "State": "sweep_core.numerics.simulator",
    "skorokhod": "sweep_core.numerics.skorokhod",
}

__all__ = [
    "FIELD_KINDS", "Field", "InfeasibleError", "RecordingError", "SCHEMES", "Scene",
    "SceneError", "Scheme", "Simulator", "SolverOptions", "State", "SweepError",
    "__version__", "field_from_spec", "grid_field", "skorokhod",
]


def __getattr__(name: str) -> Any:
    """The public API's engine names, imported when first asked for."""
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'sweep_core' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
