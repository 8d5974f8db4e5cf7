"""sweep_core: the stochastic sweeping process for crowds of rigid disks.

    dq + N(Q(t), q) ∋ U(t, q) dt + sigma dB_t,  q(0) ∈ Q(t)

discretised by the projected Euler scheme on the linearised feasible set, one convex QP per
step. No ROS import anywhere in this package. The scene schema: docs/schema.md.
"""
from __future__ import annotations

from sweep_core.errors import InfeasibleError, RecordingError, SceneError, SweepError
from sweep_core.model.drift import field_from_spec
from sweep_core.model.fields import FIELD_KINDS, Field, grid_field
from sweep_core.model.scene import Scene
from sweep_core.numerics.projection import SolverOptions
from sweep_core.numerics.schemes import SCHEMES, Scheme
from sweep_core.numerics.simulator import Simulator, State
from sweep_core.numerics.skorokhod import skorokhod

__version__ = "0.2.2"

__all__ = [
    "FIELD_KINDS", "Field", "InfeasibleError", "RecordingError", "SCHEMES", "Scene",
    "SceneError", "Scheme", "Simulator", "SolverOptions", "State", "SweepError",
    "__version__", "field_from_spec", "grid_field", "skorokhod",
]
