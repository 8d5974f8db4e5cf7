"""The deterministic Skorokhod problem, solved by catching-up on a time grid (reference §1, §5)."""
from __future__ import annotations

import numpy as np

from sweep_core import checks
from sweep_core.errors import SceneError
from sweep_core.model.gaps import gaps
from sweep_core.model.scene import Scene
from sweep_core.numerics.projection import SolverOptions, project


def skorokhod(scene: Scene, path: np.ndarray, times: np.ndarray,
              solver: SolverOptions | None = None) -> np.ndarray:
    """Catching-up solution x of x + k = h on the grid ``times`` (s), shape (T,).

    path: (T, N, 2) values of the driving path h (m) at ``times``; h(times[0]) must lie in
    Q(times[0]). Returns x, shape (T, N, 2), with
    x_{k+1} = P_{C~(t_{k+1}, x_k)}[x_k + h_{k+1} - h_k]. For one agent at a flat wall this is
    exactly the Skorokhod map of the grid path.
    """
    n = scene.n_agents
    times = checks.array(times, "times", (None,))
    path = checks.array(path, "path", (len(times), n, 2), "(len(times), N, 2)")
    if len(times) > 1 and np.any(np.diff(times) <= 0):
        raise SceneError("times", "must be strictly increasing")
    solver = solver or SolverOptions()
    out = np.empty_like(path)
    if len(times) == 0:
        return out
    x = path[0].copy()
    g = gaps(scene.geometry, float(times[0]), x, scene.radii(float(times[0])))
    if g.min_gap < -1e-9:
        raise SceneError("path", f"path[0] is not feasible (gap {g.min_gap:.3g} m)",
                         "start the path inside the feasible set")
    out[0] = x
    for k in range(1, len(times)):
        t1 = float(times[k])
        x = project(scene.geometry, t1, x, x + path[k] - path[k - 1], scene.radii(t1), solver).y
        out[k] = x
    return out
