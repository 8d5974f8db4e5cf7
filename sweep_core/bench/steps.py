"""``sweep bench speed --scenes steps``: the engine step of small and medium scenes beside ORCA's,
``sweep run``'s recorded step, and the Gymnasium environment's steps per second.

Scenes (``STEP_SCENES``), each the bundled scene of that name at the dt given there:

* crowdnav: the CrowdNav environment's scene (10 people + a robot, dt 0.1 s, the
  environment's);
* robot_crowd: 100 people + a robot with a 360-beam scan at 10 Hz (dt 0.01 s, ``sweep run``'s);
* room_door: 200 people before the door jams (dt 0.01 s; the measured steps end by t = 2 s).

Engine: ``Simulator.step()`` (ms per step). ORCA: the RVO2 library through its Python bindings
``pyrvo`` (an optional benchmark dependency, requirements-dev.txt; never a dependency of
sweep_ros) on the same agent count, positions, radii and walls (as line obstacles), a Python
loop setting each agent's preferred velocity (towards the scene's goal at its speed; the robot
towards its goal at its top speed; robot_crowd's people, who only stand about, a seeded random
velocity of sigma m/s per axis, their Brownian displacement over 1 s) followed by ``doStep`` at
the same dt. The two are interleaved step by step in one loop, so a load on the machine falls
on both alike. Median and p90 over the measured steps; ratio = engine / ORCA, median over
median; the same of the process's CPU time (``cpu_ratio``, in the note), which leaves out the
time a loaded machine keeps the process waiting for a core.

Recorded run: ``record_run`` (what ``sweep run`` does: ``/poses``, ``/agents`` and the robot's
topics every step, MCAP to a temporary file; a step is the time between two of its ``on_state``
calls: the step, its recording and the loop) against an identical simulator's unrecorded step,
taken inside each ``on_state`` call, so the two alternate step by step (``--run-steps`` of
each; median and p90).

Environment: the vectorised environment
``gymnasium.make_vec(..., num_envs=K, vectorization_mode="vector_entry_point")`` when it is
registered, reset with seed 0 (environment i: seed i), stepped with a fixed forward command
10 times untimed, then ``--env-steps`` / K timed calls (env steps per second: K per call; it
resets its own environments), in this process and split over ``--env-workers`` worker
processes; and ``gymnasium.make("sweep/CrowdNav-v0")`` over the same episodes, seed after
seed (the same 10 untimed and --env-steps / K timed steps of each, reset at the end of an
episode), so that the rows time the same steps. Resets are included; in the note, the same
per second of the process's CPU time (the parent's alone where workers step the
environments).
"""
from __future__ import annotations

import argparse
import math
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from sweep_core.bench import options
from sweep_core.bench.options import STEPS_DEFAULTS
from sweep_core.bench.tables import write_csv
from sweep_core.ensemble.cluster import default_workers
from sweep_core.io import limits
from sweep_core.io.metadata import run_metadata
from sweep_core.io.recording.runs import record_run
from sweep_core.model.scene import Scene, load_scene
from sweep_core.numerics import kernels
from sweep_core.numerics.simulator import Simulator

#: scene -> dt (s), warm-up steps, measured steps (room_door: the measured steps end at 2 s)
STEP_SCENES = {"crowdnav": (0.1, 20, 300), "robot_crowd": (0.01, 20, 300),
               "room_door": (0.01, 20, 180)}
COLUMNS = ("measure", "scene", "agents", "sweep_median_ms", "sweep_p90_ms",
           "other", "other_median_ms", "other_p90_ms", "ratio", "sweep_cpu_median_ms",
           "other_cpu_median_ms", "cpu_ratio", "note")


def pyrvo_missing() -> str | None:
    """Why ``pyrvo`` cannot be imported here, or None when it can."""
    try:
        import pyrvo  # noqa: F401
    except Exception as err:  # noqa: BLE001 - any failure means: skip the column
        return f"{type(err).__name__}: {err}"
    return None


# -- ORCA on the same scene ----------------------------------------------------------------

