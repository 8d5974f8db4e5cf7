"""sweep_core: the stochastic sweeping process for crowds of rigid disks.

    dq + N(Q(t), q) ∋ U(t, q) dt + sigma dB_t,  q(0) ∈ Q(t)

discretised by the projected Euler scheme on the linearised feasible set, one convex QP per
step. No ROS import anywhere in this package. See the README for the scene schema.
"""
from __future__ import annotations

from .errors import InfeasibleError, RecordingError, SceneError, SweepError
from .fields import FIELD_KINDS, Field, field_from_spec, grid_field
from .projection import SolverOptions
from .scene import Scene
from .schemes import SCHEMES, Scheme
from .simulator import State, Simulator
from .skorokhod import skorokhod

__version__ = "0.1.0"

__all__ = [
    "FIELD_KINDS", "Field", "InfeasibleError", "RecordingError", "SCHEMES", "Scene",
    "SceneError", "Scheme", "Simulator", "SolverOptions", "State", "SweepError",
    "__version__", "field_from_spec", "grid_field", "skorokhod",
]
