"""The cluster backends through qpsolvers: every installed solver projects a small jam to its
stated accuracy, and an unknown name is refused with the installed ones."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import qpsolvers
from scenes import hex_jam

import sweep_core as sc
from sweep_core.numerics import projection
from sweep_core.numerics.constraints import linearise
from sweep_core.numerics.projection import backends, clusters, exact
from sweep_core.numerics.projection.options import ROW_TOLERANCE


def small_jam():
    """A 25-agent hexagonal jam pressed for 3 steps: scene, t1, q, prediction."""
    scene = sc.Scene.from_dict(hex_jam(5, 5))
    sim = sc.Simulator(scene, dt=0.01, seed=5)
    sim.step(3)
    q, t1 = sim.positions, sim.t + sim.dt
    sim.step()
    return scene, t1, q, sim.last.prediction


@pytest.mark.parametrize("name", sorted(set(qpsolvers.available_solvers) | {"clarabel"}))
def test_every_installed_backend_solves_a_small_jam(name):
    """The jam's QP over every row, posed as the projection poses a cluster (displacement
    coordinates), solved by the backend alone: it reports success, lands within its stated
    accuracy of the exact projection, and every row holds."""
    scene, t1, q, pred = small_jam()
    rows = linearise(scene.geometry, t1, q, scene.radii(t1), np.inf)
    c, b = clusters.row_matrix(rows, np.arange(len(q)), len(q))
    _, _, _, h = rows.displacement_rows(q)
    opts = sc.SolverOptions.from_values(backend=name)
    x, lam, ok = backends.solve_backend((pred - q).ravel(), c, h, opts)
    assert ok is True
    want, _, found = exact.ldp(pred.ravel(), c.toarray(), b)
    assert found
    dist = np.max(np.linalg.norm(q + x.reshape(-1, 2) - want.reshape(-1, 2), axis=1))
    assert dist <= backends.ACCURACY.get(name, 1e-6)
    assert (c @ x - h).min() >= -ROW_TOLERANCE
    assert lam.min() >= 0.0 and lam.max() > 0.0


def test_a_backend_that_fails_hands_over_to_clarabel(monkeypatch):
    scene, t1, q, pred = small_jam()
    real = clusters.solve_backend

    def failing(target, c, b, opts):
        if opts.backend != "clarabel":
            return target.copy(), np.zeros(len(b)), False
        return real(target, c, b, opts)

    monkeypatch.setattr(clusters, "solve_backend", failing)
    opts = sc.SolverOptions.from_values(backend="osqp" if "osqp" in qpsolvers.available_solvers
                                        else "clarabel", exact_vars=0, method="clusters")
    opts = replace(opts, dense_fallback=0)
    got = projection.project(scene.geometry, t1, q, pred, scene.radii(t1), opts)
    assert got.backend_agents == 25 and got.bound < 1e-3


def test_unknown_backend_is_refused_naming_the_installed_ones():
    with pytest.raises(sc.SceneError, match="solver.backend") as err:
        sc.SolverOptions.from_values(backend="nosuchsolver")
    assert "clarabel" in str(err.value) and "nosuchsolver" in str(err.value)


def test_proxsuite_is_read_as_proxqp():
    if "proxqp" not in qpsolvers.available_solvers:
        pytest.skip("proxsuite is not installed")
    assert sc.SolverOptions.from_values(backend="proxsuite").backend == "proxqp"


def test_a_factored_face_step_leaves_cvxopt_as_it_found_it():
    """The face step's factorisation sets CHOLMOD's options for itself only: cvxopt's QP
    solver, which reads them, still solves the small jam after one (it failed on it while the
    simplicial setting stayed behind)."""
    from cvxopt import cholmod

    from sweep_core.numerics.projection import factored
    before = dict(cholmod.options)
    m = factored.face_matrix(3, np.array([0, 1]), np.array([0, 1]), np.array([1, 2]),
                             np.array([[1.0, 0.0], [0.0, 1.0]]))
    assert factored.factorise((m @ m.T).tocsr()) is not None
    assert dict(cholmod.options) == before
    if "cvxopt" in qpsolvers.available_solvers:
        test_every_installed_backend_solves_a_small_jam("cvxopt")
