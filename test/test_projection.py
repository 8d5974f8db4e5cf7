"""The projection: cutoff, clusters and closed forms against one reference QP over every row."""
from __future__ import annotations

import numpy as np
import pytest
from scenes import hex_jam
from scipy.optimize import nnls

import sweep_core as sc
from sweep_core.numerics import projection
from sweep_core.numerics.constraints import linearise
from sweep_core.numerics.projection import clusters, exact


def random_crowd(rng: np.random.Generator, n: int, box: float, r: float) -> np.ndarray:
    pos: list[np.ndarray] = []
    while len(pos) < n:
        p = rng.uniform(r, box - r, 2)
        if all(np.hypot(*(p - o)) >= 2 * r for o in pos):
            pos.append(p)
    return np.array(pos)


def reference(scene: sc.Scene, t1: float, q: np.ndarray, pred: np.ndarray) -> np.ndarray:
    """Projection onto C~ with every pair and wall row built (no cutoff), solved exactly."""
    rows = linearise(scene.geometry, t1, q, scene.radii(t1), np.inf)
    n = len(q)
    c, b = clusters.row_matrix(rows, np.arange(n), n)
    x, _, ok = exact.ldp(pred.ravel(), c.toarray(), b)
    assert ok
    return x.reshape(-1, 2)


@pytest.mark.parametrize("backend", ["clarabel", "proxsuite"])
@pytest.mark.parametrize("seed", range(6))
def test_projection_matches_reference_on_random_crowds(seed, backend):
    rng = np.random.default_rng(seed)
    r = 0.2
    q = random_crowd(rng, 25, 3.0, r)
    scene = sc.Scene.from_dict({
        "agents": {"positions": q.tolist(), "radius": r},
        "walls": [{"kind": "halfplane", "normal": [1, 0], "offset": 0.0},
                  {"kind": "segment", "a": [3.0, -1.0], "b": [3.0, 4.0]}]})
    pred = q + rng.normal(0.0, 0.15, q.shape)
    opts = sc.SolverOptions(backend=backend)
    got = projection.project(scene.geometry, 0.01, q, pred, scene.radii(0.01), opts)
    want = reference(scene, 0.01, q, pred)
    assert np.max(np.abs(got.y - want)) < 1e-8
    assert got.qp_size > 0  # something was projected


def test_far_pairs_are_never_built():
    rng = np.random.default_rng(1)
    q = random_crowd(rng, 40, 20.0, 0.2)
    scene = sc.Scene.from_dict({"agents": {"positions": q.tolist(), "radius": 0.2}})
    rows = linearise(scene.geometry, 0.0, q, scene.radii(0.0), 0.05)
    d = np.hypot(*(q[rows.pair_i] - q[rows.pair_j]).T) - 0.4
    assert np.all(d <= 0.05)
    assert len(rows.single_b) == 0  # no walls, no wall rows


def kkt_gap(scene: sc.Scene, t1: float, q: np.ndarray, pred: np.ndarray, y: np.ndarray
            ) -> tuple[float, float]:
    """A check independent of the solvers: the worst row residual at y (every row built), and
    how far y - pred is from the cone of the gradients of the rows active at y (m)."""
    rows = linearise(scene.geometry, t1, q, scene.radii(t1), np.inf)
    n = len(q)
    c, b = clusters.row_matrix(rows, np.arange(n), n)
    s = c @ y.ravel() - b
    active = s <= 1e-8
    _, dist = nnls(c[active].T.toarray(), (y - pred).ravel())
    return float(s.min()), float(dist)


def jam_steps(spec: dict, seed: int, steps: int, opts: sc.SolverOptions):
    """(scene, t1, q, prediction, projection) of each step of a jam after two warm-up steps."""
    scene = sc.Scene.from_dict(spec)
    sim = sc.Simulator(scene, dt=0.01, seed=seed, solver=opts)
    sim.step(2)
    for _ in range(steps):
        q, t1 = sim.positions, sim.t + sim.dt
        sim.step()
        yield scene, t1, q, sim.last.prediction, sim.last.projection


def random_jam(seed: int, n: int = 40) -> dict:
    """n disks placed at random in a 3.2 m box, all heading for its centre, with noise."""
    q = random_crowd(np.random.default_rng(seed), n, 3.2, 0.2)
    return {"agents": {"positions": q.tolist(), "radius": 0.2},
            "drift": {"kind": "goal", "goal": [1.6, 1.6], "speed": 2.0},
            "noise": {"sigma": 0.2}}


@pytest.mark.parametrize("spec", [hex_jam(6, 6), hex_jam(8, 8), random_jam(0), random_jam(1),
                                  random_jam(2)], ids=["hex36", "hex64", "rand0", "rand1", "rand2"])
