"""The certified projection: its answer against an independent exact reference, its certificate
never below the true distance, warm starts, the fallback, feasibility and reproducibility."""
from __future__ import annotations

import dataclasses
import importlib

import numpy as np
import pytest
from scenes import hex_jam
from test_projection import jam_steps, random_crowd, reference

import sweep_core as sc
from sweep_core.numerics import projection
from sweep_core.numerics.projection import certified


def random_jam(seed: int, n: int = 40) -> dict:
    """n disks of radius 0.2 m at random in a square sized for them (about 45 % covered), all
    heading for its centre with speed 2 m/s and noise 0.2."""
    box = 0.6 * np.sqrt(n) + 0.4
    q = random_crowd(np.random.default_rng(seed), n, box, 0.2)
    return {"agents": {"positions": q.tolist(), "radius": 0.2},
            "drift": {"kind": "goal", "goal": [box / 2, box / 2], "speed": 2.0},
            "noise": {"sigma": 0.2}}


#: the projection's module (the package re-exports its function under the same name)
project_module = importlib.import_module("sweep_core.numerics.projection.project")

JAMS = [hex_jam(6, 6), hex_jam(8, 8), random_jam(0), random_jam(1), random_jam(2, n=60)]
IDS = ["hex36", "hex64", "rand0", "rand1", "rand2"]


def loose(**kw) -> sc.SolverOptions:
    return dataclasses.replace(sc.SolverOptions(), **kw)


@pytest.mark.parametrize("tol", [1e-6, 1e-3])
@pytest.mark.parametrize("spec", JAMS, ids=IDS)
def test_answer_is_within_its_bound_of_the_exact_projection(spec, tol):
    """Against the exact active-set projection over every row (no cutoff, no clusters, no
    sweeps): the distance is at most the certified bound, the bound at most tol (2e-6 m at the
    default tolerance), and every row holds."""
    for scene, t1, q, pred, proj in jam_steps(spec, seed=3, steps=6, opts=loose(tol=tol)):
        want = reference(scene, t1, q, pred)
        dist = float(np.sqrt(((proj.y - want) ** 2).sum()))
        assert dist <= proj.bound + 1e-12, (dist, proj.bound)
        assert proj.bound <= tol
        rp, rs = proj.rows.residuals(proj.y)
        assert min(rp.min(initial=0), rs.min(initial=0)) >= -1e-12
        if tol == 1e-6:
            assert dist <= 2e-6


@pytest.mark.parametrize("spec", JAMS, ids=IDS)
def test_bound_is_never_below_the_true_distance_of_an_unfinished_answer(spec, monkeypatch):
    """Stopped after one round of one sweep and two CG iterations (tol huge, no fallback), the
    answer is far from exact; its bound must still cover the true distance."""
    monkeypatch.setattr(certified, "SWEEPS", 1)
    monkeypatch.setattr(certified, "CG_ITERS", 2)
    monkeypatch.setattr(certified, "PASSES", 1)
    # every step gets its round (a cluster left to the cluster solvers would otherwise skip
    # the rounds on the next steps and be solved exactly)
    monkeypatch.setattr(project_module, "RETRY", 1)
    opts = loose(tol=1.0, max_rounds=1, warm_start=False)
    seen = 0
    for scene, t1, q, pred, proj in jam_steps(spec, seed=7, steps=4, opts=opts):
        if not np.isfinite(proj.bound):
            continue  # rows still violated: nothing certified, nothing claimed
        dist = float(np.sqrt(((proj.y - reference(scene, t1, q, pred)) ** 2).sum()))
        assert dist <= proj.bound + 1e-12
        seen += dist > 1e-9
    assert seen, "every answer was exact: the test did not test the bound"


def deep_jam(n: int = 300, seed: int = 0) -> dict:
    """A disordered, polydisperse crowd (radii 0.20-0.27 m) on a jittered lattice, all pushed
    to its centre at 1 m/s with noise 0.08 (the issue's dense-crowd benchmark, small)."""
    rng = np.random.default_rng(seed)
    cols = int(np.ceil(np.sqrt(n)))
    pos = np.array([(c * 0.6 + (r % 2) * 0.3, r * 0.6 * np.sqrt(3) / 2)
                    for r in range(cols) for c in range(cols)][:n])
    pos += rng.uniform(-0.03, 0.03, pos.shape)
    return {"agents": {"positions": pos.tolist(), "radius": rng.uniform(0.2, 0.27, n).tolist()},
            "drift": {"kind": "goal", "goal": pos.mean(axis=0).tolist(), "speed": 1.0},
            "noise": {"sigma": 0.08}}


