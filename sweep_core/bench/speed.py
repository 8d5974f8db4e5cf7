"""``sweep bench speed``: step time against the floor and whole-set QP baselines.

For each N and scene (``SCENES``: a hexagonal jam pushed to its centre, a disordered
polydisperse one, free flow), after a warm-up, on the states the simulator itself visits (times
in ms, distances in m), with the step's certified bound (largest over the measured steps):

* floor: neighbour search + constraint assembly of the step (``constraints.linearise`` at the
  cutoff the step started from), the work no exact method avoids;
* step: a full ``Simulator.step()`` (prediction, assembly, projection, feasibility check);
* baselines: assembly plus the step's linearised QP, min 1/2 |x - p|^2 s.t. C x >= b over every
  row built at that cutoff and every agent in a row (no clusters, no closed forms), solved as
  one problem by Clarabel (in this process) and by proxsuite (sparse proxqp, with the
  simulator's solver settings, in a worker process under a wall-clock limit per solve: proxsuite
  0.8.0 stalls inside its solve on degenerate jams; a stalled worker is killed and the column
  reads n/a, with the reason under the row);
* cromosim, when it is installed (never a dependency): assembly plus the same rows and
  prediction through ``cromosim.micro.projection`` with its default method and tolerances
  (velocity form: U = (y - q) / dt, each row as its gap at q and unit vector; every agent of
  the crowd), in the same worker under the same limit.

Median, min and max over the measured steps; ``*_solved`` is converged / attempted solves
among the steps with rows (a stalled one counts); ``*_dist_m`` is the largest distance
between an agent's position from that solver and from the step, over its solved steps (a
Clarabel solve that does not end "Solved" can return an x far from the projection: it counts
only in ``clarabel_solved``). A CSV is written beside the
table.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from sweep_core.bench import options, steps
from sweep_core.bench.evacuation import DT as EVACUATION_DT
from sweep_core.bench.evacuation import evacuation
from sweep_core.bench.tables import write_csv
from sweep_core.bench.worker import Worker
from sweep_core.model.scene import Scene
from sweep_core.numerics import projection
from sweep_core.numerics.constraints import Rows, linearise
from sweep_core.numerics.projection import backends
from sweep_core.numerics.projection.clusters import row_matrix
from sweep_core.numerics.projection.interior import solve_clarabel
from sweep_core.numerics.simulator import Simulator

COLUMNS = ("N", "scene", "tol", "contacts", "bound_max_m", "certified_share",
           "clarabel_dist_m", "clarabel_solved", "floor_median_ms",
           "step_median_ms", "step_min_ms", "step_p99_ms",
           "step_max_ms", "max_over_median", "run_s", "step_over_floor", "clarabel_median_ms",
           "step_over_clarabel",
           "proxsuite_median_ms", "step_over_proxsuite", "proxsuite_solved",
           "proxsuite_max_dist_m", "cromosim_median_ms", "step_over_cromosim",
           "cromosim_solved", "cromosim_max_dist_m", "notes")
#: table header and width of each column printed
_SHOWN = (("N", "N", 6), ("scene", "scene", 16), ("tol", "tol", 6),
          ("contacts", "contacts", 8), ("bound_max_m", "bound", 8),
          ("certified_share", "cert", 5),
          ("floor_median_ms", "floor", 8), ("step_median_ms", "step", 9),
          ("step_min_ms", "min", 9), ("step_p99_ms", "p99", 9), ("step_max_ms", "max", 9),
          ("run_s", "run_s", 7),
          ("step_over_floor", "/floor", 7), ("clarabel_median_ms", "clarabel", 9),
          ("step_over_clarabel", "/clar", 6), ("clarabel_dist_m", "clar_dist", 9),
          ("clarabel_solved", "solved", 6),
          ("proxsuite_median_ms", "proxsuite", 9),
          ("step_over_proxsuite", "/prox", 6), ("proxsuite_solved", "solved", 7),
          ("proxsuite_max_dist_m", "prox_dist", 9), ("cromosim_median_ms", "cromosim", 9),
          ("step_over_cromosim", "/crom", 6))


def disordered(n: int, seed: int = 0) -> Scene:
    """n disks of radii uniform in [0.20, 0.27] m on a lattice of spacing 0.6 m jittered by up
    to 3 cm, pushed to the centre at 1 m/s with sigma 0.08: a disordered, polydisperse jam
    once pressed."""
    rng = np.random.default_rng(seed)
    cols = int(math.ceil(math.sqrt(n)))
    pos = np.array([(c * 0.6 + (r % 2) * 0.3, r * 0.6 * math.sqrt(3) / 2)
                    for r in range(cols) for c in range(cols)][:n])
    pos += rng.uniform(-0.03, 0.03, pos.shape)
    return Scene.from_dict({"agents": {"positions": pos.tolist(),
                                       "radius": rng.uniform(0.20, 0.27, n).tolist()},
                            "drift": {"kind": "goal", "goal": pos.mean(axis=0).tolist(),
                                      "speed": 1.0},
                            "noise": {"sigma": 0.08}})


#: scene name -> (scene of n agents, dt in s)
SCENES = {"hex": (lambda n: crowd(n, True), 0.01),
          "disordered": (disordered, 0.02),
          "free": (lambda n: crowd(n, False), 0.01),
          "evacuation": (evacuation, EVACUATION_DT),
          "evacuation_mixed": (lambda n: evacuation(n, mixed=True), EVACUATION_DT)}
#: the jams (the backends are compared on their QPs)
JAMS = ("hex", "disordered", "evacuation")


def crowd(n: int, jammed: bool, sigma: float = 0.1) -> Scene:
    """n disks of radius 0.24 m on a hexagonal lattice: touching and pushed to the centre
    (jammed), or 1.5 m apart under a uniform drift (free flow)."""
    cols = int(math.ceil(math.sqrt(n)))
    spacing = 0.5 if jammed else 1.5
    pos = np.array([(c * spacing + (r % 2) * spacing / 2, r * spacing * math.sqrt(3) / 2)
                    for r in range(cols) for c in range(cols)][:n])
    drift = ({"kind": "goal", "goal": pos.mean(axis=0).tolist(), "speed": 1.0}
             if jammed else {"kind": "uniform", "velocity": [1.0, 0.2]})
    return Scene.from_dict({"agents": {"positions": pos.tolist(), "radius": 0.24},
                            "drift": drift, "noise": {"sigma": sigma}})


# -- measuring ----------------------------------------------------------------------------------

def _whole_qp(sim: Simulator, q: np.ndarray, r1: np.ndarray, rows: Rows) -> tuple[float, dict]:
    """Seconds to assemble the last step's rows (built at the step's first cutoff, as timed
    for the floor) into one QP, and the QP."""
    pred = sim.last.prediction
    start = time.perf_counter()
    agents = rows.agents()
    loc = np.full(len(q), -1, dtype=np.intp)
    loc[agents] = np.arange(len(agents))
    c, b = row_matrix(rows, loc, len(agents))
    seconds = time.perf_counter() - start
    return seconds, {"rows": rows, "agents": agents, "c": c, "b": b, "r1": r1, "q": q,
                     "pred": pred, "target": pred[agents].ravel(), "y": sim.last.projection.y}


def _cromosim_task(qp: dict, dt: float) -> tuple:
    """cromosim's arguments for a QP: velocities (y - q) / dt, rows as i, j, gap at q, unit
    vector from i to j (walls: j = -1 and the unit normal pointing into the free side)."""
    rows, q = qp["rows"], qp["q"]
    gap_p, gap_s = rows.residuals(q)
    pairs = np.column_stack([rows.pair_i, rows.pair_j, gap_p, -rows.pair_e])
    singles = np.column_stack([rows.single_a, np.full(len(gap_s), -1.0), gap_s, rows.single_n])
    xyrv = np.column_stack([q, qp["r1"], np.ones(len(q))])
    return dt, xyrv, np.vstack([pairs, singles]), (qp["pred"] - q) / dt


def _distance(qp: dict, x: np.ndarray) -> float:
    """Largest distance (m) between an agent's position in a whole-QP answer x (the QP's agents
    stacked, as ``_whole_qp`` poses it) and in the step's answer."""
    y = qp["pred"].copy()
    y[qp["agents"]] = np.reshape(x, (-1, 2))
    return float(np.sqrt(((y - qp["y"]) ** 2).sum(axis=1)).max(initial=0.0))


