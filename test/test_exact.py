"""The scheme against exact solutions and proven properties (reference §5)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scenes import hex_jam, wall_agent

import sweep_core as sc

#: Asmussen-Glynn-Pitman constant: E max over a grid of step h of a Brownian path falls short
#: of the continuous maximum by beta sqrt(h) + o(sqrt(h)), beta = -zeta(1/2) / sqrt(2 pi).
BETA = 1.4603545088095868 / math.sqrt(2 * math.pi)


def skorokhod_1d(h: np.ndarray, floor: float) -> np.ndarray:
    """Exact Skorokhod map of a 1-D grid path h onto [floor, inf)."""
    return h + np.maximum(0.0, np.maximum.accumulate(floor - h))


def test_half_line_scheme_equals_skorokhod_map_of_the_grid_path():
    r = 0.5
    scene = sc.Scene.from_dict(wall_agent(x0=r + 0.3, radius=r, sigma=1.0))
    rng = np.random.default_rng(7)
    n, h = 400, 0.01
    dB = rng.normal(0.0, math.sqrt(h), size=(n, 1, 2))
    sim = sc.Simulator(scene, dt=h, seed=0)
    xs = [sim.positions[0, 0]]
    for k in range(n):
        sim.step(dB=dB[k])
        xs.append(sim.positions[0, 0])
    path = (r + 0.3) + np.concatenate([[0.0], np.cumsum(dB[:, 0, 0])])
    exact = skorokhod_1d(path, r)
    assert np.max(np.abs(np.array(xs) - exact)) < 1e-9
    assert np.count_nonzero(exact[1:] - path[1:] > 1e-6) > 10  # the wall was really hit
    # tangential component is free
    assert sim.positions[0, 1] == pytest.approx(np.sum(dB[:, 0, 1]), abs=1e-12)
    # sc.skorokhod on the same grid path gives the same map
    times = np.arange(n + 1) * h
    full = np.zeros((n + 1, 1, 2))
    full[:, 0, 0] = path
    assert np.max(np.abs(sc.skorokhod(scene, full, times)[:, 0, 0] - exact)) < 1e-9


def test_reflected_brownian_mean_distance_at_t1():
    """E X_1 = sqrt(2/pi) for reflected BM from the wall, less the known grid bias."""
    m, h, r, spacing = 3000, 0.01, 0.1, 40.0
    scene = sc.Scene.from_dict({
        "agents": {"positions": [[r, spacing * k] for k in range(m)], "radius": r},
        "walls": [{"kind": "halfplane", "normal": [1, 0], "offset": 0.0}],
        "noise": {"sigma": 1.0}})
    sim = sc.Simulator(scene, dt=h, seed=2024)
    sim.run(1.0)
    d = sim.positions[:, 0] - r
    assert d.min() >= -1e-9
    mean, se = d.mean(), d.std(ddof=1) / math.sqrt(m)
    exact = math.sqrt(2 / math.pi)
    assert abs(mean - exact) <= 3 * se + BETA * math.sqrt(h)
    # sharper: the scheme's mean is the continuous one shifted by the grid bias
    assert abs(mean - (exact - BETA * math.sqrt(h))) <= 3 * se + h


def test_moving_wall_pushes_a_point_exactly():
    x0, r, c0, v = 0.5, 0.25, -1.0, 0.5
    scene = sc.Scene.from_dict({
        "agents": {"positions": [[x0, 0.0]], "radius": r},
        "walls": [{"kind": "halfplane", "normal": [1, 0], "offset": c0, "velocity": v}]})
    sim = sc.Simulator(scene, dt=0.01, seed=0)
    got, want = [], []
    sim.run(5.0, callback=lambda s: (got.append(s.positions[0, 0]),
                                     want.append(max(x0, c0 + v * s.t + r))))
    assert np.max(np.abs(np.array(got) - np.array(want))) < 1e-9
    assert want[-1] > x0 + 1.0  # the wall really pushed


def test_two_agents_head_on_touch_at_the_exact_time():
    r, h = 0.25, 0.01
    scene = sc.Scene.from_dict({
        "agents": {"positions": [[-1.0, 0.0], [1.0, 0.0]], "radius": r},
        "drift": {"kind": "per_agent", "velocities": [[1.0, 0.0], [-1.0, 0.0]]}})
    sim = sc.Simulator(scene, dt=h, seed=0)
    for k in range(1, 151):
        sim.step()
        q = sim.positions
        gap = q[1, 0] - q[0, 0] - 2 * r
        assert gap == pytest.approx(max(0.0, 1.5 - 2 * k * h), abs=1e-9)
        assert q[0, 0] == pytest.approx(-1.0 + min(k * h, 0.75), abs=1e-9)
        assert abs(q[0, 1]) < 1e-12 and abs(q[1, 1]) < 1e-12
    assert sim.contacts == 1


def test_sigma_to_zero_error_is_linear_in_sigma():
    """Bernicot-Venel: sup_t |X^sigma - x| <= c sigma. On one Brownian path and a scene whose
    contacts persist (a file of agents pushed into a wall while sliding along it), the error
    is in its linear regime: error / sigma is flat."""
    base = sc.Scene.from_dict({
        "agents": {"positions": [[0.7 * k, 0.3] for k in range(6)], "radius": 0.3},
        "walls": [{"kind": "halfplane", "normal": [0, 1], "offset": 0.0}],
        "drift": {"kind": "uniform", "velocity": [1.0, -0.5]}})
    ref = sc.Simulator(base, dt=0.01, seed=3)
    traj0 = []
    ref.run(1.0, callback=lambda s: traj0.append(s.positions))
    ratios = []
    for sigma in (0.2, 0.1, 0.05, 0.025):
        sim = sc.Simulator(base, dt=0.01, seed=3)
        sim.set_sigma(sigma)
        traj = []
        sim.run(1.0, callback=lambda s: traj.append(s.positions))
        err = np.max(np.linalg.norm(np.array(traj) - np.array(traj0), axis=2))
        ratios.append(err / sigma)
    assert max(ratios) <= 1.2 * min(ratios), ratios


def test_dense_jam_never_overlaps():
    scene = sc.Scene.from_dict(hex_jam(20, 20, radius=0.24, spacing=0.5, sigma=0.1))
    sim = sc.Simulator(scene, dt=0.01, seed=1)
    worst = math.inf

    def check(s: sc.Simulator) -> None:
        nonlocal worst
        q = s.positions
        assert np.all(np.isfinite(q))
        d = np.linalg.norm(q[:, None] - q[None], axis=2) + np.eye(len(q)) * 1e9
        worst = min(worst, float((d - 2 * 0.24).min()))

    sim.run(2.0, callback=check)
    assert sim.n_steps == 200
    assert worst >= -1e-9
    assert sim.contacts > 300  # it really is a jam


def test_growing_radii_that_cannot_fit_raise_at_the_right_time_and_keep_the_state():
    scene = sc.Scene.from_dict({
        "agents": {"positions": [[0.5, 0.0]], "radius": 0.2,
                   "radius_law": {"kind": "linear", "rate": 0.5}},
        "walls": [{"kind": "halfplane", "normal": [1, 0], "offset": 0.0},
                  {"kind": "halfplane", "normal": [-1, 0], "offset": -1.0}]})
    sim = sc.Simulator(scene, dt=0.01, seed=0)
    with pytest.raises(sc.InfeasibleError) as err:
        sim.run(1.0)
    assert err.value.t == pytest.approx(0.61)
    assert err.value.agents == [0]
    assert "t = 0.61" in str(err.value)
    assert sim.t == pytest.approx(0.60)
    assert sim.positions[0, 0] == pytest.approx(0.5, abs=1e-9)


def test_agents_never_cross_segments_and_obstacles():
    scene = sc.Scene.from_dict({
        "agents": {"positions": [[0.0, y] for y in np.linspace(-1.5, 1.5, 7)], "radius": 0.2},
        "walls": [{"kind": "segment", "a": [1.0, -0.6], "b": [1.0, 0.6]}],
        "obstacles": [{"kind": "circle", "center": [1.2, 1.4], "radius": 0.3}],
        "drift": {"kind": "uniform", "velocity": [2.0, 0.0]},
        "noise": {"sigma": 0.3}})
    sim = sc.Simulator(scene, dt=0.01, seed=5)
    sim.run(2.0, callback=lambda s: None)
    assert sim.min_gap >= -1e-9 or sim.min_gap == math.inf