@pytest.mark.parametrize("spec", JAMS[:3], ids=IDS[:3])
def test_warm_start_changes_the_answer_only_within_the_tolerance(spec):
    warm = list(jam_steps(spec, seed=5, steps=5, opts=loose(warm_start=True)))
    cold = list(jam_steps(spec, seed=5, steps=5, opts=loose(warm_start=False)))
    for (*_, a), (*_, b) in zip(warm, cold):
        assert np.sqrt(((a.y - b.y) ** 2).sum()) <= a.bound + b.bound + 1e-12


def test_warm_start_saves_sweeps_in_a_deep_jam():
    """Same states (the warm run's), solved from the previous step's multipliers or from 0."""
    scene = sc.Scene.from_dict(deep_jam())
    sim = sc.Simulator(scene, dt=0.02, seed=1)
    sim.step(30)  # pressed together
    warm = cold = 0
    for _ in range(5):
        previous = sim.last.projection
        q, t1 = sim.positions, sim.t + sim.dt
        sim.step()
        pred = sim.last.prediction
        warm += sim.last.projection.sweeps
        again = projection.project(scene.geometry, t1, q, pred, scene.radii(t1),
                                   loose(warm_start=False), warm=previous)
        cold += again.sweeps
        assert np.sqrt(((again.y - sim.positions) ** 2).sum()) <= again.bound + sim.bound + 1e-12
    assert warm < cold, (warm, cold)


def test_uncertified_clusters_fall_back_to_the_exact_solver():
    """With no sweeps allowed every cluster goes to the cluster solvers; the answer is then
    the exact one (active set), with its own certificate."""
    spec = hex_jam(6, 6)
    for scene, t1, q, pred, proj in jam_steps(spec, seed=3, steps=3, opts=loose(max_rounds=0)):
        assert proj.sweeps == 0 and proj.fallback_agents == 36
        assert np.max(np.abs(proj.y - reference(scene, t1, q, pred))) < 1e-8
        assert proj.bound <= 1e-6


def test_sweep_cap_triggers_the_fallback_and_stays_exact():
    spec = hex_jam(8, 8)
    capped = list(jam_steps(spec, seed=3, steps=4, opts=loose(max_rounds=1)))
    assert any(p.fallback_agents > 0 for *_, p in capped)
    for scene, t1, q, pred, proj in capped:
        assert np.max(np.abs(proj.y - reference(scene, t1, q, pred))) < 2e-6


@pytest.mark.parametrize("tol", [1e-6, 1e-2])
def test_never_an_overlap_whatever_the_tolerance(tol):
    scene = sc.Scene.from_dict(random_jam(4, n=80))
    sim = sc.Simulator(scene, dt=0.02, seed=2, solver=loose(tol=tol))
    for _ in range(40):
        sim.step()
        assert sim.min_gap >= -1e-9


def test_certified_runs_are_reproducible():
    scene = sc.Scene.from_dict(random_jam(5, n=60))
    runs = []
    for _ in range(2):
        sim = sc.Simulator(scene, dt=0.02, seed=9)
        sim.step(25)
        runs.append(sim.positions)
    assert np.array_equal(runs[0], runs[1])


def test_reset_forgets_the_warm_start():
    """A run after a reset is bit for bit the run from the start (replay relies on it)."""
    scene = sc.Scene.from_dict(random_jam(6, n=50))
    sim = sc.Simulator(scene, dt=0.02, seed=1)
    sim.step(10)
    first = sim.positions
    sim.step(5)
    sim.reset()
    sim.step(10)
    assert np.array_equal(sim.positions, first)


