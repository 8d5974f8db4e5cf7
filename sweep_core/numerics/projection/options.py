"""Settings of the projection's QP solve (validated like the scene) and the row tolerance."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sweep_core import checks
from sweep_core.errors import SceneError

#: largest row violation (m) accepted from the QP solver
ROW_TOLERANCE = 1e-9


@dataclass(frozen=True)
class SolverOptions:
    """Settings of the QP solve.

    eps_abs: proxsuite's absolute tolerance (m): bound on the row residuals and stationarity.
        Every row is tightened by eps_abs before the solve (a skin), so a solution within the
        tolerance still satisfies the untightened row: no overlap, not even of eps_abs.
    max_iter: proxsuite's iteration cap (backend "proxsuite").
    dense_fallback: clusters of up to this many variables (2 per agent) are retried with the
        active-set NNLS solver when the backend fails.
    backend: "clarabel" (default: interior point, robust in dense jams) or "proxsuite"
        (proxsuite 0.8.0 can stall inside its solve on degenerate jam QPs; see README).
    exact_vars: clusters of up to this many variables (2 per agent) are solved first by the
        exact active-set solver (:func:`sweep_core.numerics.projection.exact.ldp`), the backend
        only if it fails. Up to about 64
        agents that solver is also the faster one; above, it costs O(n^3) but is exact where
        the interior-point backend stops about 1e-6 m short in degenerate jams (README).
    """

    eps_abs: float = 1e-10
    max_iter: int = 1000
    dense_fallback: int = 4000
    backend: str = "clarabel"
    exact_vars: int = 128

    @classmethod
    def from_values(cls, eps_abs: float = 1e-10, max_iter: int = 1000,
                    backend: str = "clarabel", exact_vars: int = 128) -> SolverOptions:
        eps = checks.number(eps_abs, "solver.eps_abs", positive=True)
        if eps > 1e-9:
            raise SceneError("solver.eps_abs", f"{eps:g} m would allow overlaps above 1e-9 m",
                             "use eps_abs <= 1e-9")
        if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
            raise SceneError("solver.max_iter", f"must be a positive integer, got {max_iter!r}")
        if backend not in ("clarabel", "proxsuite"):
            raise SceneError("solver.backend", f"unknown backend {backend!r}",
                             "use 'clarabel' or 'proxsuite'")
        if (isinstance(exact_vars, bool) or not isinstance(exact_vars, (int, np.integer))
                or exact_vars < 0):
            raise SceneError("solver.exact_vars", f"must be an integer >= 0, got {exact_vars!r}",
                             "use 0 to send every cluster to the backend")
        return cls(eps, int(max_iter), backend=backend, exact_vars=int(exact_vars))


