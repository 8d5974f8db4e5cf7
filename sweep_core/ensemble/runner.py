"""``sweep_core.ensemble.run``: seeded runs x grid points on a Dask cluster, one row per run.

Run k of a grid point uses seed ``seed0 + k``; each run is a Dask task
(:func:`sweep_core.ensemble.task.simulate`) on whichever worker is free, and is built only
from its own data (scene dict, seed, dt, scheme), so its result does not depend on the worker,
the worker count or the order of completion. Rows are written to DIR as they arrive
(:mod:`sweep_core.ensemble.store`); a re-run with the same DIR skips the runs already there.
"""
from __future__ import annotations

import math
import os
import uuid
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sweep_core import checks
from sweep_core.analysis.arrivals import arrive_radius_for
from sweep_core.analysis.lines import line_outside_sinks, parse_line
from sweep_core.ensemble import cluster, grid, paired, store
from sweep_core.ensemble.task import RECORD, Task, simulate
from sweep_core.errors import SceneError
from sweep_core.io import limits
from sweep_core.io.outputs import write_text
from sweep_core.model.room import most_present
from sweep_core.model.scene import DEFAULT_SCENE, Scene, copy_spec, load_scene
from sweep_core.numerics import kernels
from sweep_core.numerics.schemes import SCHEMES

#: columns first in the table, in this order (grid keys follow "point")
FIRST = ("point", "run", "seed", "dt", "scheme", "status", "error", "wall_time_s", "worker",
         "t_reached_s", "final_sha256", "recording")


def resolve_scene(scene: Scene | dict | str | Path | None) -> Scene:
    """A Scene from a Scene, a scene dict, a YAML path, or None / the bundled default's name."""
    if isinstance(scene, Scene):
        return scene
    if isinstance(scene, dict):
        return Scene.from_dict(scene)
    if scene is None or (str(scene) in (DEFAULT_SCENE, DEFAULT_SCENE.rsplit(".", 1)[0])
                         and not Path(scene).exists()):
        return load_scene(None)
    return load_scene(str(scene))


#: most runs (runs per grid point x grid points) of one ensemble: each run is a Dask task and
#: a head and a task kept here before the first one is submitted (measured: 53 MB and 1.5 s
#: per 1e5 runs, so 1e9 runs built lists until memory ran out), its row gathered here and
#: the table built from them (:func:`gathered_memory`), and Dask's scheduler adds its own
#: state and scheduling time per task (about 1 ms, Dask's own figure)
MAX_RUNS = 100_000
#: memory of an ensemble's runs in the client (bytes): per run (its head and task), per
#: column of its row (a float in the row's dict and in the table), per byte of its summary
#: JSON (--record summary: the string in the row, the table's copy). Measured increase of
#: the peak resident memory building the heads and tasks, gathering rows of the bundled room
#: (52 columns, a summary of 2.3 kB) and building the table: 2e4 runs 128 MB, with summaries
#: 306 MB; 1e5 runs with summaries 1.34 GB, so MAX_RUNS keeps it near 1.5 GB for such rows
GATHER_PER_RUN, GATHER_PER_COLUMN, GATHER_PER_SUMMARY_BYTE = 550, 120, 4


def gathered_memory(runs: int, columns: int, summary_bytes: int = 0) -> int:
    """The memory (bytes) ``runs`` runs take in the client: their heads and tasks, their rows
    of ``columns`` columns with summaries of ``summary_bytes`` bytes (0: --record none), and
    the table of them (:data:`GATHER_PER_RUN` and the rest)."""
    return runs * (GATHER_PER_RUN + GATHER_PER_COLUMN * columns
                   + GATHER_PER_SUMMARY_BYTE * summary_bytes)

#: largest seed: runs.parquet stores seeds as int64 (a seed of 2^64 failed after every run)
MAX_SEED = 2**63 - 1


