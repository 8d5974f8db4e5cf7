"""Schemes: the registry, projected Euler kept bit for bit, the bridge scheme exact in law where
it claims to be, the adaptive scheme's sub-steps, exact solutions for every scheme, and
``sweep bench accuracy`` (reference §5)."""
from __future__ import annotations

import argparse
import math

import numpy as np
import pytest
from scenes import wall_agent
from scipy import stats
from scipy.integrate import quad

import sweep_core as sc
from sweep_core.bench.accuracy import Measurement, fit_slope
from sweep_core.bench.accuracy_problems import circle_exact
from sweep_core.cli import bench
from sweep_core.numerics import noise
from sweep_core.numerics.projection import project
from sweep_core.numerics.schemes import AdaptiveSubstep, adaptive

#: schemes beyond the seed's; projected Euler's exact solutions are in test_exact.py
NEW = sorted(set(sc.SCHEMES) - {"projected_euler"})


def mixed_scene(sigma: float = 0.3) -> dict:
    """Pairs, a moving half-plane, a segment, a circle, breathing radii, drift and noise."""
    return {"agents": {"positions": [[0.0, y] for y in np.linspace(-1.5, 1.5, 7)], "radius": 0.2,
                       "radius_law": {"kind": "sine", "amplitude": 0.02, "period": 1.0}},
            "walls": [{"kind": "segment", "a": [1.0, -0.6], "b": [1.0, 0.6]},
                      {"kind": "halfplane", "normal": [0, 1], "offset": -2.5, "velocity": 0.1}],
            "obstacles": [{"kind": "circle", "center": [1.2, 1.4], "radius": 0.3}],
            "drift": {"kind": "uniform", "velocity": [2.0, 0.0]}, "noise": {"sigma": sigma}}


def many_at_wall(m: int, sigma: float = 1.0, drift=(0.0, 0.0), wall_velocity: float = 0.0,
                 r: float = 0.1) -> sc.Scene:
    """m agents touching the wall x >= r, 40 m apart (independent paths)."""
    return sc.Scene.from_dict({
        "agents": {"positions": [[r, 40.0 * k] for k in range(m)], "radius": r},
        "walls": [{"kind": "halfplane", "normal": [1, 0], "offset": 0.0,
                   "velocity": wall_velocity}],
        "drift": {"kind": "uniform", "velocity": list(drift)}, "noise": {"sigma": sigma}})


def rbm_cdf(y: np.ndarray, mu: float, t: float, x: float = 0.0) -> np.ndarray:
    """P(X_t <= y) for Brownian motion with drift mu, unit variance, reflected at 0, X_0 = x
    (J. M. Harrison, Brownian Motion and Stochastic Flow Systems, 1985, §1.8)."""
    s = math.sqrt(t)
    return (stats.norm.cdf((y - x - mu * t) / s)
            - np.exp(2.0 * mu * y) * stats.norm.cdf((-y - x - mu * t) / s))


# -- registry and projected Euler -------------------------------------------------------------
def test_registry_names_default_and_errors():
    assert {"projected_euler", "bridge", "adaptive"} <= set(sc.SCHEMES)
    scene = sc.Scene.from_dict(wall_agent())
    assert sc.Simulator(scene).scheme.name == "projected_euler"
    for name in sc.SCHEMES:
        assert sc.Simulator(scene, scheme=name).scheme.name == name
    with pytest.raises(sc.SceneError, match="unknown scheme"):
        sc.Simulator(scene, scheme="runge_kutta")
    cls = adaptive(0.25, max_depth=3)
    sim = sc.Simulator(scene, scheme=cls)
    assert isinstance(sim.scheme, AdaptiveSubstep) and sim.scheme.label == "adaptive(0.25)"
    assert sim.scheme.max_depth == 3 and sc.SCHEMES["adaptive"].tolerance == 0.5
    for bad in (0.0, -1.0, math.nan):
        with pytest.raises(sc.SceneError, match="tolerance"):
            adaptive(bad)
    with pytest.raises(sc.SceneError, match="max_depth"):
        adaptive(0.5, max_depth=-1)


def test_projected_euler_is_predict_then_project_bit_for_bit():
    scene = sc.Scene.from_dict(mixed_scene())
    sim = sc.Simulator(scene, dt=0.01, seed=5)
    rng = noise.generator(5)
    q = scene.positions.copy()
    previous = None  # the projection warm-starts the next one, as in the scheme
    for k in range(40):
        sim.step()
        dB = noise.increments(rng, 0.01, scene.n_agents)
        t, t1 = k * 0.01, (k + 1) * 0.01
        pred = q + 0.01 * scene.drift(t, q) + scene.sigma[:, None] * dB
        previous = project(scene.geometry, t1, q, pred, scene.radii(t1), sim.scheme.solver,
                           warm=previous)
        q = previous.y
        assert np.array_equal(sim.positions, q)
        assert np.array_equal(sim.reaction, pred - q)


