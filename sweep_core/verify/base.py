"""What a verification test is made of: the runs it needs (:class:`Case`), one seeded run
as a worker executes it (:func:`simulate`, giving a :class:`Trace`), and the verdict over the
seeds (:class:`Verdict`, :class:`Test`).

A case is a bundled scene (``sweep_core/scenes/rimea/NAME.yaml``, or the file of that name in
the folder given by ``--scenes``) with keys changed by the test (dotted keys, as ``sweep
ensemble --vary`` takes them), a horizon, a time step and a recording interval. A run is built
as ``sweep run`` builds it (``Scene.from_dict``, ``Simulator(scene, dt, seed)``); the spawned
crowd of a scene with ``agents.spawn`` is drawn with the run's seed.

A run's outcome depends on its case and seed only: it ends at the case's horizon ``t_end``
in simulated time (or once every agent left, with ``stop_when_empty``), never on a clock; the
wall time it took is kept for information (``Trace.wall_s``) and judges nothing.
"""
from __future__ import annotations

import copy
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from sweep_core.analysis.pedpy_export import Trajectories
from sweep_core.errors import SceneError, SweepError
from sweep_core.model.scene import Scene
from sweep_core.model.yaml_files import load_yaml
from sweep_core.numerics.simulator import Simulator

#: the folder of the bundled scenes, inside the package
SCENES = "scenes/rimea"


def scene_text(name: str, folder: str | None = None) -> str:
    """The YAML text of scene ``name`` (without .yaml): from ``folder`` when given and it
    holds that file, else the bundled one."""
    if folder is not None:
        path = Path(folder) / f"{name}.yaml"
        if path.is_file():
            return path.read_text()
    return resources.files("sweep_core").joinpath(f"{SCENES}/{name}.yaml").read_text()


def set_key(spec: dict, key: str, value: Any) -> None:
    """spec[a][b]... = value for the dotted key ``a.b...`` (list indices as numbers)."""
    parts = key.split(".")
    node: Any = spec
    for part in parts[:-1]:
        node = node[int(part)] if isinstance(node, list) else node.setdefault(part, {})
    last = parts[-1]
    if isinstance(node, list):
        node[int(last)] = value
    else:
        node[last] = value


@dataclass(frozen=True)
class Case:
    """One run of a test: ``label`` (unique in the test), the scene ``scene`` (a bundled name),
    ``changes`` (dotted key -> value), horizon ``t_end`` (s), ``dt`` (s), ``record_every``
    (steps between recorded frames), ``stop_when_empty`` (end once every agent left);
    ``inline``: a scene dict built by the test instead of a bundled file (``scene`` names it)."""

    label: str
    scene: str
    t_end: float
    changes: tuple[tuple[str, Any], ...] = ()
    dt: float = 0.05
    record_every: int = 4
    stop_when_empty: bool = False
    inline: dict | None = None

    def spec(self, seed: int, folder: str | None = None) -> dict:
        """The scene dict of this case for a seed (a spawned crowd takes the seed)."""
        data = self.inline if self.inline is not None else load_yaml(scene_text(self.scene,
                                                                                folder))
        if not isinstance(data, dict):
            raise SceneError(self.scene, "is not a mapping", "give a scene YAML file")
        spec = copy.deepcopy(data)
        for key, value in self.changes:
            set_key(spec, key, copy.deepcopy(value))
        if isinstance(spec.get("agents"), dict) and isinstance(spec["agents"].get("spawn"), dict):
            spec["agents"]["spawn"]["seed"] = int(seed)
        return spec