def _check_options(runs: int, seed0: int, t_end: float, dt: float, scheme: str, record: str,
                   out: str | Path | None, arrive_radius: float | None) -> None:
    checks.integer(runs, "--runs", low=1, fix="e.g. --runs 200")
    if runs > MAX_RUNS:
        raise SceneError("--runs", f"{runs} runs are more than the limit {MAX_RUNS} of one "
                         "ensemble", f"--runs {MAX_RUNS} or fewer (several --out folders for more)")
    checks.integer(seed0, "--seed0", fix="e.g. --seed0 0")
    if seed0 + runs - 1 > MAX_SEED:
        raise SceneError("--seed0", f"{seed0} + {runs} runs passes the largest seed {MAX_SEED} "
                         "(2^63 - 1)", f"--seed0 {MAX_SEED - runs + 1} or less")
    for field, value, example in (("--t-end", t_end, "60"), ("--dt", dt, "0.01"),
                                  ("--arrive-radius", arrive_radius, "1.0")):
        if value is None and field == "--arrive-radius":
            continue
        ok = (not isinstance(value, bool) and isinstance(value, (int, float))
              and math.isfinite(value) and value > 0)
        if not ok:
            shown = f"{value:g}" if isinstance(value, float) else repr(value)
            raise SceneError(field, f"must be a positive number, got {shown}",
                             f"e.g. {field} {example}")
    limits.check_dt(dt, "--dt")
    check_steps(t_end, dt, "--dt")
    if scheme not in SCHEMES:
        raise SceneError("--scheme", f"unknown scheme {scheme!r}", f"use one of {sorted(SCHEMES)}")
    if record not in RECORD:
        raise SceneError("--record", f"{record!r} is not one of {', '.join(RECORD)}",
                         "use none, summary or full")
    if record == "full" and out is None:
        raise SceneError("--record", "full writes one MCAP per run into the output directory",
                         "give --out DIR (out=DIR)")


def check_steps(t_end: float, dt: float, field: str) -> None:
    """Refuses a run of more than :data:`limits.MAX_STEPS` steps (``sweep run``'s bound
    without --force), naming ``field`` (``--dt``, or the grid key ``dt``)."""
    steps = t_end / dt
    if steps > limits.MAX_STEPS:
        shorter = f"a shorter --t-end (at most {limits.MAX_STEPS * dt:g} s)"
        least = t_end / limits.MAX_STEPS
        raise SceneError(f"--t-end/{field}", f"{t_end:g} s at dt = {dt:g} s is {steps:g} steps "
                         f"per run, more than the limit {limits.MAX_STEPS:g}",
                         f"a dt of at least {least:g} s, or {shorter}"
                         if least <= limits.DT_MAX else shorter)


def check_recording(scene: Scene, t_end: float, dt: float) -> None:
    """Refuses runs whose recording, every step of ``t_end`` s at ``dt`` s written to a
    temporary file on the worker and read back by the analysis, would pass ``sweep run``'s
    bound :data:`limits.MAX_RECORDING_BYTES` (the same estimate: agents of sources counted
    from their times on, at most what the room holds; the base scene's agents)."""
    sources = scene.flows.sources if scene.flows is not None else ()
    entries = np.concatenate([s.times for s in sources]) if sources else None
    size = limits.check_run_size(scene.n_agents, dt, t_end, force=True, entries=entries,
                                 most=most_present(scene, t_end) if sources else None)
    if size.recording_bytes > limits.MAX_RECORDING_BYTES:
        most = t_end * limits.MAX_RECORDING_BYTES / size.recording_bytes
        raise SceneError("--t-end", f"{t_end:g} s at dt = {dt:g} s records {size.frames:g} "
                         f"states of {scene.n_agents} agents per run, about "
                         f"{size.recording_bytes / 1e9:.3g} GB uncompressed on its worker, "
                         f"more than the limit {limits.MAX_RECORDING_BYTES / 1e9:g} GB",
                         f"a shorter --t-end (at most about {most:.3g} s), a larger --dt, or "
                         "fewer agents")