@pytest.mark.parametrize("name", NEW)
def test_without_noise_every_scheme_is_projected_euler_bit_for_bit(name):
    scene = sc.Scene.from_dict(mixed_scene(sigma=0.0))
    a = sc.Simulator(scene, dt=0.01, seed=1)
    b = sc.Simulator(scene, dt=0.01, seed=2, scheme=name)
    for _ in range(60):
        a.step()
        b.step()
        assert np.array_equal(a.positions, b.positions)
    assert a.contacts > 0  # the agents really met the walls and obstacle


@pytest.mark.parametrize("name", sorted(sc.SCHEMES))
def test_seeded_runs_are_reproducible(name):
    scene = sc.Scene.from_dict(mixed_scene())
    a, b, c = (sc.Simulator(scene, dt=0.02, seed=s, scheme=name) for s in (3, 3, 4))
    for sim in (a, b, c):
        sim.step(40)
    assert np.array_equal(a.positions, b.positions)
    assert not np.array_equal(a.positions, c.positions)
    a.reset()
    a.step(40)
    assert np.array_equal(a.positions, b.positions)


# -- exact solutions, every scheme ----------------------------------------------------------
@pytest.mark.parametrize("name", NEW)
def test_moving_wall_pushes_a_point_exactly(name):
    x0, r, c0, v = 0.5, 0.25, -1.0, 0.5
    scene = sc.Scene.from_dict({
        "agents": {"positions": [[x0, 0.0]], "radius": r},
        "walls": [{"kind": "halfplane", "normal": [1, 0], "offset": c0, "velocity": v}]})
    sim = sc.Simulator(scene, dt=0.05, seed=0, scheme=name)
    err = []
    sim.run(4.0, callback=lambda s: err.append(abs(s.positions[0, 0] - max(x0, c0 + v * s.t + r))))
    assert max(err) < 1e-9


@pytest.mark.parametrize("name", NEW)
def test_head_on_pair_touches_at_the_exact_time(name):
    r, h = 0.25, 0.01
    scene = sc.Scene.from_dict({
        "agents": {"positions": [[-1.0, 0.0], [1.0, 0.0]], "radius": r},
        "drift": {"kind": "per_agent", "velocities": [[1.0, 0.0], [-1.0, 0.0]]}})
    sim = sc.Simulator(scene, dt=h, seed=0, scheme=name)
    for k in range(1, 121):
        sim.step()
        gap = sim.positions[1, 0] - sim.positions[0, 0] - 2 * r
        assert gap == pytest.approx(max(0.0, 1.5 - 2 * k * h), abs=1e-9)


@pytest.mark.parametrize("name", sorted(sc.SCHEMES))
def test_sliding_around_a_circle_converges_at_order_one(name):
    """tan(theta/2) = tan(theta0/2) exp(-V t / rho) in contact, a straight line after release;
    the sup error over the grid halves with dt (order 1 for smooth deterministic sliding)."""
    big_r, r, speed, theta0 = 1.0, 0.25, 1.0, math.pi - 0.4
    rho = big_r + r
    scene = sc.Scene.from_dict({
        "agents": {"positions": [circle_exact(np.array(0.0), rho, speed, theta0).tolist()],
                   "radius": r},
        "obstacles": [{"kind": "circle", "center": [0.0, 0.0], "radius": big_r}],
        "drift": {"kind": "uniform", "velocity": [speed, 0.0]}})
    errors = []
    for dt in (0.02, 0.01):
        sim = sc.Simulator(scene, dt=dt, seed=0, scheme=name)
        err = []
        sim.run(2.6, callback=lambda s: err.append(float(np.hypot(
            *(s.positions[0] - circle_exact(np.array(s.t), rho, speed, theta0))))))
        errors.append(max(err))
    assert errors[0] < 0.6 * 0.02  # error <= C dt with C ~ 0.5 m/s
    assert 1.8 < errors[0] / errors[1] < 2.2, errors


# -- the bridge correction: exact in law where it claims to be --------------------------------
# Statistical tolerances: with m independent agents the sample mean has standard error
# sd / sqrt(m); |mean - exact| <= 4 SE fails with probability 6e-5 when the law is right.
# The KS test at the fixed seed uses the same logic: p > 1e-3 for the right law.

