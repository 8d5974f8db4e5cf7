"""Brownian paths drawn at a fine resolution, so runs at different time steps share one path.

The simulator draws one increment per step, so a dt = 0.01 run and a dt = 0.001 run with the
same seed see different Brownian paths. Here the path is drawn at a fine resolution
``path_dt`` (the same draws, in the same order, as a plain run at ``dt = path_dt``) and each
coarse increment is the sum of the m = dt / path_dt fine increments of its step:

    B_{n+1} - B_n = sum_{j < m} sqrt(path_dt) Z_{n m + j},   Z ~ N(0, I) from PCG64(seed)

With m = 1 the increments are bit for bit those of a plain run (``noise.increments``), so
``--path-dt`` equal to ``--dt`` changes nothing. As in the simulator, nothing is drawn for a
step whose sigma is zero everywhere. The coarse increments are the fine path's increments up
to rounding (about 1e-16 relative), which is what ``sweep compare`` needs for a pathwise error.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from sweep_core import checks
from sweep_core.errors import SceneError
from sweep_core.numerics import noise
from sweep_core.numerics.simulator import Simulator

#: relative tolerance on dt / path_dt being an integer
_RATIO_TOL = 1e-9


def substeps(dt: float, path_dt: float) -> int:
    """m = dt / path_dt, which must be a positive integer (up to 1e-9 relative)."""
    dt = checks.number(dt, "dt", positive=True)
    path_dt = checks.number(path_dt, "path_dt", positive=True)
    m = int(round(dt / path_dt))
    if m < 1 or abs(m * path_dt - dt) > _RATIO_TOL * dt:
        raise SceneError("path_dt", f"dt = {dt:g} s is not a whole multiple of path_dt = "
                         f"{path_dt:g} s", "choose path_dt = dt / m for an integer m >= 1")
    return m


class FinePath:
    """Increments over steps of ``dt`` of a Brownian path drawn at resolution ``path_dt``.

    Args:
        seed: seed of the path (the simulator's seed).
        dt: the run's step, s.
        path_dt: the resolution the path is drawn at, s (dt / path_dt a whole number).
        n_agents: N; each increment has shape (N, 2).
    """

    def __init__(self, seed: int, dt: float, path_dt: float, n_agents: int) -> None:
        self.m = substeps(dt, path_dt)
        self.seed = int(seed)
        self.dt = float(dt)
        self.path_dt = float(path_dt)
        self.n_agents = int(n_agents)
        self.reset()

    def reset(self) -> None:
        """Back to the start of the path."""
        self._rng = noise.generator(self.seed)

    def increment(self) -> np.ndarray:
        """The next coarse increment, shape (N, 2)."""
        z = self._rng.standard_normal((self.m, self.n_agents, 2))
        if self.m == 1:
            return np.sqrt(self.dt) * z[0]  # exactly noise.increments(rng, dt, N)
        return np.sqrt(self.path_dt) * z.sum(axis=0)


def step(sim: Simulator, path: FinePath) -> None:
    """One step of ``sim`` driven by the next increment of ``path`` (none if sigma = 0)."""
    if np.any(sim.sigma):
        sim.step(1, dB=path.increment())
    else:
        sim.step(1)


def run(sim: Simulator, t_end: float, path_dt: float, progress: bool = False,
        callback: Callable[[Simulator], None] | None = None) -> FinePath:
    """Like ``Simulator.run``, with the Brownian path drawn at ``path_dt`` (see module doc).

    Starts the path at the simulator's seed; ``sim`` must be at t = 0. Returns the path.
    """
    if sim.n_steps:
        raise SceneError("path_dt", f"the simulator is at step {sim.n_steps}, not at t = 0",
                         "call sim.reset() first")
    flows = sim.scene.flows
    if flows is not None and flows.changes_population:
        raise SceneError("path_dt", f"{path_dt:g} s is given for a scene whose flows (sinks, "
                         "sources) change the agents: a fine path holds a fixed number of them",
                         "run it without --path-dt")
    path = FinePath(sim.seed, sim.dt, path_dt, sim.scene.n_agents)
    sim.run(t_end, progress=progress, callback=callback, increments=path.increment)
    return path