def run(scene: Scene | dict | str | Path | None = None, *, runs: int = 1, seed0: int = 0,
        t_end: float = 60.0, dt: float = 0.01, scheme: str = "projected_euler",
        vary: Mapping[str, Sequence[Any]] | None = None, client: Any = None,
        record: str = "none", out: str | Path | None = None,
        line: tuple[float, float, float, float] | str | None = None,
        arrive_radius: float | None = None, workers: int | None = None,
        scheduler: str | None = None, plots: bool = True, progress: bool = False,
        log: Callable[[str], None] | None = None) -> pd.DataFrame:
    """Runs ``runs`` seeded runs of ``scene`` at every grid point of ``vary``; one row each.

    Args:
        scene: a Scene, a scene dict, a YAML path, or None (the bundled default scene).
        runs: runs per grid point; run k has seed ``seed0 + k``.
        t_end, dt: simulated time and time step (s); scheme: a name in ``SCHEMES``.
        vary: key -> values; keys are ``dt``, ``scheme`` or dotted scene keys
            (``noise.sigma``); the grid is their product (see :mod:`.grid`).
        client: a ``distributed.Client``, used as is. Otherwise ``scheduler``
            (``tcp://HOST:PORT``) is connected to, or a LocalCluster of ``workers`` processes
            (default: the cores) is started on 127.0.0.1 and closed afterwards.
        record: ``none`` (rows only), ``summary`` (rows carry ``sweep analyze``'s whole summary
            as JSON, also written to DIR/summaries/), ``full`` (also one MCAP per run in
            DIR/mcap/, written by the workers: DIR must be the same path on every worker).
        out: output directory DIR (runs.parquet, summary.csv, plots, resume); None: no files.
        line, arrive_radius: as ``sweep analyze --line x0,y0,x1,y1 --arrive-radius R`` (m).
        plots: write the PNG plots into DIR.
        progress: a progress bar on stderr (on a terminal only).
        log: called with one-line notes (cluster, dashboard, resume, outputs).

    Returns:
        One row per run, ordered by grid point and seed: point, the grid keys, run, seed, dt,
        scheme, status (``ok``, ``failed``; ``lost`` if the worker died), error, wall_time_s
        (on the worker: build, simulate, record, analyse), worker, t_reached_s, final_sha256
        (SHA-256 of the final float64 positions), recording (its MCAP, record full), then the
        metrics of ``sweep analyze`` as ``section.key`` columns (``min_gap.min_m``,
        ``arrivals.t_90_s``, ...).

    Called from a script, guard the call with ``if __name__ == "__main__":``: the local
    workers are new processes that import the script's main module.
    """
    say = log or (lambda _text: None)
    _check_options(runs, seed0, t_end, dt, scheme, record, out, arrive_radius)
    if client is None and scheduler is None:
        cluster.check_workers(workers)
    if isinstance(line, str):
        line = parse_line(line)
    base = resolve_scene(scene)
    base.check_horizon(t_end)
    spec = copy_spec(base)
    points = grid.grid(vary, spec)
    if runs * len(points) > MAX_RUNS:
        raise SceneError("--runs", f"{runs} runs x {len(points)} grid points are "
                         f"{runs * len(points)} runs, more than the limit {MAX_RUNS} of one "
                         "ensemble", f"--runs {MAX_RUNS // len(points)} or fewer, or fewer "
                         "--vary values")
    for point in points:
        limits.check_some_step(t_end, float(point.get("dt", dt)),
                               "every run would end at its start")
        if "dt" in point:
            check_steps(t_end, float(point["dt"]), "--vary dt")
    check_recording(base, t_end, min(float(p.get("dt", dt)) for p in points))
    # a line in a sink, a radius arrivals would not use: refused before any run, as analyze does
    line, arrive_radius = line_outside_sinks(line, base), arrive_radius_for(arrive_radius, base)
    keys = list(points[0])
    out_dir = Path(out).resolve() if out is not None else None
    held = None  # DIR/.lock, held while this ensemble writes DIR
    if out_dir is not None:
        held = store.lock(out_dir)
    try:
        return _run(base, spec, points, keys, out_dir, runs, seed0, t_end, dt, scheme, record,
                    line, arrive_radius, client, scheduler, workers, progress, plots, say)
    finally:
        if held is not None:
            os.close(held)