@pytest.mark.parametrize("name", NEW)
def test_reflected_bm_is_exact_in_law_at_a_coarse_step(name):
    m, h = 4000, 0.25
    d = {}
    for scheme in ("projected_euler", name):
        sim = sc.Simulator(many_at_wall(m), dt=h, seed=2024, scheme=scheme)
        sim.run(1.0)
        d[scheme] = sim.positions[:, 0] - 0.1
    se = math.sqrt(1 - 2 / math.pi) / math.sqrt(m)   # sd of |B_1| from the wall
    exact = math.sqrt(2 / math.pi)
    assert d[name].min() >= -1e-9
    assert abs(d[name].mean() - exact) <= 4 * se
    assert stats.kstest(d[name], stats.halfnorm.cdf).pvalue > 1e-3
    # projected Euler at this step is visibly biased: the test can tell the difference
    assert exact - d["projected_euler"].mean() > 10 * se


@pytest.mark.parametrize("drift, wall_velocity", [(-1.0, 0.0), (0.0, 0.8)])
def test_bridge_with_drift_or_moving_wall_is_exact_in_law(drift, wall_velocity):
    """A constant drift towards the wall, or a wall moving at constant speed towards the
    agent, is a reflected BM with drift mu for the gap: Harrison's transition law."""
    m, h, r = 4000, 0.25, 0.1
    mu = drift - wall_velocity
    sim = sc.Simulator(many_at_wall(m, drift=(drift, 0.0), wall_velocity=wall_velocity, r=r),
                       dt=h, seed=77, scheme="bridge")
    sim.run(1.0)
    gap = sim.positions[:, 0] - r - wall_velocity * 1.0
    mean = quad(lambda y: 1.0 - rbm_cdf(np.array(y), mu, 1.0), 0, np.inf)[0]
    second = quad(lambda y: 2 * y * (1.0 - rbm_cdf(np.array(y), mu, 1.0)), 0, np.inf)[0]
    se = math.sqrt(second - mean ** 2) / math.sqrt(m)
    assert gap.min() >= -1e-9
    assert abs(gap.mean() - mean) <= 4 * se
    assert stats.kstest(gap, lambda y: rbm_cdf(y, mu, 1.0)).pvalue > 1e-3


def test_bridge_in_an_orthogonal_corner_is_exact_in_law():
    """Two orthogonal walls: the normal components are independent reflected BMs, so each
    coordinate of an agent starting in the corner is |B_1| (one agent per seed: 400 paths)."""
    m, h, r = 400, 0.25, 0.1
    corner = sc.Scene.from_dict({
        "agents": {"positions": [[r, r]], "radius": r},
        "walls": [{"kind": "halfplane", "normal": [1, 0], "offset": 0.0},
                  {"kind": "halfplane", "normal": [0, 1], "offset": 0.0}],
        "noise": {"sigma": 1.0}})
    ends = {}
    for scheme in ("projected_euler", "bridge"):
        out = []
        for seed in range(m):
            sim = sc.Simulator(corner, dt=h, seed=seed, scheme=scheme)
            sim.run(1.0)
            out.append(sim.positions[0] - r)
        ends[scheme] = np.array(out)
    got = ends["bridge"]
    assert got.min() >= -1e-9
    for k in range(2):
        assert stats.kstest(got[:, k], stats.halfnorm.cdf).pvalue > 1e-3
        assert stats.kstest(ends["projected_euler"][:, k], stats.halfnorm.cdf).pvalue < 1e-3
    # independence of the two coordinates: the sample correlation has SE ~ 1 / sqrt(m)
    assert abs(np.corrcoef(got.T)[0, 1]) < 4 / math.sqrt(m)


# -- adaptive sub-steps ----------------------------------------------------------------------
def test_adaptive_never_substeps_in_free_flight():
    scene = sc.Scene.from_dict({"agents": {"positions": [[0.0, 0.0], [50.0, 0.0]], "radius": 0.1},
                                "drift": {"kind": "uniform", "velocity": [3.0, 0.0]},
                                "noise": {"sigma": 2.0}})
    sim = sc.Simulator(scene, dt=0.5, seed=0, scheme="adaptive")
    dB = np.random.default_rng(0).normal(0.0, math.sqrt(0.5), (10, 2, 2))
    q = scene.positions.copy()
    for k in range(10):
        sim.step(dB=dB[k])
        q = q + 0.5 * np.array([3.0, 0.0]) + 2.0 * dB[k]
        assert sim.scheme.last_substeps == 1
        np.testing.assert_allclose(sim.positions, q, rtol=0, atol=1e-12)


