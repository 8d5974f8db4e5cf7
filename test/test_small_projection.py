"""A small scene's projection in one compiled call (``projection.small``) has the bits of
``project``'s own path, field by field, and leaves every other case to that path."""
from __future__ import annotations

import importlib
from typing import Any

import numpy as np
import pytest

import sweep_core as sc
from sweep_core.numerics import schemes
from sweep_core.numerics.projection import SolverOptions, small
from sweep_core.numerics.robots import fleet, small_step

project_module = importlib.import_module("sweep_core.numerics.projection.project")

WALLS = [{"kind": "segment", "a": [-1.0, 0.0], "b": [9.0, 0.0]},
         {"kind": "segment", "a": [-1.0, 3.0], "b": [9.0, 3.0]},
         {"kind": "halfplane", "normal": [1.0, 0.0], "offset": -1.0}]


def crowded(sigma: float) -> sc.Scene:
    """Twelve people walking west into a robot driving east between two walls, round a
    circle obstacle: contacts on many steps (people with people, walls, the obstacle and the
    robot's disk, which the fleet appends to the circles)."""
    rng = np.random.default_rng(11)
    q = np.column_stack([rng.uniform(2.0, 8.0, 40), rng.uniform(0.4, 2.6, 40)])
    keep: list[int] = []
    for k in range(len(q)):
        if (np.hypot(*(q[k] - [5.0, 1.5])) > 0.6
                and (not keep or np.min(np.hypot(*(q[keep] - q[k]).T)) > 0.52)):
            keep.append(k)
    kin = {"type": "diff_drive", "max_speed": 1.0, "max_angular_speed": 2.0,
           "max_acceleration": 3.0, "max_angular_acceleration": 6.0}
    return sc.Scene.from_dict({
        "agents": {"positions": q[keep[:12]].tolist(), "radius": 0.25},
        "drift": {"kind": "goal", "goal": [-2.0, 1.5], "speed": 1.0},
        "noise": {"sigma": sigma},
        "walls": WALLS,
        "obstacles": [{"kind": "circle", "center": [5.0, 1.5], "radius": 0.3}],
        "robots": [{"name": "robot", "radius": 0.3, "pose": [0.2, 1.5, 0.0],
                    "kinematics": kin, "weight": "inf"}]})


def gathering() -> sc.Scene:
    """Twenty people in open space (no wall, no robot) walking to one point: a growing
    cluster of contacts, projected through the scheme's own step."""
    angles = np.linspace(0.0, 2.0 * np.pi, 20, endpoint=False)
    q = np.column_stack([3.0 * np.cos(angles), 3.0 * np.sin(angles)])
    return sc.Scene.from_dict({"agents": {"positions": q.tolist(), "radius": 0.25},
                               "drift": {"kind": "goal", "goal": [0.0, 0.0], "speed": 1.2},
                               "noise": {"sigma": 0.1}})


def captured(monkeypatch: pytest.MonkeyPatch, scene: sc.Scene, steps: int,
             dt: float) -> list[tuple[Any, ...]]:
    """The arguments of every projection the steps asked for (the robots' general path's
    or, without robots, the scheme's)."""
    calls: list[tuple[Any, ...]] = []
    where = fleet if scene.robots else schemes
    real = where.project

    def spy(geom: Any, t1: float, q: np.ndarray, pred: np.ndarray, r1: np.ndarray,
            opts: SolverOptions, warm: Any = None) -> Any:
        calls.append((geom, t1, q.copy(), pred.copy(), r1.copy(), opts, warm))
        return real(geom, t1, q, pred, r1, opts, warm=warm)

    monkeypatch.setattr(where, "project", spy)
    # the robots' steps with contacts project through the fleet (not in small_step's call)
    monkeypatch.setattr(small_step, "applies", lambda *args: False)
    sim = sc.Simulator(scene, dt=dt, seed=4)
    for _ in range(steps):
        if scene.robots:
            sim.robots.command("robot", (1.0, 0.0, 0.0))
        sim.step()
    monkeypatch.undo()
    return calls