def _external(worker: Worker, name: str, qps: list[dict], build: list[float], dt: float,
              limit_s: float, opts: projection.SolverOptions) -> dict:
    """Median ms (assembly + solve), solved count and largest distance to the step's answer."""
    if name == "proxsuite":
        tasks = [(qp["target"], qp["c"], qp["b"], opts) for qp in qps]
    else:
        tasks = [_cromosim_task(qp, dt) for qp in qps]
    results, note = worker.run(name, tasks, limit_s)
    # solved / attempted among the steps with rows (the solve that failed or stalled counts)
    solved = sum(ok for (_, ok, _), qp in zip(results, qps) if len(qp["b"]))
    attempted = len(results) + (1 if note and len(results) < len(qps) else 0)
    posed = sum(1 for qp in qps[:attempted] if len(qp["b"]))
    dist = 0.0
    for (_, _, x), qp in zip(results, qps):
        if name == "proxsuite":
            dist = max(dist, _distance(qp, x))
        else:
            y = qp["q"] + dt * np.reshape(x, (-1, 2))
            dist = max(dist, float(np.sqrt(((y - qp["y"]) ** 2).sum(axis=1)).max(initial=0.0)))
    done = not note and len(results) == len(qps)
    ms = [1e3 * (s + b) for (s, _, _), b in zip(results, build)]
    return {"median_ms": float(np.median(ms)) if done else math.nan,
            "solved": f"{solved}/{posed}" if posed else "no QP",
            "max_dist_m": dist if results else math.nan, "note": note}


