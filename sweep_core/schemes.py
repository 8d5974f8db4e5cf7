"""Time-stepping schemes, registered by name in :data:`SCHEMES`.

A scheme maps the state at t_n to the state at t_{n+1} = t_n + h. The base class owns the
template (prediction, projection, bookkeeping); a scheme subclass provides ``predict`` and may
override ``_step``. What a subclass must provide:

* ``name``: the registry key;
* ``predict(t, q, h, dB) -> (N, 2)``: the unconstrained update;
* optionally ``_step`` for schemes that are not predict-then-project.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .projection import Projection, SolverOptions, project
from .scene import Scene


@dataclass(frozen=True)
class StepResult:
    """One step: q_new (N, 2) m, prediction (N, 2) m, projection details."""

    q_new: np.ndarray
    prediction: np.ndarray
    projection: Projection


class Scheme:
    """Base class of the schemes; see the module docstring."""

    name = ""

    def __init__(self, scene: Scene, solver: SolverOptions) -> None:
        self.scene = scene
        self.solver = solver

    def predict(self, t: float, q: np.ndarray, h: float, dB: np.ndarray | None,
                drift, sigma: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def step(self, t: float, q: np.ndarray, h: float, dB: np.ndarray | None, drift,
             sigma: np.ndarray) -> StepResult:
        """Advance from (t, q) by h with Brownian increments dB (N, 2) or None (sigma = 0)."""
        pred = self.predict(t, q, h, dB, drift, sigma)
        t1 = t + h
        proj = project(self.scene.geometry, t1, q, pred, self.scene.radii(t1), self.solver)
        return StepResult(proj.y, pred, proj)


class ProjectedEuler(Scheme):
    """q_{n+1} = P_{C~(t_{n+1}, q_n)}[q_n + h U(t_n, q_n) + sigma (B_{n+1} - B_n)] (reference §4)."""

    name = "projected_euler"

    def predict(self, t: float, q: np.ndarray, h: float, dB: np.ndarray | None, drift,
                sigma: np.ndarray) -> np.ndarray:
        pred = q.copy() if drift.is_zero else q + h * drift(t, q)
        if dB is not None:
            pred += sigma[:, None] * dB
        return pred


#: registry of schemes by name
SCHEMES: dict[str, type[Scheme]] = {ProjectedEuler.name: ProjectedEuler}