class Orca:
    """The scene's agents (and robot) as RVO2 agents; ``step()`` sets every preferred velocity
    in a Python loop and calls ``do_step``."""

    def __init__(self, scene: Scene, dt: float, seed: int = 0) -> None:
        import pyrvo

        q, r = scene.positions, scene.radii(0.0)
        spec = scene.spec
        drift = spec.get("drift") or {}
        speed = float(drift.get("speed", (spec.get("agents") or {}).get("speed", 1.3)))
        self.goal = (np.asarray(drift["goal"], dtype=np.float64)
                     if drift.get("kind") == "goal" else None)
        # people without a goal: a random velocity per axis of sd sigma (m/s), the scene's
        # Brownian displacement over 1 s
        self.still = float(np.mean((spec.get("noise") or {}).get("sigma", 0.0)))
        # time step, neighbour distance, max neighbours, time horizons (agents, obstacles),
        # radius, max speed: RVO2's example values (a 2 s horizon, 10 neighbours)
        self.sim = pyrvo.RVOSimulator(dt, 3.0, 10, 2.0, 2.0, float(r.max()), 2.0)
        self.targets: list[tuple[float, float, float]] = []  # goal x, y and speed per agent
        for i in range(len(q)):
            self.sim.add_agent((float(q[i, 0]), float(q[i, 1])))
            self.sim.set_agent_radius(i, float(r[i]))
            g = self.goal if self.goal is not None else (math.nan, math.nan)
            self.targets.append((float(g[0]), float(g[1]), speed))
        for robot in spec.get("robots") or []:
            k = self.sim.add_agent((float(robot["pose"][0]), float(robot["pose"][1])))
            self.sim.set_agent_radius(k, float(robot["radius"]))
            vmax = float((robot.get("kinematics") or {}).get("max_speed", 1.0))
            self.targets.append((float(robot["goal"][0]), float(robot["goal"][1]), vmax))
        for a, b in _segments(scene):
            self.sim.add_obstacle([a, b])
        self.sim.process_obstacles()
        self.rng = np.random.default_rng(seed)
        self.n = self.sim.get_num_agents()

    def step(self) -> None:
        """Preferred velocities (a Python loop over the agents, as an RVO2 user writes it),
        then one ORCA step."""
        sim = self.sim
        for i in range(self.n):
            gx, gy, speed = self.targets[i]
            if gx != gx:  # no goal: standing about
                vx, vy = self.rng.normal(0.0, self.still, 2)
            else:
                p = sim.get_agent_position(i)
                dx, dy = gx - p.x, gy - p.y
                d = math.hypot(dx, dy)
                vx, vy = (speed * dx / d, speed * dy / d) if d > 1e-9 else (0.0, 0.0)
            sim.set_agent_pref_velocity(i, (float(vx), float(vy)))
        sim.do_step()


def _segments(scene: Scene) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """The scene's static wall pieces as segments (polylines split)."""
    out = []
    for wall in scene.spec.get("walls") or []:
        pts = ([wall["a"], wall["b"]] if wall.get("kind") == "segment"
               else wall.get("points") or [])
        for a, b in zip(pts[:-1], pts[1:]):
            out.append(((float(a[0]), float(a[1])), (float(b[0]), float(b[1]))))
    return out


# -- measurements --------------------------------------------------------------------------

def _stats(seconds: list[float]) -> tuple[float, float]:
    ms = 1e3 * np.asarray(seconds)
    return float(np.median(ms)), float(np.percentile(ms, 90))