def measure(n: int, scene: str, steps: int, warmup: int, baseline: bool,
            worker: Worker | None = None, limit_s: float = 30.0,
            cromosim: bool = False, tol: float | None = None, backend: str = "piqp"
            ) -> dict:
    """One row of the table (see the module docstring and COLUMNS); tol: the projection's
    certified tolerance (m; None: the default)."""
    make, dt = SCENES[scene]
    solver = projection.SolverOptions(backend=backend, **({} if tol is None else {"tol": tol}))
    sim = Simulator(make(n), dt=dt, seed=0, solver=solver)
    start_run = time.perf_counter()
    sim.step(warmup)
    run_s = time.perf_counter() - start_run
    floor, step, build, clarabel, qps, bounds = [], [], [], [], [], []
    clarabel_dist = 0.0
    clarabel_ok = clarabel_posed = 0
    opts = sim.scheme.solver
    for _ in range(steps):
        q, t1 = sim.positions, sim.t + sim.dt
        start = time.perf_counter()
        sim.step()
        step.append(time.perf_counter() - start)
        bounds.append(sim.bound)
        # the floor of that step: assembly at the cutoff the step itself started from
        r1 = sim.scene.radii(t1)
        start = time.perf_counter()
        rows = linearise(sim.scene.geometry, t1, q, r1,
                         projection.first_cutoff(q, sim.last.prediction, r1))
        floor.append(time.perf_counter() - start)
        if baseline:
            seconds, qp = _whole_qp(sim, q, r1, rows)
            seconds += floor[-1]  # the baselines assemble the same rows
            start = time.perf_counter()
            x, ok = None, False
            if len(qp["b"]):
                x, _, ok = solve_clarabel(qp["target"], qp["c"].tocsr(), qp["b"], opts)
            clarabel.append(seconds + time.perf_counter() - start)
            if x is not None:  # measured outside the timed solve
                clarabel_posed += 1
                clarabel_ok += ok is True
                if ok is True:  # a failed solve's x says nothing (it counts in solved)
                    clarabel_dist = max(clarabel_dist, _distance(qp, x))
            build.append(seconds)
            qps.append(qp)
    ms = {k: 1e3 * np.array(v) for k, v in (("floor", floor), ("step", step),
                                             ("clarabel", clarabel))}
    out: dict[str, Any] = {"N": n, "scene": scene, "tol": solver.tol,
                           "contacts": sim.contacts, "notes": "", "qps": qps,
                           "bound_max_m": float(max(bounds)),
                           "certified_share": float(np.mean(np.array(bounds) <= solver.tol)),
                           "run_s": run_s + float(np.sum(step)),
                           "clarabel_dist_m": clarabel_dist if clarabel_ok else math.nan,
                           "clarabel_solved": (f"{clarabel_ok}/{clarabel_posed}"
                                               if clarabel_posed else "")}
    for k, v in ms.items():
        out[f"{k}_median_ms"] = float(np.median(v)) if len(v) else math.nan
    out["step_min_ms"], out["step_max_ms"] = float(ms["step"].min()), float(ms["step"].max())
    out["step_p99_ms"] = float(np.percentile(ms["step"], 99))
    out["max_over_median"] = out["step_max_ms"] / out["step_median_ms"]
    notes = []
    for name in ("proxsuite", "cromosim"):
        res = {"median_ms": math.nan, "solved": "", "max_dist_m": math.nan, "note": ""}
        if baseline and worker is not None and (name == "proxsuite" or cromosim):
            res = _external(worker, name, qps, build, sim.dt, limit_s, opts)
        out[f"{name}_median_ms"], out[f"{name}_max_dist_m"] = res["median_ms"], res["max_dist_m"]
        out[f"{name}_solved"] = res["solved"]
        if res["note"]:
            notes.append(res["note"])
    out["notes"] = "; ".join(notes)
    for k in ("floor", "clarabel", "proxsuite", "cromosim"):
        out[f"step_over_{k}"] = out["step_median_ms"] / out[f"{k}_median_ms"]
    return out


