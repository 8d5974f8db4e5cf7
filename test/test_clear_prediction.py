"""A prediction that holds every row is answered without building the rows
(``projection.clear``): the same answer as building them, bit for bit."""
from __future__ import annotations

import importlib

import numpy as np
import pytest
from test_projection import random_crowd

import sweep_core as sc
from sweep_core.errors import SceneError
from sweep_core.numerics.constraints import linearise
from sweep_core.numerics.projection import clear
from sweep_core.numerics.projection.options import ROW_TOLERANCE
from sweep_core.numerics.projection.project import first_cutoff, project
from sweep_core.numerics.simulator import violating_agents

#: the module (the package exports its function of the same name)
project_module = importlib.import_module("sweep_core.numerics.projection.project")

WALLS = [{"kind": "halfplane", "normal": [1, 0], "offset": 0.0},
         {"kind": "halfplane", "normal": [0.6, 0.8], "offset": -0.5},
         {"kind": "segment", "a": [4.0, -1.0], "b": [4.0, 5.0]},
         {"kind": "segment", "a": [-1.0, 4.0], "b": [5.0, 4.2]}]
OBSTACLES = [{"kind": "circle", "center": [2.0, 2.0], "radius": 0.3}]


def scene_of(q: np.ndarray, r: float) -> sc.Scene:
    return sc.Scene.from_dict({"agents": {"positions": q.tolist(), "radius": r},
                               "walls": WALLS, "obstacles": OBSTACLES})


def by_rows(scene: sc.Scene, q: np.ndarray, pred: np.ndarray, cut: float) -> int:
    """What building the rows says: -1 if a row fails at pred, else the rows that hold with
    equality there."""
    rows = linearise(scene.geometry, 0.1, q, scene.radii(0.1), cut)
    rp, rs = rows.residuals(pred)
    res = np.concatenate([rp, rs])
    if not np.all(res >= 0.0):
        return -1
    return int(np.count_nonzero(res <= ROW_TOLERANCE))


def crowd_between_walls(rng: np.random.Generator, n: int, r: float) -> np.ndarray:
    """n disks clear of each other, the walls and the obstacle (rejection sampling)."""
    while True:
        q = random_crowd(rng, n, 3.6, r) + 0.2
        try:
            if not violating_agents(scene_of(q, r), 0.0, q):
                return q
        except SceneError:  # a disk on a wall or the obstacle
            continue


@pytest.mark.parametrize("seed", range(12))
def test_the_pass_says_what_the_rows_say(seed: int) -> None:
    rng = np.random.default_rng(seed)
    r = 0.2
    q = crowd_between_walls(rng, 12, r)
    scene = scene_of(q, r)
    answers = set()
    for spread in (0.002, 0.01, 0.03, 0.1):
        pred = q + rng.normal(0.0, spread, q.shape)
        cut = first_cutoff(q, pred, scene.radii(0.1))
        want = by_rows(scene, q, pred, cut)
        got = clear.clear_active(scene.geometry, q, pred, scene.radii(0.1), cut)
        assert got == want
        answers.add(want >= 0)
    # rows that hold with equality: every agent's prediction on its contacts (q itself, where
    # the sampled disks touch nothing, so also a crowd pushed into contact)
    pred = q.copy()
    cut = first_cutoff(q, pred, scene.radii(0.1))
    assert clear.clear_active(scene.geometry, q, pred, scene.radii(0.1), cut) == \
        by_rows(scene, q, pred, max(cut, 1e-3 * r))


def test_rows_holding_with_equality_are_counted() -> None:
    # two disks touching each other, one of them touching the half-plane x >= 0 (exact in
    # binary): two rows hold with equality at q (residual 0) and the prediction stays
    q = np.array([[0.25, 1.0], [0.75, 1.0], [1.5, 1.5]])
    scene = scene_of(q, 0.25)
    cut = first_cutoff(q, q, scene.radii(0.1))
    assert by_rows(scene, q, q, cut) == 2
    assert clear.clear_active(scene.geometry, q, q, scene.radii(0.1), cut) == 2


def test_a_failing_row_or_nan_sends_the_step_to_the_rows() -> None:
    q = np.array([[1.0, 1.0], [1.6, 1.0]])
    scene = scene_of(q, 0.2)
    r = scene.radii(0.1)
    pred = q + np.array([[0.15, 0.0], [-0.15, 0.0]])  # overlapping by 0.1 m
    assert clear.clear_active(scene.geometry, q, pred, r, first_cutoff(q, pred, r)) == -1
    pred = q.copy()
    pred[1, 0] = np.nan
    assert clear.clear_active(scene.geometry, q, pred, r, 1.0) == -1
    # scenes the pass does not answer for
    assert clear.clear_active(scene.geometry, q, q, r, 0.5 * clear.MIN_CUT) == -1
    many = crowd_between_walls(np.random.default_rng(3), clear.MAX_AGENTS + 1, 0.1)
    crowd = scene_of(many, 0.1)
    assert clear.clear_active(crowd.geometry, many, many, crowd.radii(0.1), 0.1) == -1


@pytest.mark.parametrize("seed", range(6))
def test_projections_with_and_without_the_pass_are_the_same(seed: int, monkeypatch) -> None:
    """A run of steps with the pass and one without give the same bits (positions, active
    rows, bound), and the pass answered some steps."""
    spec = {"agents": {"positions": crowd_between_walls(np.random.default_rng(seed), 10,
                                                       0.2).tolist(), "radius": 0.2},
            "walls": WALLS, "obstacles": OBSTACLES, "noise": {"sigma": 0.3},
            "drift": {"kind": "goal", "goal": [3.5, 3.0], "speed": 1.0}}
    calls = {"clear": 0}
    passed = clear.clear_active

    def counting(*args: object) -> int:
        out = passed(*args)  # type: ignore[arg-type]
        calls["clear"] += int(out >= 0)
        return out

    def run() -> list[tuple]:
        sim = sc.Simulator(sc.Scene.from_dict(spec), 0.05, seed)
        out = []
        for _ in range(60):
            sim.step()
            p = sim.last.projection
            out.append((sim.positions.tobytes(), p.active, p.bound, p.solves > 0))
        return out

    monkeypatch.setattr(project_module, "clear_active", counting)
    fast = run()
    monkeypatch.setattr(project_module, "clear_active", lambda *args: -1)
    slow = run()
    assert fast == slow
    assert calls["clear"] > 0 and any(solved for *_, solved in fast)


def test_a_clear_prediction_is_returned_as_it_is() -> None:
    q = np.array([[1.0, 1.0], [2.5, 1.0]])
    scene = scene_of(q, 0.2)
    pred = q + 0.01
    got = project(scene.geometry, 0.1, q, pred, scene.radii(0.1), sc.SolverOptions())
    assert got.y.tobytes() == pred.tobytes() and got.y is not pred
    assert (got.qp_size, got.solves, got.bound, got.rows.count) == (0, 0, 0.0, 0)