def same(a: Any, b: Any) -> None:
    """Two projections with the same bits in every field."""
    for name in ("y", "lam_pair", "lam_single"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes(), name
    for name in ("active", "qp_size", "solves", "backend_agents", "bound", "sweeps",
                 "fallback_agents", "stuck_steps"):
        assert getattr(a, name) == getattr(b, name), name
    assert a.stuck is None and b.stuck is None
    for name in a.rows.__dataclass_fields__:
        x, y = getattr(a.rows, name), getattr(b.rows, name)
        assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes(), name


@pytest.mark.parametrize("scene", ["robot", "noisy robot", "gathering"])
def test_the_compiled_answer_has_the_bits_of_projects_own_path(
        monkeypatch: pytest.MonkeyPatch, scene: str) -> None:
    made = {"robot": lambda: crowded(0.0), "noisy robot": lambda: crowded(0.3),
            "gathering": gathering}[scene]()
    calls = captured(monkeypatch, made, 150, 0.02)
    answered = solved = carried = 0
    real = small.small_projection
    for geom, t1, q, pred, r1, opts, warm in calls:
        fast = project_module.project(geom, t1, q, pred, r1, opts, warm=warm)
        with monkeypatch.context() as m:
            m.setattr(small, "applies", lambda *args: False)
            slow = project_module.project(geom, t1, q, pred, r1, opts, warm=warm)
        same(fast, slow)
        cut = project_module.first_cutoff(q, pred, r1)
        if small.applies(geom, len(q), opts, False):
            hold = (warm.rows, warm.lam_pair, warm.lam_single) if warm is not None else None
            if real(geom, q, pred, r1, cut, opts, hold) is not None:
                answered += 1
                solved += fast.solves
                carried += int(warm is not None and warm.rows.count > 0 and fast.solves > 0)
    # the compiled call answered QPs, some warm-started from the step before
    assert answered >= 20 and solved >= 10 and carried >= 5, (answered, solved, carried)


def test_what_the_rounds_cannot_certify_or_a_narrow_cutoff_goes_to_projects_path(
        monkeypatch: pytest.MonkeyPatch) -> None:
    calls = captured(monkeypatch, crowded(0.0), 150, 0.02)
    with_qp = [c for c in calls
               if project_module.project(*c[:6], warm=c[6]).qp_size > 0]
    assert with_qp
    geom, t1, q, pred, r1, opts, warm = with_qp[0]
    cut = project_module.first_cutoff(q, pred, r1)
    # no round allowed: the clusters stay uncertified (the cluster solvers' work)
    none = SolverOptions.from_values(max_rounds=0)
    assert small.small_projection(geom, q, pred, r1, cut, none, None) is None
    # a cutoff the answer moves beyond: project widens it
    moved = float(np.max(np.hypot(*(project_module.project(*with_qp[0][:6]).y - q).T)))
    assert small.small_projection(geom, q, pred, r1, moved, opts, None) is None
    # ... and project's answers there are its own path's
    for options in (none, opts):
        fast = project_module.project(geom, t1, q, pred, r1, options)
        with monkeypatch.context() as m:
            m.setattr(small, "applies", lambda *args: False)
            slow = project_module.project(geom, t1, q, pred, r1, options)
        assert fast.y.tobytes() == slow.y.tobytes() and fast.bound == slow.bound


def test_it_applies_only_to_small_static_scenes() -> None:
    scene = crowded(0.0)
    geom, opts = scene.geometry, SolverOptions()
    assert small.applies(geom, 12, opts, False)
    assert not small.applies(geom, 12, opts, True)  # clusters held back last step
    assert not small.applies(geom, 1, opts, False)
    assert not small.applies(geom, 65, opts, False)
    assert not small.applies(geom, 12, SolverOptions.from_values(method="clusters"), False)
