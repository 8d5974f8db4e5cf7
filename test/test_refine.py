"""Iterative refinement of a backend's answer (:mod:`projection.refine`): the QP solved again
around the answer, magnified, so that its rows hold to a few ulp and the certificate proves a
bound far below what the backend's skin allows (sqrt(2 x 1e-12 m x the sum of the
multipliers))."""
from __future__ import annotations

import importlib
from dataclasses import replace

import numpy as np
from test_stuck import hex_steps, lattice_qp

import sweep_core as sc
from sweep_core.numerics.projection import backends, exact, refine

project_module = importlib.import_module("sweep_core.numerics.projection.project")


def pressed_lattice(radius: float | list[float]) -> tuple[np.ndarray, object, np.ndarray]:
    """A 10 x 10 lattice pressed towards its centre at 1 m/s, steps of 0.05 s: the QP of its
    4th step (target, C, h), every row built."""
    return lattice_qp(10, 0.05, 3, radius)


def certified_bound(target: np.ndarray, c, h: np.ndarray, x: np.ndarray, lam: np.ndarray
                    ) -> float:
    """The certificate's bound (m) for the primal point x (every row holding) and lam."""
    assert (c @ x - h).min() >= 0.0
    r = x - target - c.T @ lam
    return float(np.sqrt(2.0 * (0.5 * r @ r + lam @ (c @ x - h))))


def test_refined_rows_hold_and_the_bound_is_far_below_the_backends():
    """Radii 0.20-0.245 m (a jam whose exact projection the dense solver finds accurately):
    the refined point holds every row, is within its bound of the exact projection, and the
    bound is under a tenth of what the backend's answer proves."""
    radii = np.random.default_rng(1).uniform(0.2, 0.245, 100).tolist()
    target, c, h = pressed_lattice(radii)
    x, lam, ok = backends.solve_backend(target, c, h, replace(sc.SolverOptions(), eps_abs=1e-12))
    assert ok is True
    before = certified_bound(target, c, h, x, lam)
    assert before > 1e-6  # the multipliers sum to about 13 m: the skin alone costs that
    found = refine.refine(target, x, c, h)
    assert found is not None
    xr, lr = found
    after = certified_bound(target, c, h, xr, lr)
    assert after < 0.1 * before and after < 1e-6
    want, _, solved = exact.ldp(target, c.toarray(), h)
    assert solved
    assert np.linalg.norm(xr - want) <= after


def test_refinement_is_reproducible_and_needs_a_near_active_row():
    """The same answer refined twice gives the same bits; with no row within NEAR of holding
    with equality there is nothing to refine."""
    target, c, h = pressed_lattice(0.24)
    x, _, _ = backends.solve_backend(target, c, h, replace(sc.SolverOptions(), eps_abs=1e-12))
    one, two = refine.refine(target, x, c, h), refine.refine(target, x, c, h)
    assert one is not None and two is not None
    assert np.array_equal(one[0], two[0]) and np.array_equal(one[1], two[1])
    assert refine.refine(target, x, c, h - 1e-6) is None


def lattice_steps(steps: int):
    """(projection, distance to the exact projection) of each step of the equal-radius 10 x 10
    lattice pressed at 1 m/s, every cluster sent to the backend (no rounds, no exact path)."""
    return hex_steps(steps, 3, sc.SolverOptions(exact_vars=0, method="clusters"), 10, 0.05)


def test_an_equal_radius_lattice_left_to_the_backend_is_certified_within_tol():
    """Degenerate (equal radii, more loaded rows than coordinates) and pressed hard enough
    that the backend's skin alone costs more than tol: every step is certified within tol =
    1e-6 m, and is that close to the exact projection."""
    for proj, dist in lattice_steps(3):
        assert proj.backend_agents == 100
        total = float(proj.lam_pair.sum() + proj.lam_single.sum())
        assert np.sqrt(2.0 * 1e-12 * total) > 1e-6
        assert proj.bound <= 1e-6
        assert dist <= proj.bound


def test_without_the_refinement_the_same_steps_miss_tol(monkeypatch):
    """The check above can fail: with the refinement switched off the same steps are only
    polished, and some bound is above tol."""
    monkeypatch.setattr(project_module.refine, "refine", lambda *args: None)
    bounds = [proj.bound for proj, _ in lattice_steps(3)]
    assert max(bounds) > 1e-6


class _Scripted:
    """Stands in for PIQP's module in :func:`refine.refine`: its solver answers each
    magnification D (read from the Hessian I / D it is given) with a scripted status and the
    point and multipliers of ``answers[D]``, expressed as PIQP would (v = D (x - x^))."""
    PIQP_SOLVED, PIQP_MAX_ITER_REACHED = "solved", "max_iter"

    def __init__(self, start: np.ndarray, answers: dict, near: np.ndarray) -> None:
        self.start, self.answers, self.near, self.setups = start, answers, near, []

    def SparseSolver(self):  # noqa: N802 (PIQP's name)
        outer = self

        class Solver:
            settings = type("Settings", (), {})()

            def setup(self, p, *args) -> None:
                self.scale = round(1.0 / p.diagonal()[0])
                outer.setups.append(self.scale)

            def solve(self):
                status, x, lam = outer.answers[self.scale]
                self.result = type("Result", (), {
                    "x": self.scale * (x - outer.start), "z_u": lam[outer.near]})()
                return status

        return Solver()


def test_the_closest_answer_is_kept_when_a_magnification_is_cut_short(monkeypatch):
    """PIQP can stop at its iteration cap at one magnification with an answer closer than the
    one it reports solved at the next: refine returns the answer of the smallest duality gap
    among those it tried, not the last one, and stops at the first one solved."""
    target, c, h = pressed_lattice(np.random.default_rng(1).uniform(0.2, 0.245, 100).tolist())
    x, lam, _ = backends.solve_backend(target, c, h, replace(sc.SolverOptions(), eps_abs=1e-12))
    near = np.flatnonzero(c @ x - h < refine.NEAR)
    want, _, _ = exact.ldp(target, c.toarray(), h)
    good, good_lam = refine.refine(target, x, c, h)  # a refined answer and its multipliers
    assert refine.gap(target, c.tocsr(), h, good, good_lam) < refine.gap(target, c.tocsr(), h,
                                                                        x, lam)
    fake = _Scripted(x, {10**10: (_Scripted.PIQP_MAX_ITER_REACHED, good, good_lam),
                         10**9: (_Scripted.PIQP_SOLVED, x, lam),
                         10**8: (_Scripted.PIQP_SOLVED, want, lam)}, near)
    monkeypatch.setattr(refine.pivot, "baseline", lambda: fake)
    monkeypatch.setattr(refine, "SCALES", (1e10, 1e9, 1e8))
    xr, lr = refine.refine(target, x, c, h)
    assert np.allclose(xr, good, rtol=0, atol=1e-15) and np.array_equal(lr[near], good_lam[near])
    assert fake.setups == [10**10, 10**9]
