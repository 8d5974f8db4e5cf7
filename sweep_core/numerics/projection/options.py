"""Settings of the projection's QP solve (validated like the scene) and the row tolerance."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import qpsolvers

from sweep_core import checks
from sweep_core.errors import SceneError

#: largest row violation (m) accepted from the QP solver
ROW_TOLERANCE = 1e-9


#: other names of backends: proxsuite's QP solver is qpsolvers' "proxqp"
ALIASES = {"proxsuite": "proxqp"}


def available_backends() -> list[str]:
    """The QP solvers installed here that can be the backend (qpsolvers' names, sorted;
    clarabel and piqp are dependencies, so always there)."""
    return sorted(set(qpsolvers.available_solvers) | {"clarabel", "piqp"})


def check_backend(name: object, field: str = "solver.backend") -> str:
    """The backend's qpsolvers name if it is installed (aliases resolved); SceneError naming
    the field, the value and the installed solvers if not."""
    names = available_backends()
    key = ALIASES.get(name, name) if isinstance(name, str) else name
    if not isinstance(key, str) or key not in names:
        raise SceneError(field, f"{name!r} is not an installed QP solver",
                         f"use one of {', '.join(names)} (or pip install another solver "
                         "that qpsolvers supports)")
    return key


#: methods of the projection: the certified compiled solver, or the cluster solvers alone
METHODS = ("certified", "clusters")


@dataclass(frozen=True)
class SolverOptions:
    """Settings of the projection (the QP of one step).

    tol: the certified accuracy (m): every step's answer y is within tol of the exact projection
        onto the linearised set, proved by a duality-gap certificate (``Projection.bound``).
        Clusters the compiled solver cannot certify within ``max_rounds`` go to the exact or
        the interior-point solver, whose answer is certified the same way (the bound is
        reported even where it exceeds tol). Feasibility does not depend on tol: every row
        holds to ``ROW_TOLERANCE`` whatever it is.
    max_rounds: cap on the rounds of the certified solver in one step (a round: 10 projected
        Gauss-Seidel sweeps and one conjugate-gradient face step on the dual; the rounds also
        stop after 10 without progress). 0 sends every cluster to the cluster solvers.
    warm_start: start each step from the previous step's multipliers, matched by contact.
    method: "certified" (default: compiled sweeps, then the cluster solvers where needed) or
        "clusters" (the cluster solvers alone: closed form, active set, interior point).
    eps_abs: skin (m) the interior-point and proxsuite backends tighten every row by, so an
        answer within their tolerance still satisfies the untightened row.
    max_iter: proxqp's iteration cap (backend "proxqp").
    dense_fallback: clusters of up to this many variables (2 per agent) are retried with the
        exact active-set solver when the backend fails. Its cost grows as the cube of the
        cluster's size (about 0.2 s at 512 variables, 1 to 5 s at 2000), so above 512
        variables it runs only when the backend gave no answer whose rows hold (a feasible
        reduced-accuracy answer is kept, its bound reported).
    backend: the QP solver of the clusters the exact solver does not take (larger than
        ``exact_vars``, or past its step cap), through qpsolvers: any installed solver
        (:func:`available_backends`; "proxsuite" is read as "proxqp"). "piqp" (default,
        proximal interior point, its baseline build: the same bits on every x86-64 CPU): on
        the 1000-agent evacuation jam it solves the cluster 1.6 to 2.7 times faster than
        Clarabel and held its rows at the 1e-12 m skin on every measured step, where Clarabel
        broke some (docs/performance.md has the bench's table).
    exact_vars: clusters of up to this many variables (2 per agent) that reach the cluster
        solvers are solved first by the exact active-set solver
        (:func:`sweep_core.numerics.projection.active.solve`, steps capped at 3 per row plus
        one per variable), the backend only if it fails or hits the cap. 256 (128 agents):
        there it costs a few times the interior point (4-7 ms against 8 at 64 agents of a
        hexagonal jam, 35-50 ms against 11 at 120, on a loaded 2-core machine), and it gives
        degenerate clusters, which the certified rounds leave, an answer certified to the
        tolerance instead of Clarabel's 1e-5 to 1e-4 m.
    """

    eps_abs: float = 1e-10
    max_iter: int = 1000
    dense_fallback: int = 4000
    backend: str = "piqp"
    exact_vars: int = 256
    tol: float = 1e-6
    max_rounds: int = 200
    warm_start: bool = True
    method: str = "certified"

    @classmethod
    def from_values(cls, eps_abs: float = 1e-10, max_iter: int = 1000,
                    backend: str = "piqp", exact_vars: int = 256, tol: float = 1e-6,
                    max_rounds: int = 200, warm_start: bool = True,
                    method: str = "certified") -> SolverOptions:
        """Validated options; SceneError names the field, the value and the fix."""
        eps = checks.number(eps_abs, "solver.eps_abs", positive=True)
        if eps > 1e-9:
            raise SceneError("solver.eps_abs", f"{eps:g} m would allow overlaps above 1e-9 m",
                             "use eps_abs <= 1e-9")
        tol_ = checks.number(tol, "solver.tol", positive=True)
        if not 1e-12 <= tol_ <= 1.0:
            raise SceneError("solver.tol", f"{tol_:g} m is outside [1e-12, 1] m",
                             "use e.g. 1e-6 (the default) or 1e-4 for speed")
        backend = check_backend(backend)
        if method not in METHODS:
            raise SceneError("solver.method", f"unknown method {method!r}",
                             f"use one of {list(METHODS)}")
        if not isinstance(warm_start, (bool, np.bool_)):
            raise SceneError("solver.warm_start", f"must be true or false, got {warm_start!r}")
        max_iter = checks.integer(max_iter, "solver.max_iter", low=1, fix="use e.g. 1000")
        exact_vars = checks.integer(exact_vars, "solver.exact_vars",
                                    fix="use 0 to send every cluster to the backend")
        max_rounds = checks.integer(max_rounds, "solver.max_rounds",
                                    fix="use e.g. 200, or 0 to skip the rounds")
        return cls(eps, max_iter, backend=backend, exact_vars=exact_vars, tol=tol_,
                   max_rounds=max_rounds, warm_start=bool(warm_start), method=method)