@dataclass
class Trace:
    """What one run left for the verdict: ``traj`` (every recorded frame), ``left_at`` (id ->
    time, s, of leaving at a sink), ``left_xy`` (id -> last centre before leaving, m),
    ``start`` (id -> centre at t = 0), ``walls`` (the scene's walls spec), ``speeds`` (id ->
    preferred speed, m/s, when the scene draws them), ``t_end`` (simulated time reached, s),
    ``t_limit`` (the case's horizon, s), ``error`` (the failure, "" if none), ``wall_s`` (the
    wall time it took, s: information only, no verdict reads it)."""

    case: str
    seed: int
    traj: Trajectories
    left_at: dict[int, float] = field(default_factory=dict)
    left_xy: dict[int, tuple[float, float]] = field(default_factory=dict)
    start: dict[int, tuple[float, float]] = field(default_factory=dict)
    speeds: dict[int, float] = field(default_factory=dict)
    t_end: float = 0.0
    n0: int = 0
    walls: list = field(default_factory=list)
    error: str = ""
    wall_s: float = 0.0
    t_limit: float = 0.0

    def positions(self, agent: int) -> tuple[np.ndarray, np.ndarray]:
        """Times (s) and centres (K, 2) of one agent's recorded frames."""
        sel = self.traj.ids == agent
        return self.traj.frames[sel] / self.traj.frame_rate, self.traj.xy[sel]