def test_feasible_prediction_costs_nothing_and_is_exact():
    scene = sc.Scene.from_dict({"agents": {"positions": [[0, 0], [2, 0]], "radius": 0.3}})
    q = scene.positions
    proj = projection.project(scene.geometry, 0.01, q, q + 0.01, scene.radii(0.01),
                              sc.SolverOptions())
    assert proj.qp_size == 0 and proj.bound == 0.0 and proj.sweeps == 0


@pytest.mark.parametrize("field, value", [("tol", 0.0), ("tol", 5.0), ("max_rounds", -1),
                                          ("method", "magic"), ("warm_start", "yes")])
def test_options_are_validated(field, value):
    with pytest.raises(sc.SceneError, match=f"solver.{field}"):
        sc.SolverOptions.from_values(**{field: value})


def test_an_uncertified_answer_keeps_a_finite_cutoff(monkeypatch):
    """A fallback answer that breaks its rows by up to 5e-10 m (within ROW_TOLERANCE, so accepted)
    is not certified: bound inf. The cutoff proof then rests on y alone; it must not grow to
    infinity, which would build every pair of the crowd and solve again."""
    real = project_module.solve_qp

    def short(target, c, b, opts):
        return real(target, c, b - 5e-10, opts)

    monkeypatch.setattr(project_module, "solve_qp", short)
    # without the refinement and the polish, which would repair the answer (the next test)
    monkeypatch.setattr(project_module.refine, "refine", lambda *args: None)
    monkeypatch.setattr(project_module.polish, "shrink", lambda x, *args: x)
    scene = sc.Scene.from_dict(deep_jam(n=120))
    sim = sc.Simulator(scene, dt=0.02, seed=1, solver=loose(max_rounds=0))
    sim.step(3)
    proj = sim.last.projection
    assert proj.fallback_agents > 0 and proj.bound == np.inf
    assert proj.solves == 1
    every_pair = scene.n_agents * (scene.n_agents - 1) // 2
    assert len(proj.rows.pair_i) < every_pair / 10


def test_a_slightly_infeasible_answer_is_repaired_by_the_refinement(monkeypatch):
    """The same answer, rows broken by up to 5e-10 m: the refinement (the QP solved again
    around it, magnified) returns a point that holds every row, certified within tol, and
    that close to the exact projection."""
    real = project_module.solve_qp

    def short(target, c, b, opts):
        return real(target, c, b - 5e-10, opts)

    monkeypatch.setattr(project_module, "solve_qp", short)
    scene = sc.Scene.from_dict(deep_jam(n=120))
    sim = sc.Simulator(scene, dt=0.02, seed=1, solver=loose(max_rounds=0))
    sim.step(2)
    q, t1 = sim.positions, sim.t + sim.dt
    sim.step()
    proj = sim.last.projection
    assert proj.fallback_agents > 0 and proj.bound <= sc.SolverOptions().tol
    rp, rs = proj.rows.residuals(proj.y)
    assert min(rp.min(), rs.min(initial=np.inf)) >= 0.0
    want = reference(scene, t1, q, sim.last.prediction)
    assert np.sqrt(((proj.y - want) ** 2).sum()) <= proj.bound


def test_bundled_door_scene_is_certified_every_step_without_fallback() -> None:
    # the default scene's crowd at the door had slow phases of several rounds that then
    # converged: before the projected search, giving up after 5 stalled rounds instead of 10
    # sent its 200-agent cluster to Clarabel with a bound of 1.4e-4 m; every step must finish
    # certified to tol
    from sweep_core.model.scene import load_scene

    sim = sc.Simulator(load_scene(""), dt=0.01, seed=0)
    for _ in range(600):
        sim.step()
        proj = sim.last.projection
        assert proj.fallback_agents == 0 and proj.bound <= sim.scheme.solver.tol, (sim.t, proj)


def test_projected_search_drops_every_row_that_crosses_zero_in_one_pass():
    """Five separate pairs, each pushed 0.1 m apart by its multiplier although its row is
    slack at the projection: the face direction sends all five multipliers below 0, and one
    face pass must drop them all (stopping where the first reaches 0 dropped one a pass)."""
    from sweep_core.numerics.projection import dual

    n_pairs = 5
    d = np.zeros((2 * n_pairs, 2))
    ri = np.arange(0, 2 * n_pairs, 2)
    rj = ri + 1
    re = np.tile([1.0, 0.0], (n_pairs, 1))
    h = -np.linspace(0.1, 0.3, n_pairs)  # every row holds at x = d: the projection is d
    lam = np.array([0.15, 0.05, 0.1, 0.12, 0.07])  # each reaches 0 at its own step
    x = dual.apply_multipliers(d, ri, rj, re, lam)
    its, reach = dual.face_pass(x, d, ri, rj, re, h, lam, 10)
    assert its > 0 and reach < 1.0
    assert np.all(lam == 0.0), lam
    assert np.array_equal(x, d)