def engine_vs_orca(name: str, steps: int | None = None) -> dict[str, Any]:
    """One row: the engine step and ORCA's, interleaved step by step."""
    dt, warmup, measured = STEP_SCENES[name]
    measured = measured if steps is None else min(steps, measured)
    scene = load_scene(name)
    sim = Simulator(scene, dt=dt, seed=0)
    sim.step(warmup)
    missing = pyrvo_missing()
    orca = None if missing else Orca(scene, dt)
    if orca is not None:
        for _ in range(warmup):
            orca.step()
    ours, theirs, ours_cpu, theirs_cpu = [], [], [], []
    for _ in range(measured):
        start, cpu = time.perf_counter(), time.process_time()
        sim.step()
        ours.append(time.perf_counter() - start)
        ours_cpu.append(time.process_time() - cpu)
        if orca is not None:
            start, cpu = time.perf_counter(), time.process_time()
            orca.step()
            theirs.append(time.perf_counter() - start)
            theirs_cpu.append(time.process_time() - cpu)
    agents = scene.n_agents + len(scene.spec.get("robots") or [])
    row = {"measure": "engine step", "scene": name, "agents": agents, "other": "ORCA (pyrvo)",
           "note": f"dt {dt:g} s, steps {warmup + 1}-{warmup + measured}"}
    row["sweep_median_ms"], row["sweep_p90_ms"] = _stats(ours)
    if orca is None:
        row.update(other_median_ms=math.nan, other_p90_ms=math.nan, ratio=math.nan,
                   note=row["note"] + f"; ORCA n/a ({missing})")
    else:
        row["other_median_ms"], row["other_p90_ms"] = _stats(theirs)
        row["ratio"] = row["sweep_median_ms"] / row["other_median_ms"]
        # the process's CPU time: what a loaded machine's waiting for a core leaves out
        mine, other = _stats(ours_cpu)[0], _stats(theirs_cpu)[0]
        row.update(sweep_cpu_median_ms=mine, other_cpu_median_ms=other,
                   cpu_ratio=mine / other if other > 0 else math.nan)
        row["note"] += (f"; CPU time: {mine:.3f} / {other:.3f} ms = {row['cpu_ratio']:.1f}")
    return row


def recorded_vs_engine(name: str, steps: int) -> dict[str, Any]:
    """One row: ``record_run``'s step (the step, its recording and the run loop: the time
    between two of its ``on_state`` calls) against an identical simulator's unrecorded step,
    taken inside each ``on_state`` call: the two interleaved step by step."""
    dt, warmup, _ = STEP_SCENES[name]
    scene = load_scene(name)
    recorded_sim, plain_sim = Simulator(scene, dt=dt, seed=0), Simulator(scene, dt=dt, seed=0)
    recorded_sim.step(warmup)
    plain_sim.step(warmup)
    recorded: list[float] = []
    plain: list[float] = []
    last: list[float] = []

    def interleave(_: Simulator) -> None:
        now = time.perf_counter()
        if last:
            recorded.append(now - last[0])
        start = time.perf_counter()
        plain_sim.step()
        plain.append(time.perf_counter() - start)
        last[:] = [time.perf_counter()]

    t_end = recorded_sim.t + steps * dt
    with tempfile.TemporaryDirectory(prefix="sweep_bench_") as tmp:
        run = record_run(recorded_sim, t_end, Path(tmp) / "run.mcap",
                         run_metadata(scene, recorded_sim, t_end, 1), on_state=interleave)
    if run.status != "completed":
        raise RuntimeError(f"the recorded run of {name} {run.status}: {run.error}")
    row = {"measure": "sweep run step", "scene": name,
           "agents": scene.n_agents + len(scene.spec.get("robots") or []),
           "other": "engine step",
           "note": f"steps {warmup + 1}-{warmup + len(recorded)}, dt {dt:g} s"}
    row["sweep_median_ms"], row["sweep_p90_ms"] = _stats(recorded)
    row["other_median_ms"], row["other_p90_ms"] = _stats(plain[:len(recorded)])
    row["ratio"] = row["sweep_median_ms"] / row["other_median_ms"]
    return row


def env_rates(steps: int, num_envs: int, workers: int = 1) -> list[dict[str, Any]]:
    """Rows of the environment's steps per second, single and (when registered) vectorised,
    in this process and, for ``workers`` > 1, split over that many worker processes."""
    try:
        import sweep_core.envs as envs
    except ImportError as err:
        return [{"measure": "env steps/s", "scene": "crowdnav", "agents": 11, "other": "",
                 "note": f"n/a: gymnasium is not installed ({err})"}]
    rows = [_rate_single(steps, num_envs, envs.make_single)]
    if envs.has_vector():
        rows.append(_rate(f"env steps/s, K={num_envs}", steps, num_envs,
                          lambda: envs.make_vector(num_envs)))
        if 1 < workers <= num_envs:
            rows.append(_rate(f"env steps/s, K={num_envs}/{workers}", steps, num_envs,
                              lambda: envs.make_vector(num_envs, workers=workers), workers))
    return rows