def cromosim_missing() -> str | None:
    """Why ``cromosim.micro`` cannot be imported here, or None when it can."""
    try:
        with contextlib.redirect_stdout(io.StringIO()):  # it prints about optional modules
            import cromosim.micro  # noqa: F401
    except Exception as err:  # noqa: BLE001 - any failure means: skip the column
        return f"{type(err).__name__}: {err}"
    return None


def _cell(value: Any, width: int) -> str:
    if isinstance(value, float):
        if math.isnan(value):
            return f"{'n/a':>{width}}"
        return f"{value:>{width}.3g}" if abs(value) < 1e-2 and value else f"{value:>{width}.3f}"
    return f"{value:>{width}}"


def run(args: argparse.Namespace) -> int:
    options.speed(args)
    if "steps" in args.scenes:  # the small and medium scenes beside ORCA (bench/steps.py)
        rest = [s for s in args.scenes if s != "steps"]
        csv = args.csv if not rest else str(Path(args.csv).with_name(
            Path(args.csv).stem + "_steps.csv"))
        steps.run(argparse.Namespace(**{**vars(args), "csv": csv}))
        if not rest:
            return 0
        args.scenes = rest
    args.backend = projection.SolverOptions.from_values(backend=args.backend).backend
    baseline = not args.no_baseline
    missing = cromosim_missing() if baseline else "baselines off"
    if missing:
        print(f"cromosim: skipped ({missing}); it is never a dependency of sweep_ros")
    else:
        from importlib.metadata import version
        print(f"cromosim {version('cromosim')}: cromosim.micro.projection (its default "
              "method) on the same rows, every agent of the crowd")
    print("times in ms (median over the steps unless min/max), dist in m; /X = step / X")
    print(" ".join(f"{head:>{w}}" for _, head, w in _SHOWN), flush=True)
    worker = Worker() if baseline else None
    results: list[dict] = []
    compared: list[dict] = []
    plan = [(n, scene) for n in args.sizes for scene in args.scenes if scene != "evacuation"]
    if "evacuation" in args.scenes:
        plan += [(n, "evacuation") for n in args.evacuation_sizes]
    try:
        for n, scene in plan:
            evac = scene == "evacuation"
            # the Pareto of step time against tolerance on the jams (the evacuation's: whole
            # runs again, equal and mixed radii); one row at the default tolerance (with the
            # baselines) for free flow
            tols = [None] + ([t for t in args.tols] if scene != "free" else [])
            for tol in tols:
                r = measure(n, scene, args.evacuation_steps if evac else args.steps,
                            args.evacuation_warmup if evac else args.warmup,
                            baseline and tol is None, worker, args.timeout,
                            cromosim=missing is None, tol=tol, backend=args.backend)
                qps = r.pop("qps")
                results.append(r)
                print(" ".join(_cell(r[c], w) for c, _, w in _SHOWN), flush=True)
                if r["notes"]:
                    print(f"{'':>14}{r['notes']}", flush=True)
                if evac:
                    # the same run with radii 0.20-0.27 m: what equal radii cost over a run
                    mixed = measure(n, "evacuation_mixed", args.evacuation_steps,
                                    args.evacuation_warmup, False, None, args.timeout,
                                    tol=tol, backend=args.backend)
                    mixed.pop("qps")
                    results.append(mixed)
                    print(" ".join(_cell(mixed[c], w) for c, _, w in _SHOWN), flush=True)
                    print(f"{'':>14}whole run ({args.evacuation_warmup + args.evacuation_steps}"
                          f" steps): equal radii {r['run_s']:.1f} s, radii 0.20-0.27 m "
                          f"{mixed['run_s']:.1f} s, ratio {r['run_s'] / mixed['run_s']:.2f}",
                          flush=True)
                if worker is not None and tol is None and scene in JAMS and args.backend_qps:
                    for row in compare_backends(worker, qps[: args.backend_qps],
                                                args.backend_timeout):
                        compared.append({"N": n, "scene": scene, **row})
                        print(f"{'':>14}backend {row['backend']:<9} {_cell(row['median_ms'], 9)}"
                              f" ms  solved {row['solved']:<5} dist {_cell(row['max_dist_m'], 9)}"
                              f" m  {row['note']}", flush=True)
    finally:
        if worker is not None:
            worker.close()
    write_csv(Path(args.csv), results, COLUMNS)
    print(f"csv: {args.csv}")
    if compared:
        path = Path(args.csv).with_name(Path(args.csv).stem + "_backends.csv")
        write_csv(path, compared, ("N", "scene", "backend", "median_ms", "solved",
                                   "max_dist_m", "note"))
        print(f"csv: {path}")
    return 0