def test_adaptive_substeps_fast_contacts_and_keeps_the_barycentre():
    """Two equal disks thrown at each other at 5 m/s with dt = 0.1: every step in contact is
    bisected (displacement 0.5 m against radius 0.2 m, tolerance 0.5 radius); the pair's
    barycentre stays where the symmetric drift keeps it, the pair never overlaps."""
    scene = sc.Scene.from_dict({
        "agents": {"positions": [[-1.0, 0.0], [1.0, 0.0]], "radius": 0.2},
        "drift": {"kind": "linear", "matrix": [[-5.0, 0.0], [0.0, -5.0]], "offset": [0.0, 0.0]}})
    sim = sc.Simulator(scene, dt=0.1, seed=0, scheme="adaptive")
    subs = []
    for _ in range(10):
        sim.step()
        subs.append(sim.scheme.last_substeps)
        q = sim.positions
        assert np.hypot(*(q[0] - q[1])) >= 0.4 - 1e-9
        np.testing.assert_allclose(q.mean(axis=0), 0.0, atol=1e-12)
    assert max(subs) > 1
    assert sim.positions[1, 0] - sim.positions[0, 0] == pytest.approx(0.4, abs=1e-9)


def test_adaptive_bounds_the_substeps():
    scene = sc.Scene.from_dict(wall_agent(x0=0.5, radius=0.5, sigma=0.0) | {
        "drift": {"kind": "uniform", "velocity": [-100.0, 1.0]}})
    sim = sc.Simulator(scene, dt=0.5, seed=0, scheme=adaptive(0.01, max_depth=3))
    sim.step(3)
    assert sim.scheme.last_substeps == 8
    assert sim.positions[0, 0] == pytest.approx(0.5, abs=1e-9)
    assert sim.positions[0, 1] == pytest.approx(1.5, abs=1e-9)


# -- the study --------------------------------------------------------------------------------
def _m(dt: float, err: float, values=None) -> Measurement:
    return Measurement("p", "weak", "s", dt, "tol", err, 0.0, 1.0, 1.0, 1, values)


def test_fit_slope_recovers_an_order_and_reports_unresolved_levels():
    dts = [0.1 / 2 ** k for k in range(6)]
    s = fit_slope([_m(dt, 0.3 * dt ** 0.5) for dt in dts])
    assert s.slope == pytest.approx(0.5, abs=1e-9) and s.lo - 1e-9 <= 0.5 <= s.hi + 1e-9
    rng = np.random.default_rng(0)
    # per-path values with mean c dt and unit noise: the bootstrap interval covers 1
    ms = []
    base = rng.standard_normal(4000)
    for dt in dts:
        vals = 5.0 * dt + 0.05 * base + 0.05 * rng.standard_normal(4000)
        mean, ci = abs(vals.mean()), 1.96 * vals.std(ddof=1) / math.sqrt(len(vals))
        ms.append(Measurement("p", "weak", "s", dt, "tol", mean, ci, 1.0, 1.0, 4000, vals))
    s = fit_slope(ms)
    assert s.lo <= 1.0 <= s.hi and s.hi - s.lo < 0.5
    exact = fit_slope([_m(dt, 0.0) for dt in dts])
    assert math.isnan(exact.slope) and exact.note == "exact to rounding"
    noisy = fit_slope([Measurement("p", "weak", "s", dt, "tol", 1e-4, 1e-3, 1.0, 1.0, 1)
                       for dt in dts])
    assert math.isnan(noisy.slope) and noisy.note.startswith("unresolved")


def test_bench_accuracy_command_writes_tables_and_plots(tmp_path, capsys):
    parser = argparse.ArgumentParser(prog="sweep")
    bench.register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["bench", "accuracy", "--quick", "--problems", "moving_wall",
                              "features", "--out", str(tmp_path / "b")])
    assert args.func(args) == 0
    out = capsys.readouterr().out
    assert "moving_wall" in out and "exact to rounding" in out and "x none" in out
    for name in ("accuracy.csv", "slopes.csv", "features.csv", "error_vs_dt.png", "pareto.png"):
        assert (tmp_path / "b" / name).stat().st_size > 0
    rows = (tmp_path / "b" / "accuracy.csv").read_text().splitlines()
    assert rows[0].startswith("problem,metric,scheme,tol,dt,error,ci95")
    assert len(rows) == 1 + 6 * 3  # 6 dt levels x 3 schemes
    with pytest.raises(SystemExit):
        parser.parse_args(["bench", "accuracy", "--problems", "nope"])
    from sweep_core.bench import speed
    assert parser.parse_args(["bench", "speed", "--no-baseline"]).func is speed.run



def test_set_sigma_keeps_its_own_copy():
    """The intensities set are the simulator's own: an array the caller changes after
    set_sigma changes nothing (a run with them is the run with the values given)."""
    from scenes import GOOD
    scene = sc.Scene.from_dict(GOOD)
    given = np.zeros(scene.n_agents)
    a, b = sc.Simulator(scene, seed=4), sc.Simulator(scene, seed=4)
    a.set_sigma(given)
    given[:] = 0.5  # after set_sigma: the caller's array, not the simulator's
    b.set_sigma(0.0)
    a.step(5)
    b.step(5)
    assert np.all(a.sigma == 0.0)
    assert np.array_equal(a.positions, b.positions)
