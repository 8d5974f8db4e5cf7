"""The worker process of ``sweep bench speed``: solver calls run one at a time in a spawned
process, each under a wall-clock limit (proxsuite 0.8.0 can stall inside its solve on
degenerate jams; a stalled worker is killed). Solvers: proxsuite, cromosim's projection (when
installed; never a dependency) and any backend of
:mod:`sweep_core.numerics.projection.backends`."""
from __future__ import annotations

import contextlib
import io
import multiprocessing
import time
from dataclasses import replace
from typing import Any

import numpy as np

from sweep_core.numerics import projection
from sweep_core.numerics.projection import backends
from sweep_core.numerics.projection.proxqp import solve_proxsuite

# -- solvers run in the worker process (each returns seconds, converged, answer) ---------------

def _solve_proxsuite(target: np.ndarray, c: Any, b: np.ndarray,
                     opts: projection.SolverOptions) -> tuple[float, bool, np.ndarray]:
    if len(b) == 0:
        return 0.0, True, target
    start = time.perf_counter()
    x, _, ok = solve_proxsuite(target, c, b, opts)
    return time.perf_counter() - start, ok, x


def _solve_cromosim(dt: float, xyrv: np.ndarray, contacts: np.ndarray, vd: np.ndarray
                    ) -> tuple[float, bool, np.ndarray]:
    """cromosim's velocity-form projection; its fallback to Uzawa (announced on stdout) and
    a negative ``info`` count as not converged."""
    said = io.StringIO()
    with contextlib.redirect_stdout(said):  # its import and its solver talk on stdout
        from cromosim.micro import projection as cromosim_projection

        start = time.perf_counter()
        info, _, u, _, _ = cromosim_projection(dt, xyrv, contacts, vd)
        seconds = time.perf_counter() - start
    return seconds, info >= 0 and "failed" not in said.getvalue(), np.asarray(u)


def _solve_backend(name: str, target: np.ndarray, c: Any, b: np.ndarray,
                   opts: projection.SolverOptions) -> tuple[float, bool, np.ndarray]:
    """One backend through :mod:`sweep_core.numerics.projection.backends`."""
    start = time.perf_counter()
    x, _, ok = backends.solve_backend(target, c, b, replace(opts, backend=name))
    return time.perf_counter() - start, ok is True, x


_SOLVERS = {"proxsuite": _solve_proxsuite, "cromosim": _solve_cromosim,
            "backend": _solve_backend}


def serve(conn: Any) -> None:
    """Worker loop: (solver name, args) in, ("ok", result) or ("error", text) out."""
    while (task := conn.recv()) is not None:
        name, args = task
        try:
            conn.send(("ok", _SOLVERS[name](*args)))
        except Exception as err:  # noqa: BLE001 - reported in the table's notes
            conn.send(("error", f"{type(err).__name__}: {err}"))


class Worker:
    """A spawned process that runs solver calls one at a time, each under a wall-clock limit;
    a call past the limit kills the process (a new one is started for the next batch)."""

    def __init__(self) -> None:
        self._proc: Any = None
        self._conn: Any = None

    def run(self, name: str, tasks: list[tuple], limit_s: float) -> tuple[list, str]:
        """Results of the tasks up to the first failure or solve longer than limit_s seconds,
        and a note saying why it stopped ("" when every task was done)."""
        if self._proc is None:
            ctx = multiprocessing.get_context("spawn")
            self._conn, child = ctx.Pipe()
            self._proc = ctx.Process(target=serve, args=(child,), daemon=True)
            self._proc.start()
            child.close()
        results: list = []
        for k, task in enumerate(tasks):
            self._conn.send((name, task))
            try:
                if not self._conn.poll(limit_s):
                    self.close(kill=True)
                    return results, (f"{name} n/a: solve {k + 1} of {len(tasks)} still running "
                                     f"after {limit_s:g} s, killed")
                status, value = self._conn.recv()
            except (EOFError, OSError) as err:
                self.close(kill=True)
                return results, f"{name} n/a: worker died in solve {k + 1} ({err!r})"
            if status == "error":
                return results, f"{name} n/a: {value}"
            results.append(value)
        return results, ""

    def close(self, kill: bool = False) -> None:
        if self._proc is None:
            return
        if kill:
            self._proc.kill()
        else:
            self._conn.send(None)
        self._proc.join()
        self._conn.close()
        self._proc = self._conn = None
