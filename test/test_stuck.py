"""Clusters the certified rounds cannot certify, and the backends' skins.

A cluster the rounds leave to the cluster solvers is sent there directly on the next steps and
given the rounds again once in ``RETRY`` steps; the answer stays the exact projection (small
clusters: the exact active-set solver) and within its bound. A backend is tried with the thin
skin first, and with ``eps_abs`` when that answer breaks a row. PIQP, the default backend, is
loaded from its baseline build."""
from __future__ import annotations

import importlib
from dataclasses import replace

import numpy as np
import pytest
from scenes import hex_jam
from test_projection import reference

import sweep_core as sc
from sweep_core.numerics.constraints import linearise
from sweep_core.numerics.projection import backends, certified, clusters, pivot, polish

project_module = importlib.import_module("sweep_core.numerics.projection.project")


def hex_steps(steps: int, warmup: int, opts: sc.SolverOptions | None = None, side: int = 8,
              dt: float = 0.01):
    """(projection, its distance to the exact projection) of each step of a pressed side x
    side hexagonal lattice (seed 3) after ``warmup`` steps of dt (s)."""
    scene = sc.Scene.from_dict(hex_jam(side, side))
    sim = sc.Simulator(scene, dt=dt, seed=3, solver=opts)
    sim.step(warmup)
    for _ in range(steps):
        q, t1 = sim.positions, sim.t + sim.dt
        sim.step()
        want = reference(scene, t1, q, sim.last.prediction)
        proj = sim.last.projection
        yield proj, float(np.sqrt(((proj.y - want) ** 2).sum()))


def test_a_cluster_the_rounds_leave_skips_them_until_the_retry(monkeypatch):
    """A pressed hexagonal lattice (degenerate: the rounds stall and hand it over): on the
    steps after a hand-over the rounds are skipped (no sweeps), on every RETRY-th they run
    again, and every answer is the exact projection to 1e-8 m, within its bound."""
    monkeypatch.setattr(project_module, "RETRY", 3)
    seen = []
    for proj, dist in hex_steps(14, 2):
        assert dist <= proj.bound + 1e-12 and dist < 1e-8
        seen.append((proj.sweeps, proj.fallback_agents, proj.stuck_steps))
    handed = [k for k, (sweeps, fallback, held) in enumerate(seen) if sweeps > 0 and fallback]
    assert handed, f"the rounds never handed the lattice over: {seen}"
    k = handed[0]
    assert k + 3 < len(seen), f"handed over too late to see the retry: {seen}"
    # the next two steps skip the rounds (the whole lattice is one cluster), the third retries
    assert seen[k + 1][0] == 0 and seen[k + 1][1] > 0 and seen[k + 1][2] == 1, seen
    assert seen[k + 2][0] == 0 and seen[k + 2][2] == 2, seen
    assert seen[k + 3][0] > 0 and seen[k + 3][2] == 0, seen
    # and the retry's rounds are capped
    assert seen[k + 3][0] <= project_module.RETRY_ROUNDS * certified.SWEEPS, seen


def test_without_a_previous_step_nothing_is_skipped():
    """A projection without a warm start (or after a change in the number of agents) runs
    the rounds: nothing is held from a step that did not happen."""
    scene = sc.Scene.from_dict(hex_jam(6, 6))
    sim = sc.Simulator(scene, dt=0.01, seed=3)
    sim.step(4)
    q = sim.positions
    pred = sim.last.prediction
    opts = sc.SolverOptions()
    proj = project_module.project(scene.geometry, sim.t, q, pred, scene.radii(sim.t), opts)
    assert proj.sweeps > 0 and proj.stuck_steps == 0


def lattice_qp(side: int, dt: float, seed: int, radius: float | list[float] = 0.24
               ) -> tuple[np.ndarray, object, np.ndarray]:
    """The QP of the 4th step of a side x side hexagonal lattice pressed towards its centre
    at 1 m/s, in displacement coordinates (target, C, h), every row built."""
    spec = hex_jam(side, side)
    spec["agents"]["radius"] = radius
    scene = sc.Scene.from_dict(spec)
    sim = sc.Simulator(scene, dt=dt, seed=seed)
    sim.step(3)
    q, t1 = sim.positions, sim.t + sim.dt
    sim.step()
    rows = linearise(scene.geometry, t1, q, scene.radii(t1), np.inf)
    c, _ = clusters.row_matrix(rows, np.arange(len(q)), len(q))
    _, _, _, h = rows.displacement_rows(q)
    return (sim.last.prediction - q).ravel(), c, h