def check_env_memory(num_envs: int, workers: int) -> None:
    """Refuses, before any row runs, the vectorised rows' ``num_envs`` environments and
    ``workers`` processes that the memory does not hold (the vector environment's own check,
    naming --num-envs and --env-workers); nothing without gymnasium or a vector entry point."""
    try:
        import sweep_core.envs as envs
    except ImportError:
        return
    if envs.has_vector():
        envs.check_memory(num_envs, workers if 1 < workers <= num_envs else 1,
                          {"num_envs": "--num-envs", "workers": "--env-workers"})


def _rate(label: str, steps: int, k: int, make: Callable[[], Any], workers: int = 1
          ) -> dict[str, Any]:
    env = make()
    try:
        env.reset(seed=0)
        action = _ahead(env)
        for _ in range(10):  # warm-up
            _step(env, action, k)
        calls = max(1, steps // k)
        start, cpu = time.perf_counter(), time.process_time()
        for _ in range(calls):
            _step(env, action, k)
        seconds = time.perf_counter() - start
        cpu = time.process_time() - cpu
    finally:
        env.close()
    cpu_note = (f"CPU time: {calls * k / max(cpu, 1e-9):.0f} env steps/s" if workers == 1 else
                f"{workers} worker processes, each stepping K/{workers} (their CPU time not "
                "counted here)")
    return _env_row(label, calls * k, seconds, f"resets included; {cpu_note}")


def _ahead(env: Any) -> np.ndarray:
    """The rows' action: ahead at 0.8 m/s, not turning (for each environment of a batch)."""
    action = np.zeros(env.action_space.shape)
    action[..., 0] = 0.8
    return action


def _env_row(label: str, n: int, seconds: float, note: str) -> dict[str, Any]:
    """An environment row: ``n`` env steps in ``seconds`` (wall clock); ``note`` follows the
    rate."""
    return {"measure": label, "scene": "crowdnav", "agents": 11, "other": "",
            "sweep_median_ms": 1e3 * seconds / n, "sweep_p90_ms": math.nan,
            "other_median_ms": math.nan, "other_p90_ms": math.nan, "ratio": math.nan,
            "note": f"{n / seconds:.0f} env steps/s over {n} env steps, {note}"}


def _rate_single(steps: int, k: int, make: Callable[[], Any]) -> dict[str, Any]:
    """The single environment over the episodes the vectorised rows step: seeds 0 .. k - 1
    in turn, each reset with its seed, 10 untimed steps, then ``steps // k`` timed steps (the
    vectorised rows' calls), reset at the end of an episode (resets timed)."""
    env = make()
    calls = max(1, steps // k)
    seconds = cpu = 0.0
    try:
        action = _ahead(env)
        for seed in range(k):
            env.reset(seed=seed)
            for _ in range(10):  # the vectorised rows' warm-up
                _step(env, action, 1)
            start, began = time.perf_counter(), time.process_time()
            for _ in range(calls):
                _step(env, action, 1)
            seconds += time.perf_counter() - start
            cpu += time.process_time() - began
    finally:
        env.close()
    n = calls * k
    return _env_row("env steps/s, single", n, seconds,
                    f"the vectorised rows' episodes (seeds 0-{k - 1}, {calls} steps each after "
                    f"10), resets included; CPU time: {n / max(cpu, 1e-9):.0f} env steps/s")


def _step(env: Any, action: np.ndarray, k: int) -> None:
    """One step; the single environment is reset at the end of an episode (the vectorised one
    resets its own environments)."""
    out = env.step(action)
    if k == 1 and (out[2] or out[3]):
        env.reset()


def _cell(value: Any, width: int) -> str:
    if isinstance(value, float):
        return f"{'n/a':>{width}}" if math.isnan(value) else f"{value:>{width}.3f}"
    return f"{value!s:>{width}}"


_SHOWN = (("measure", 22), ("scene", 12), ("agents", 6), ("sweep_median_ms", 9),
          ("sweep_p90_ms", 9), ("other", 13), ("other_median_ms", 9), ("other_p90_ms", 9),
          ("ratio", 7))


def most_run_steps() -> int:
    """The largest ``--run-steps``: each scene's recorded run (a temporary MCAP file) within
    ``sweep run``'s bounds without ``--force``: at most ``limits.MAX_STEPS`` steps, and a
    recording of at most ``limits.MAX_RECORDING_BYTES`` (uncompressed, as ``sweep run``
    estimates it: about 18 kB a step for room_door's 200 people)."""
    most = limits.MAX_STEPS
    for name in STEP_SCENES:
        scene = load_scene(name)
        agents = scene.n_agents + len(scene.spec.get("robots") or [])
        most = min(most, limits.MAX_RECORDING_BYTES // limits.frame_bytes(agents) - 1)
    return most


def run(args: argparse.Namespace) -> int:
    """The study (module docstring): prints the table, writes the CSV."""
    for name, default in STEPS_DEFAULTS.items():
        if getattr(args, name) is None:
            setattr(args, name, default)
    options.counts([args.run_steps], "--run-steps", high=most_run_steps(), example="200")
    # as many environment steps as a run of sweep run takes at most (1e6: minutes per row)
    options.counts([args.env_steps], "--env-steps", high=limits.MAX_STEPS, example="2000")
    options.counts([args.num_envs], "--num-envs", high=1024, example="32")
    if args.env_workers is None:  # the default: 2, or fewer on a single core or for K < 2
        args.env_workers = min(2, default_workers(), args.num_envs)
    options.counts([args.env_workers], "--env-workers", high=args.num_envs, example="2")
    options.csv_path(args.csv)
    kernels.warm_up(lambda line: print(f"sweep: {line}", flush=True))
    check_env_memory(args.num_envs, args.env_workers)  # the environments' rows come last
    missing = pyrvo_missing()
    if missing:
        print(f"ORCA: skipped ({missing}); install pyrvo (requirements-dev.txt) for its column; "
              "it is never a dependency of sweep_ros")
    print("ms per step: median and p90 over the measured steps; ratio = sweep / other "
          "(medians)")
    print(" ".join(f"{head[:w]:>{w}}" for head, w in _SHOWN) + "  note", flush=True)
    rows: list[dict[str, Any]] = []

    def show(row: dict[str, Any]) -> None:
        rows.append(row)
        print(" ".join(_cell(row.get(c, math.nan), w) for c, w in _SHOWN)
              + f"  {row.get('note', '')}", flush=True)

    for name in STEP_SCENES:
        show(engine_vs_orca(name))
    for name in STEP_SCENES:
        show(recorded_vs_engine(name, args.run_steps))
    for row in env_rates(args.env_steps, args.num_envs, args.env_workers):
        show(row)
    write_csv(Path(args.csv), rows, COLUMNS)
    print(f"csv: {args.csv}")
    return 0


def add_options(p: argparse.ArgumentParser) -> None:
    """The options of the ``steps`` scene set on ``sweep bench speed``."""
    p.add_argument("--run-steps", type=int, default=None, metavar="STEPS",
                   help="steps: with --scenes steps, steps of the recorded run measured, each "
                        f"beside an unrecorded step (default {STEPS_DEFAULTS['run_steps']})")
    p.add_argument("--env-steps", type=int, default=None, metavar="STEPS",
                   help="steps: environment steps timed, single and vectorised (default "
                        f"{STEPS_DEFAULTS['env_steps']})")
    p.add_argument("--num-envs", type=int, default=None, metavar="K",
                   help="steps: environments of the vectorised environment (default "
                        f"{STEPS_DEFAULTS['num_envs']})")
    p.add_argument("--env-workers", type=int, default=None, metavar="W",
                   help="steps: worker processes of the vectorised environment's second row "
                        "(default: 2, or 1 on a single core or with --num-envs 1: no such "
                        "row)")