def test_factored_face_step_finishes_a_found_face_in_one_step():
    """Multipliers on the exact face but off its values by up to 30 %: one factored face step
    lands on the exact projection (to rounding), where the CG pass does not."""
    from sweep_core.numerics.projection import dual, factored

    scene = sc.Scene.from_dict(deep_jam(120))
    sim = sc.Simulator(scene, dt=0.02, seed=2)
    sim.step(25)
    q = sim.positions
    sim.step()
    rows = sim.last.projection.rows
    ri, rj, re, h = rows.displacement_rows(q)
    d = sim.last.prediction - q
    exact = certified.solve(d, ri, rj, re, h, np.zeros(len(ri)), tol=1e-9, max_rounds=200)
    assert exact.done.all()
    start = exact.lam * np.random.default_rng(0).uniform(0.7, 1.3, len(exact.lam))
    lam = start.copy()
    x = dual.apply_multipliers(d, ri, rj, re, lam)
    assert factored.face_step(x, d, ri, rj, re, h, lam)
    assert np.max(np.abs(x - exact.x)) < 1e-11
    lam_cg = start.copy()
    x_cg = dual.apply_multipliers(d, ri, rj, re, lam_cg)
    dual.face_pass(x_cg, d, ri, rj, re, h, lam_cg, certified.CG_ITERS)
    assert np.max(np.abs(x_cg - exact.x)) > 1e-9


def test_factored_direction_is_refused_when_the_face_has_no_solution():
    """Two rows on the same pair and the same direction asking for different separations:
    the face system is singular and inconsistent, so no direction is returned."""
    from sweep_core.numerics.projection import factored

    ri, rj = np.array([0, 0]), np.array([1, 1])
    re = np.array([[1.0, 0.0], [1.0, 0.0]])
    assert factored.newton_direction(2, np.array([0, 1]), ri, rj, re,
                                     np.array([0.1, 0.2])) is None
    consistent = factored.newton_direction(2, np.array([0, 1]), ri, rj, re,
                                           np.array([0.1, 0.1]))
    assert consistent is not None
    assert np.allclose(consistent.sum() * 2.0, 0.1)


def test_deep_jam_is_certified_in_few_rounds():
    """The 300-agent deep jam, warm-started step after step: every step certified by the
    rounds themselves (no fallback) in at most 8 rounds (the face passes that dropped one row
    each and the unpreconditioned CG took 15 to 40)."""
    sim = sc.Simulator(sc.Scene.from_dict(deep_jam()), dt=0.02, seed=1)
    sim.step(30)
    for _ in range(10):
        sim.step()
        proj = sim.last.projection
        assert proj.fallback_agents == 0 and proj.bound <= sim.scheme.solver.tol
        assert proj.sweeps <= 8 * certified.SWEEPS, proj.sweeps


def test_degenerate_cluster_of_100_agents_is_certified_by_the_exact_solver():
    """A hexagonal jam of 100 equal disks: the rounds cannot certify its degenerate cluster
    (200 variables), which then goes to the exact active-set solver (exact_vars 256), not to
    the interior point, and each step is certified to the tolerance; with exact_vars 128 it
    went to Clarabel with a bound of about 1e-5 m or more."""
    steps = list(jam_steps(hex_jam(10, 10), seed=4, steps=6, opts=sc.SolverOptions()))
    assert max(p.fallback_agents for *_, p in steps) == 100
    for scene, t1, q, pred, proj in steps:
        if proj.fallback_agents:
            assert proj.backend_agents == 0
        assert proj.bound <= 1e-6, proj.bound
        assert np.max(np.abs(proj.y - reference(scene, t1, q, pred))) < 2e-6