def simulate(case: Case, seed: int, folder: str | None = None) -> Trace:
    """Run one case with one seed (a worker's task); any failure is returned in ``error``."""
    start = time.perf_counter()
    rate = 1.0 / (case.dt * case.record_every)
    frames: list[tuple[int, np.ndarray, np.ndarray]] = []
    trace = Trace(case.label, seed, Trajectories.from_frames([], rate), t_limit=case.t_end)
    try:
        spec = case.spec(seed, folder)
        trace.walls = list(spec.get("walls") or [])
        scene = Scene.from_dict(spec, name=case.scene)
        sim = Simulator(scene, dt=case.dt, seed=seed)
        trace.n0 = scene.n_agents
        last = [sim.ids, sim.positions]
        trace.start = {int(i): (float(x), float(y)) for i, (x, y) in zip(*last)}
        pop = sim.flows
        if pop is not None and getattr(pop, "scaled", False):
            trace.speeds = {int(i): float(pop.speed[i]) for i in last[0]}

        def record(s: Simulator) -> None:
            ids, q = s.ids, s.positions
            gone = np.setdiff1d(last[0], ids)
            for i in gone.tolist():
                k = int(np.flatnonzero(last[0] == i)[0])
                trace.left_xy[int(i)] = (float(last[1][k, 0]), float(last[1][k, 1]))
            last[0], last[1] = ids, q
            if s.n_steps % case.record_every == 0:
                frames.append((s.n_steps // case.record_every, ids, q))
            if case.stop_when_empty and len(ids) == 0 and s.flows is not None \
                    and not _more_to_come(s):
                raise _Done

        record(sim)
        try:
            sim.run(case.t_end, callback=record)
        except _Done:
            pass
        trace.t_end = sim.t
        if pop is not None:
            trace.left_at = {int(k): float(v) for k, v in pop.left_at.items()}
            if getattr(pop, "scaled", False):
                trace.speeds.update({int(i): float(pop.speed[i]) for i in sim.ids})
    except SweepError as err:
        trace.error = str(err)
    except Exception as err:  # noqa: BLE001 - a failed run is a failed verdict, not a crash
        trace.error = f"{type(err).__name__}: {err}"
    trace.traj = Trajectories.from_frames(frames, rate)
    trace.wall_s = time.perf_counter() - start
    return trace


class _Done(Exception):
    """Ends a run early: every agent left and none is still due."""


def _more_to_come(sim: Simulator) -> bool:
    pop = sim.flows
    return bool(pop is not None and pop.flows.sources and
                any(k < len(src.times) for k, src in zip(pop.next, pop.flows.sources)))


def failing(conditions: Sequence[tuple[bool, str]]) -> tuple[bool, str]:
    """A seed's pass and why it fails: ``conditions`` are (holds, what failed, said when it
    does not hold); returns whether all hold and the failed ones joined by "; "."""
    failed = [text for holds, text in conditions if not holds]
    return not failed, "; ".join(failed)


def ran(tr: Trace) -> tuple[bool, str]:
    """The condition that a run ended without an error (the error quoted when it did not)."""
    return not tr.error, f"run error in case {tr.case}: {tr.error[:200]}"


def all_left(tr: Trace) -> tuple[bool, str]:
    """The condition that every agent of a run left (at a sink): how many had not, and when
    the run ended (its horizon, simulated time)."""
    gone = len(tr.left_at)
    return (tr.n0 > 0 and gone >= tr.n0,
            f"{tr.n0 - gone} of {tr.n0} agents had not left when case {tr.case} ended at "
            f"t = {tr.t_end:g} s (its limit {tr.t_limit:g} s of simulated time)")


@dataclass
class Verdict:
    """A test's result: ``values`` (one per seed, the measured quantity), ``passed`` (per
    seed; None: the test documents and has no threshold), ``unit``, ``notes`` (extra figures
    for the line and the report), and ``reasons`` (per seed: the conditions that failed, ""
    where it passed; the runner adds run errors)."""

    values: list[float]
    passed: list[bool] | None
    unit: str = ""
    notes: str = ""
    figures: dict[str, Any] = field(default_factory=dict)
    reasons: list[str] = field(default_factory=list)

    @classmethod
    def judged(cls, values: list[float],
               checks: Sequence[Sequence[tuple[bool, str]]], unit: str = "",
               notes: str = "") -> Verdict:
        """From the conditions of each seed (:func:`failing`): passed where all hold, and
        the failed ones as the seed's reason."""
        out = [failing(c) for c in checks]
        return cls(values, [ok for ok, _ in out], unit, notes,
                   reasons=[why for _, why in out])

    def fail(self, k: int, why: str) -> None:
        """Seed number ``k`` (its position) fails for ``why`` (added to its reason)."""
        n = len(self.values)
        if self.passed is None:
            self.passed = [True] * n
        self.reasons += [""] * (n - len(self.reasons))
        self.passed[k] = False
        self.reasons[k] = f"{self.reasons[k]}; {why}" if self.reasons[k] else why

    def failures(self, seeds: Sequence[int]) -> str:
        """The failing seeds and why, "seed 0: ...; seed 2: ..." ("" when none fails); a
        failing seed without a reason says so rather than nothing."""
        if self.passed is None:
            return ""
        reasons = self.reasons + [""] * (len(self.passed) - len(self.reasons))
        return " | ".join(f"seed {seed}: {why or 'failed (no condition recorded)'}"
                          for seed, ok, why in zip(seeds, self.passed, reasons) if not ok)

    @property
    def status(self) -> str:
        if self.passed is None:
            return "DOC"
        return "PASS" if self.passed and all(self.passed) else "FAIL"

    def spread(self) -> str:
        """The mean value and its spread over seeds: "m (min-max, n seeds)"."""
        v = np.asarray([x for x in self.values if math.isfinite(x)], dtype=np.float64)
        if not len(v):
            return "no value"
        if len(v) == 1:
            return f"{v[0]:.3g}{self.unit}"
        return (f"{v.mean():.3g}{self.unit} (range {v.min():.3g}-{v.max():.3g}, "
                f"{len(self.values)} seeds)")


@dataclass(frozen=True)
class Test:
    """A verification test: ``key`` (its command-line name, e.g. ``rimea1``), ``title``,
    ``measures`` and ``criterion`` (printed), ``cases(quick)`` the runs per seed,
    ``judge(traces, quick)`` the verdict from {case label: [trace per seed]}, ``plot(traces,
    verdict, folder)`` its figures (paths written), ``source``: where the scene and the
    criterion come from (for the report)."""

    key: str
    title: str
    measures: str
    criterion: str
    cases: Callable[[bool], Sequence[Case]]
    judge: Callable[[dict[str, list[Trace]], bool], Verdict]
    plot: Callable[[dict[str, list[Trace]], Verdict, Path], list[Path]] | None = None
    source: str = ""
    slow: bool = False