def test_jams_are_projected_exactly(spec):
    """Dense, degenerate jams (more active rows than coordinates): the step's projection is
    the exact one (active-set reference over every row) to 1e-8 m, not only to the
    interior-point tolerance, and every row holds."""
    for scene, t1, q, pred, proj in jam_steps(spec, seed=3, steps=6, opts=sc.SolverOptions()):
        want = reference(scene, t1, q, pred)
        assert np.max(np.abs(proj.y - want)) < 1e-8
        worst, dist = kkt_gap(scene, t1, q, pred, proj.y)
        assert worst >= -1e-9 and dist < 1e-8
        assert proj.backend_agents == 0


def test_larger_jams_are_exact_on_request():
    """A 144-agent jam is one cluster of 288 variables: above exact_vars it goes to the
    interior-point backend (counted in backend_agents); raising exact_vars makes it exact."""
    spec = hex_jam(12, 12)
    default = list(jam_steps(spec, seed=4, steps=3, opts=sc.SolverOptions(method="clusters")))
    exact = list(jam_steps(spec, seed=4, steps=3,
                           opts=sc.SolverOptions(method="clusters", exact_vars=400)))
    assert max(p.backend_agents for *_, p in default) == 144
    sim = sc.Simulator(sc.Scene.from_dict(spec), dt=0.01, seed=4,
                       solver=sc.SolverOptions(method="clusters"))
    assert sim.backend_agents == 0  # before any step
    sim.step(3)
    assert sim.backend_agents == sim.last.projection.backend_agents
    for scene, t1, q, pred, proj in exact:
        assert proj.backend_agents == 0
        assert np.max(np.abs(proj.y - reference(scene, t1, q, pred))) < 1e-8


def test_exact_vars_is_validated():
    with pytest.raises(sc.SceneError, match="solver.exact_vars"):
        sc.SolverOptions.from_values(exact_vars=-1)


def test_almost_solved_is_a_last_resort(monkeypatch):
    """A backend answer flagged "AlmostSolved" is not taken while the exact solver answers,
    and is taken (rows holding) rather than stopping the run when nothing else does."""
    spec = hex_jam(5, 5)
    scene = sc.Scene.from_dict(spec)
    sim = sc.Simulator(scene, dt=0.01, seed=5,
                       solver=sc.SolverOptions(exact_vars=0, method="clusters"))
    sim.step(2)
    q, t1 = sim.positions, sim.t + sim.dt
    sim.step()
    pred, want = sim.last.prediction, sim.last.projection.y
    real = clusters.solve_backend

    def almost(target, c, b, opts):
        x, lam, _ = real(target, c, b, opts)
        return x, lam, None

    monkeypatch.setattr(clusters, "solve_backend", almost)
    opts = sc.SolverOptions(exact_vars=0, method="clusters")
    got = projection.project(scene.geometry, t1, q, pred, scene.radii(t1), opts)
    assert got.backend_agents == 0  # the exact fallback answered
    assert np.max(np.abs(got.y - reference(scene, t1, q, pred))) < 1e-8
    no_exact = sc.SolverOptions(exact_vars=0, dense_fallback=0, method="clusters")
    got = projection.project(scene.geometry, t1, q, pred, scene.radii(t1), no_exact)
    assert got.backend_agents == 25 and np.max(np.abs(got.y - want)) < 1e-12


@pytest.mark.parametrize("seed", range(6))
def test_row_summary_is_numpys(seed: int) -> None:
    """The compiled summary of the residuals gives what numpy's reductions gave: Python's min
    of the two minima (NaN-propagating, initial inf), the rows within ROW_TOLERANCE, and
    ``rp.min() < 0 or rs.min() < 0`` (a NaN hiding the negatives of its array)."""
    from sweep_core.numerics.projection.options import ROW_TOLERANCE
    from sweep_core.numerics.projection.summaries import row_summary
    rng = np.random.default_rng(seed)
    for _ in range(200):
        rp, rs = (rng.choice([-1e-3, -1e-12, 0.0, 1e-12, 2e-3, np.nan], rng.integers(0, 5))
                  for _ in range(2))
        rp, rs = rp + rng.normal(0, 1e-10, len(rp)) * rng.integers(0, 2), rs.copy()
        worst, active, broken = row_summary(rp, rs)
        want = min(rp.min(initial=np.inf), rs.min(initial=np.inf))
        assert (np.isnan(worst) and np.isnan(want)) or worst == want
        assert active == np.count_nonzero(rp <= ROW_TOLERANCE) + np.count_nonzero(
            rs <= ROW_TOLERANCE)
        assert broken == bool((len(rp) and rp.min() < 0) or (len(rs) and rs.min() < 0))