def small_cluster() -> tuple[np.ndarray, object, np.ndarray]:
    """A 25-agent hexagonal jam's QP in displacement coordinates: target, C, h."""
    return lattice_qp(5, 0.01, 5)


@pytest.mark.parametrize("thin_holds", [True, False])
def test_the_thin_skin_first_then_eps_abs_when_a_row_breaks(monkeypatch, thin_holds):
    """The backend is called with the 1e-12 m skin; if that answer breaks a row (here made
    to, by 1e-13 m) it is called again with eps_abs, whose answer is taken."""
    target, c, h = small_cluster()
    calls = []
    real = clusters.solve_backend

    def spy(t, c_, b, opts):
        calls.append(opts.eps_abs)
        x, lam, ok = real(t, c_, b, opts)
        if opts.eps_abs < 1e-11 and not thin_holds:
            # move x along the gradient of its tightest row until that row is 1e-13 m broken
            s = c_ @ x - b
            w = int(np.argmin(s))
            grad = c_[w].toarray().ravel()
            x = x - (s[w] + 1e-13) * grad / float(grad @ grad)
        return x, lam, ok

    monkeypatch.setattr(clusters, "solve_backend", spy)
    opts = sc.SolverOptions(eps_abs=1e-10)
    x, lam, ok = clusters.solve_tight(target, c, h, opts)
    assert calls == ([1e-12] if thin_holds else [1e-12, 1e-10])
    assert ok is True and (c @ x - h).min() >= 0.0
    if thin_holds:
        # the thin skin: the rows carrying force hold to within about 1e-12 m, not 1e-10 m
        s = c @ x - h
        assert np.max(s[lam > 1e-6]) < 1e-11


def test_the_default_backend_is_piqp_in_its_baseline_build(monkeypatch):
    """PIQP is the default; the projection loads its baseline build (not the one for this
    CPU's vector units) and its answer is the exact projection to its stated accuracy."""
    assert sc.SolverOptions().backend == "piqp"
    assert pivot.baseline().__name__ == "piqp.piqp_python"
    loaded = []
    real = pivot.baseline

    def spy():
        loaded.append(real())
        return loaded[-1]

    monkeypatch.setattr(pivot, "baseline", spy)
    target, c, h = small_cluster()
    x, lam, ok = backends.solve_backend(target, c, h, replace(sc.SolverOptions(), eps_abs=1e-12))
    assert loaded and ok is True
    want, _, found = clusters.solve_active(target, c.tocsr(), h)
    assert found
    assert np.max(np.abs(x - want)) <= backends.ACCURACY["piqp"]


def test_the_polish_keeps_every_row_and_only_lowers_the_bound():
    """A backend's answer on a hexagonal jam, polished: every row still holds by the rounding
    floor, the point is still within its (smaller) bound of the exact projection."""
    target, c, h = small_cluster()
    x, lam, ok = backends.solve_backend(target, c, h, replace(sc.SolverOptions(), eps_abs=1e-12))
    assert ok is True
    floor = 1e-15
    moved = polish.shrink(x, c, h, floor)
    assert (c @ moved - h).min() >= floor
    want, _, found = clusters.solve_active(target, c.tocsr(), h)
    assert found

    def bound(y: np.ndarray) -> float:
        # the certificate's gap for the primal point y and the backend's multipliers
        r = y - target - c.T @ lam
        return float(np.sqrt(2.0 * (0.5 * r @ r + lam @ (c @ y - h))))

    assert bound(moved) < bound(x)
    assert np.linalg.norm(moved - want) <= bound(moved)


def test_a_jam_left_to_the_backend_is_improved_within_its_bound():
    """Every cluster to the backend (no exact path, no rounds): the answers (refined, or
    polished where that does not prove tol) are the exact projection within their bound, and
    the bound is below what the backend's own answer proves (sqrt(2 x skin x sum of
    multipliers))."""
    lowered = 0
    for proj, dist in hex_steps(4, 3, sc.SolverOptions(exact_vars=0, method="clusters")):
        assert proj.backend_agents > 0
        assert dist <= proj.bound
        total = float(proj.lam_pair.sum() + proj.lam_single.sum())
        lowered += proj.bound < np.sqrt(2.0 * 1e-12 * total)
    assert lowered, "no step proved a smaller bound than the skin's"
