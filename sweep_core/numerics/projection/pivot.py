"""The PIQP backend (proximal interior point, sparse) for one cluster QP, in its baseline build.

PIQP's Python package ships three builds of the same solver (baseline x86-64, AVX2, AVX-512)
and imports the widest one the CPU offers; their answers differ in the last bits (measured
1e-17 m on 1000-agent jams), so a run handed to the backend would depend on the CPU. This
module loads the baseline build by name: the same bits on every x86-64 CPU, at the same speed
(within a few per cent on those jams). Settings are :data:`.backends.SETTINGS` ["piqp"].
"""
from __future__ import annotations

import importlib
from types import ModuleType

import numpy as np
import scipy.sparse as sp

from sweep_core.numerics.projection.options import SolverOptions

#: PIQP's settings: its tolerances at 1e-11, absolute, with the duality gap checked (the
#: refinement takes the answer from there; at 1e-10 one step of the 1000-agent door run in
#: 500 ended 6.5e-6 m from certain, at 1e-11 none); its proximal regularisation allowed down to
#: 1e-11 (PIQP's default stops at 1e-10): on jams of equal disks, whose active rows outnumber
#: the coordinates, the default's last iterations crawl (18 to 42 iterations on captured
#: 1000-agent door QPs, 20 to 30 with 1e-11 or 1e-12; at 1e-13 the refined answers of two
#: steps in 500 lost their certificate)
SETTINGS: dict[str, float | bool | int] = {
    "eps_abs": 1e-11, "eps_rel": 0.0, "eps_duality_gap_abs": 1e-11,
    "eps_duality_gap_rel": 0.0, "check_duality_gap": True, "max_iter": 250,
    "reg_lower_limit": 1e-11}


def baseline() -> ModuleType:
    """PIQP's baseline build (``piqp.piqp_python``); ImportError if PIQP is not installed."""
    importlib.import_module("piqp")
    return importlib.import_module("piqp.piqp_python")


def solve_piqp(target: np.ndarray, c: sp.spmatrix, b: np.ndarray, opts: SolverOptions
               ) -> tuple[np.ndarray, np.ndarray, bool]:
    """min 1/2 |x - target|^2 s.t. c x >= b + eps_abs (the skin) by PIQP's baseline build:
    x (n,), multipliers (m,) >= 0 and whether it solved the QP."""
    n, m = c.shape[1], c.shape[0]
    if m == 0:
        return target.copy(), np.zeros(0), True
    piqp = baseline()
    solver = piqp.SparseSolver()
    for key, value in SETTINGS.items():
        setattr(solver.settings, key, value)
    solver.settings.verbose = False
    solver.setup(sp.identity(n, format="csc"), -np.asarray(target, dtype=float),
                 sp.csc_matrix((0, n)), np.zeros(0), sp.csc_matrix(-c), None,
                 -(np.asarray(b, dtype=float) + opts.eps_abs), None, None)
    status = solver.solve()
    ok = status == piqp.PIQP_SOLVED
    return (np.array(solver.result.x, dtype=float),
            np.maximum(np.array(solver.result.z_u, dtype=float), 0.0), bool(ok))