def _run(base: Scene, spec: dict, points: list, keys: list[str], out_dir: Path | None,
         runs: int, seed0: int, t_end: float, dt: float, scheme: str, record: str,
         line: Any, arrive_radius: float | None, client: Any, scheduler: str | None,
         workers: int | None, progress: bool, plots: bool, say: Any) -> pd.DataFrame:
    """The ensemble of :func:`run` once its options are checked and DIR is locked."""
    if out_dir is not None:
        store.check_config(out_dir, {"scene": spec, "t_end": t_end, "dt": dt, "scheme": scheme,
                                     "line": list(line) if line else None,
                                     "arrive_radius": arrive_radius})

    heads: dict[str, dict[str, Any]] = {}
    tasks: dict[str, Task] = {}
    for i, point in enumerate(points):
        pid = grid.point_id(point)
        point_spec = grid.apply(spec, point)
        p_dt = float(point.get("dt", dt))
        p_scheme = str(point.get("scheme", scheme))
        for k in range(runs):
            name = store.run_name(pid, seed0 + k)
            mcap = str(out_dir / "mcap" / f"{name}.mcap") if record == "full" and out_dir else None
            heads[name] = {"point": i, **point, "run": k, "seed": seed0 + k, "dt": p_dt,
                           "scheme": p_scheme}
            if mcap is not None:
                heads[name]["recording"] = mcap
            tasks[name] = Task(spec=point_spec, name=base.name, seed=seed0 + k, dt=p_dt,
                               scheme=p_scheme, t_end=t_end, line=line,
                               arrive_radius=arrive_radius, mcap=mcap, summary=record != "none")
    rows = store.read_rows(out_dir, heads) if out_dir is not None else {}
    if rows:
        say(f"resume: {len(rows)} of {len(heads)} runs already in {out_dir}, skipped")
    todo = [name for name in heads if name not in rows]
    marker = None
    if record == "full" and out_dir is not None and todo:
        (out_dir / "mcap").mkdir(parents=True, exist_ok=True)
        marker = out_dir / f".shared-{uuid.uuid4().hex}"
        marker.write_text("created by sweep ensemble; workers check they see it\n")
        for name in todo:
            tasks[name].marker = str(marker)
    try:
        if todo:
            # compiled here once (first run on this machine) into the cache the workers of a
            # local cluster share, then loaded by every worker before its first run; a remote
            # scheduler's workers compile or load their own
            if scheduler is None:
                kernels.warm_up(say)
            else:
                cluster.check_address(scheduler)
            with cluster.connect(client, scheduler, workers, say) as cl:
                cl.run(kernels.warm_up)
                _execute(cl, [(name, tasks[name]) for name in todo], rows, out_dir, progress)
    finally:
        if marker is not None:
            marker.unlink(missing_ok=True)
        table = _table(heads, rows, keys)
        if out_dir is not None and len(table):
            files = store.write_tables(out_dir, table, keys)
            if paired.is_paired(keys, points):  # with and without the robots, seed by seed
                files.update(paired.write(out_dir, table, keys))
            if plots:
                from sweep_core.ensemble.plots import write_plots
                files.update(write_plots(out_dir, table, keys))
            say("outputs " + ", ".join(files.values()))
    return table


def _execute(client: Any, todo: list[tuple[str, Task]], rows: dict[str, dict[str, Any]],
             out_dir: Path | None, progress: bool) -> None:
    """Submits the tasks, collects each row as it completes (written to DIR at once)."""
    from distributed import as_completed
    from tqdm import tqdm

    token = uuid.uuid4().hex[:8]
    futures = {client.submit(simulate, task, key=f"sweep-run-{name}-{token}", pure=False): name
               for name, task in todo}
    counts = {"ok": 0, "failed": 0}
    bar = tqdm(total=len(todo), unit="run", dynamic_ncols=True,
               disable=None if progress else True)
    try:
        for fut in as_completed(list(futures)):
            name = futures.pop(fut)
            try:
                row = fut.result()
            except Exception as err:  # noqa: BLE001 - the cluster lost this run: retried on resume
                row = {"status": "lost", "error": " ".join(f"{type(err).__name__}: {err}".split()),
                       "wall_time_s": math.nan}
            fut.release()
            rows[name] = row
            if out_dir is not None:
                _save(out_dir, name, row)
            counts["ok" if row["status"] == "ok" else "failed"] += 1
            bar.set_postfix(completed=counts["ok"], failed=counts["failed"], refresh=False)
            bar.update()
    finally:
        bar.close()
        if futures:
            client.cancel(list(futures))


def _save(out_dir: Path, name: str, row: dict[str, Any]) -> None:
    if row.get("summary_json"):
        summaries = out_dir / "summaries"
        summaries.mkdir(exist_ok=True)
        write_text(summaries / f"{name}.json", row["summary_json"] + "\n",
                   other="--out OTHERDIR")
    store.write_row(out_dir, name, row)


def _table(heads: dict[str, dict[str, Any]], rows: dict[str, dict[str, Any]],
           keys: list[str]) -> pd.DataFrame:
    """The rows of the runs that have one, in grid-point and seed order, head columns first
    (a row read back from DIR gets this invocation's point index and run number)."""
    records = [{**{k: v for k, v in rows[name].items() if k not in heads[name]}, **heads[name]}
               for name in heads if name in rows]
    if not records:
        return pd.DataFrame(columns=list(dict.fromkeys((*FIRST[:1], *keys, *FIRST[1:]))))
    table = pd.DataFrame(records)
    first = [c for c in dict.fromkeys(("point", *keys, *FIRST[1:])) if c in table]
    return table[first + [c for c in table.columns if c not in first]].reset_index(drop=True)