def compare_backends(worker: Worker, qps: list[dict], limit_s: float) -> list[dict]:
    """Each installed backend (:func:`backends.available`) on the cluster QP of whole steps,
    posed as the projection poses it (displacement coordinates, rows tightened by eps_abs):
    median solve time (ms), solved count and the largest distance (m) of an agent to the
    step's certified answer."""
    opts = projection.SolverOptions()
    rows_out = []
    for name in backends.available():
        tasks, posed = [], []
        for qp in qps:
            if not len(qp["b"]):
                continue
            _, _, _, h = qp["rows"].displacement_rows(qp["q"])
            target = (qp["pred"] - qp["q"])[qp["agents"]].ravel()
            tasks.append((name, target, qp["c"], h, opts))
            posed.append(qp)
        results, note = worker.run("backend", tasks, limit_s)
        dist, solved = 0.0, 0
        for (_, ok, x), qp in zip(results, posed):
            solved += ok
            if ok:
                y = qp["pred"].copy()
                y[qp["agents"]] = qp["q"][qp["agents"]] + np.reshape(x, (-1, 2))
                dist = max(dist, float(np.sqrt(((y - qp["y"]) ** 2).sum(axis=1)).max()))
        done = len(results) == len(tasks) and not note
        rows_out.append({"backend": name, "note": note,
                         "median_ms": (float(np.median([1e3 * t for t, _, _ in results]))
                                       if done and results else math.nan),
                         "solved": f"{solved}/{len(tasks)}",
                         "max_dist_m": dist if solved else math.nan})
    return rows_out


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``speed`` to the ``bench`` subcommands."""
    p = sub.add_parser("speed", help="step time vs floor and whole-set QP baselines")
    p.add_argument("--sizes", type=int, nargs="+", default=[100, 1000, 4000, 10000], metavar="N",
                   help="agent counts of the scenes (default 100 1000 4000 10000)")
    shown = [s for s in SCENES if s != "evacuation_mixed"]  # run with "evacuation"
    p.add_argument("--scenes", nargs="+", default=shown, choices=[*shown, "steps"],
                   help="steps: the engine step of the bundled crowdnav, robot_crowd and "
                        "room_door beside ORCA's (pyrvo), sweep run's recorded step and the "
                        "CrowdNav environment's steps/s (not in the default set); "
                        "hex: hexagonal jam pushed to its centre; disordered: polydisperse "
                        "jam (radii 0.20-0.27 m, sigma 0.08, dt 0.02); free: free flow; "
                        "evacuation: equal radii 0.25 m jammed at the 1.2 m door of a 23 m "
                        "room (dt 0.02, sigma 0.05; its own sizes, warm-up and steps), "
                        "followed by the same run with radii 0.20-0.27 m")
    p.add_argument("--evacuation-sizes", type=int, nargs="+", default=[1000], metavar="N",
                   help="sizes of the evacuation scene (default 1000; 5000 is about 10 times "
                        "longer)")
    p.add_argument("--evacuation-warmup", type=int, default=400, metavar="STEPS",
                   help="evacuation steps before measuring (default 400: 8 s, the jam formed)")
    p.add_argument("--evacuation-steps", type=int, default=100, metavar="STEPS",
                   help="measured evacuation steps (default 100)")
    p.add_argument("--backend", default=projection.SolverOptions.backend, metavar="NAME",
                   help="QP solver of the clusters the exact solver does not take, in the "
                        "measured steps: any installed one (default piqp)")
    p.add_argument("--backend-qps", type=int, default=3, metavar="K",
                   help="QPs of each jam (its first K measured steps) every installed backend "
                        "solves for the backend table (default 3; 0: no table)")
    p.add_argument("--backend-timeout", type=float, default=20.0, metavar="S",
                   help="wall-clock limit of one backend solve, s (default 20)")
    p.add_argument("--tols", type=float, nargs="*", default=[1e-4, 1e-8], metavar="M",
                   help="further tolerances (m) the jams and the evacuation's two runs are "
                        "run at, for the Pareto of step time against certified bound "
                        "(default 1e-4 1e-8)")
    p.add_argument("--steps", type=int, default=30, help="measured steps (default 30)")
    p.add_argument("--warmup", type=int, default=40, help="steps before measuring")
    p.add_argument("--no-baseline", action="store_true",
                   help="skip the whole-set QPs (Clarabel, proxsuite, cromosim)")
    p.add_argument("--timeout", type=float, default=30.0, metavar="S",
                   help="wall-clock limit of one proxsuite (or cromosim) solve, s; the first "
                        "solve past it ends that column for the N and scene (default 30)")
    steps.add_options(p)
    p.add_argument("--csv", default="bench_speed.csv", help="CSV file to write")
    p.set_defaults(func=run)
