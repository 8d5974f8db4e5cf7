"""The compiled dual active-set solver of one cluster (Goldfarb-Idnani): exact on degenerate
problems (dependent rows), infeasibility detected, its step cap handing over to the backend,
and the step's certificate on jams of equal radii against walls and in a door."""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse as sp
from scenes import hex_jam
from test_projection import reference

import sweep_core as sc
from sweep_core.numerics import projection
from sweep_core.numerics.constraints import linearise
from sweep_core.numerics.projection import active, clusters, exact
from sweep_core.numerics.projection.options import ROW_TOLERANCE


def solve(d: np.ndarray, c: np.ndarray, h: np.ndarray, cap: int = 100000):
    csr = sp.csr_matrix(c)
    csr.sort_indices()
    return active.solve(d, csr.indptr.astype(np.int64), csr.indices.astype(np.int64),
                        csr.data.astype(float), h, cap)


def degenerate_qp(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A random sparse QP whose rows include copies and combinations of others, all holding
    with equality at one point (dependent active rows), and a target far outside."""
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(6, 30)), int(rng.integers(10, 50))
    c = rng.normal(size=(m, n)) * (rng.random((m, n)) < 0.3)
    extra = np.array([c[i] + c[j] for i, j in rng.integers(0, m, (m // 2, 2))])
    c = np.vstack([c, extra, c[: m // 4]])
    x0 = rng.normal(size=n)
    h = c @ x0 - np.where(rng.random(len(c)) < 0.3, rng.uniform(0.0, 1.0, len(c)), 0.0)
    return rng.normal(size=n) * 3.0, c, h


@pytest.mark.parametrize("seed", range(8))
def test_dependent_rows_are_solved_exactly(seed):
    d, c, h = degenerate_qp(seed)
    x, lam, status, steps = solve(d, c, h)
    assert status == active.SOLVED and steps <= 3 * len(h) + len(d)
    want, _, ok = exact.ldp(d, c, h)
    assert ok
    assert np.max(np.abs(x - want)) < 1e-9
    assert (c @ x - h).min() >= -1e-12
    assert lam.min() >= 0.0
    assert np.max(np.abs(x - d - c.T @ lam)) < 1e-12  # x is rebuilt from the multipliers
    assert abs(lam @ (c @ x - h)) < 1e-10  # complementarity


def test_no_common_point_is_reported():
    c = np.array([[1.0, 0.0], [-1.0, 0.0], [1.0, 1.0]])
    h = np.array([1.0, 0.0, 0.5])
    _, _, status, _ = solve(np.zeros(2), c, h)
    assert status == active.INFEASIBLE


def test_step_cap_hands_the_cluster_to_the_backend(monkeypatch):
    d, c, h = degenerate_qp(3)
    assert solve(d, c, h, cap=3)[2] == active.CAPPED
    real = active.solve
    monkeypatch.setattr(clusters.active, "solve",
                        lambda d_, p, i, v, h_, cap: real(d_, p, i, v, h_, 3))
    target = d
    found = clusters.solve_cluster(target, sp.csr_matrix(c), h, sc.SolverOptions())
    assert found is not None
    x, _, is_exact = found
    assert not is_exact  # the backend answered
    assert (c @ x - h).min() >= -ROW_TOLERANCE


def wall_corner(rows: int, cols: int, r: float = 0.25) -> dict:
    """Equal disks on a touching hexagonal patch in the corner of two walls, pressed into it."""
    pos = np.array([(r + c * 2 * r + (k % 2) * r, r + k * r * math.sqrt(3))
                    for k in range(rows) for c in range(cols)])
    return {"agents": {"positions": pos.tolist(), "radius": r},
            "walls": [{"kind": "halfplane", "normal": [1, 0], "offset": 0.0},
                      {"kind": "halfplane", "normal": [0, 1], "offset": 0.0}],
            "drift": {"kind": "uniform", "velocity": [-1.0, -0.7]}, "noise": {"sigma": 0.05}}


def door(n: int, side: float = 5.0, r: float = 0.25) -> dict:
    """n equal disks on a jittered lattice in a square room, led to its 1.2 m door."""
    rng = np.random.default_rng(0)
    cols = math.ceil(math.sqrt(n))
    start = 0.5 * (side - (cols - 1) * 0.62)
    pos = np.array([(start + c * 0.62, start + k * 0.62) for k in range(cols)
                    for c in range(cols)][:n]) + rng.uniform(-0.04, 0.04, (n, 2))
    lo, hi = 0.5 * (side - 1.2), 0.5 * (side + 1.2)
    walls = [{"kind": "segment", "a": a, "b": b} for a, b in (
        ([0, 0], [side, 0]), ([side, 0], [side, lo]), ([side, hi], [side, side]),
        ([side, side], [0, side]), ([0, side], [0, 0]))]
    return {"agents": {"positions": pos.tolist(), "radius": r}, "walls": walls,
            "drift": {"kind": "geodesic", "goal": [side + 3.0, 0.5 * side], "speed": 1.3},
            "noise": {"sigma": 0.05}}


def dependent_rows(scene: sc.Scene, t1: float, q: np.ndarray, y: np.ndarray) -> int:
    """Active rows at y minus the rank of their gradients (> 0: dependent active rows)."""
    rows = linearise(scene.geometry, t1, q, scene.radii(t1), np.inf)
    c, b = clusters.row_matrix(rows, np.arange(len(q)), len(q))
    act = (c @ y.ravel() - b) <= 1e-9
    return int(act.sum() - np.linalg.matrix_rank(c[act].toarray(), tol=1e-8))


@pytest.mark.parametrize("spec, steps, degenerate",
                         [(hex_jam(8, 8), 30, True), (wall_corner(6, 8), 30, True),
                          (door(40), 150, False)], ids=["hex64", "corner48", "door40"])
def test_jams_of_equal_radii_are_certified_by_the_exact_path(spec, steps, degenerate):
    """Every cluster goes to the cluster solvers (method "clusters"); the active-set solver
    answers each (no backend), the step's bound is within tol, the answer within it of the
    exact projection, every row holds; the lattices are degenerate (dependent active rows;
    the jittered crowd at the door is only nearly so)."""
    scene = sc.Scene.from_dict(spec)
    opts = sc.SolverOptions(method="clusters")
    sim = sc.Simulator(scene, dt=0.02, seed=1, solver=opts)
    sim.step(steps)
    q, t1 = sim.positions, sim.t + sim.dt
    sim.step()
    proj = sim.last.projection
    assert proj.backend_agents == 0 and proj.qp_size > 0
    assert proj.bound <= opts.tol
    want = reference(scene, t1, q, sim.last.prediction)
    assert np.max(np.linalg.norm(proj.y - want, axis=1)) <= proj.bound + 1e-12
    rp, rs = proj.rows.residuals(proj.y)
    assert min(rp.min(initial=0.0), rs.min(initial=0.0)) >= -ROW_TOLERANCE
    assert (dependent_rows(scene, t1, q, proj.y) > 0) == degenerate


def test_large_degenerate_cluster_matches_a_converged_interior_point():
    """A 120-agent hexagonal jam, one cluster: the active-set answer and Clarabel's at tight
    tolerance agree within the certified bound plus Clarabel's own certified bound."""
    spec = hex_jam(10, 12)
    scene = sc.Scene.from_dict(spec)
    exact_opts = sc.SolverOptions(method="clusters", exact_vars=400)
    sim = sc.Simulator(scene, dt=0.01, seed=2, solver=exact_opts)
    sim.step(20)
    q, t1, r1 = sim.positions, sim.t + sim.dt, scene.radii(sim.t + sim.dt)
    sim.step()
    pred = sim.last.prediction
    mine = projection.project(scene.geometry, t1, q, pred, r1, exact_opts)
    theirs = projection.project(scene.geometry, t1, q, pred, r1,
                                sc.SolverOptions(method="clusters", exact_vars=0))
    assert mine.backend_agents == 0 and theirs.backend_agents == 120
    assert mine.bound <= exact_opts.tol
    dist = np.max(np.linalg.norm(mine.y - theirs.y, axis=1))
    assert dist <= mine.bound + theirs.bound
