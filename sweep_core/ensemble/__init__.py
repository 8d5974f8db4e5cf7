"""Monte Carlo ensembles on Dask's ``distributed``: seeded runs x a grid of scene keys and run
options, one row of ``sweep analyze`` metrics per run (:func:`run`, ``sweep ensemble``).

Modules: :mod:`.grid` (``--vary`` keys and the grid), :mod:`.task` (one run on a worker),
:mod:`.cluster` (LocalCluster, a scheduler's address or a given Client), :mod:`.store` (the
output directory, resume, summary statistics), :mod:`.plots`, :mod:`.runner` (:func:`run`).

``run`` is imported on first use, so ``sweep`` and the workers' task module do not import
pandas and distributed until an ensemble runs.
"""
from __future__ import annotations

from typing import Any

__all__ = ["run"]


def __getattr__(name: str) -> Any:
    if name == "run":
        from sweep_core.ensemble.runner import run
        return run
    raise AttributeError(f"module 'sweep_core.ensemble' has no attribute {name!r}")
