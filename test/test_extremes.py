"""The engine at the extremes (reference §6): no noise and vanishing noise, noise far larger
than the radii, tiny and huge steps, a 1000-agent jam, radii that stop fitting or shrink to
their floor, corners, N = 0 and N = 1, and 1e5 steps without drift of an invariant.

These tests assert feasibility, finiteness and exact invariants, never timings. Feasibility is
checked independently of the engine's own check (brute-force distances below)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scenes import hex_jam
from scipy.spatial import cKDTree

import sweep_core as sc

ALL = sorted(sc.SCHEMES)
NEW = sorted(set(sc.SCHEMES) - {"projected_euler"})
TOL = 1e-9  # the engine's feasibility tolerance (m)


def true_gaps(scene: sc.Scene, t: float, q: np.ndarray) -> float:
    """Smallest true constraint value at (t, q), computed from scratch (m; inf if none)."""
    r = scene.radii(t)
    worst = math.inf
    if len(q) > 1:
        i, j = cKDTree(q).query_pairs(2 * r.max() + 1.0, output_type="ndarray").T
        if len(i):
            worst = min(worst, float((np.linalg.norm(q[i] - q[j], axis=1) - r[i] - r[j]).min()))
    for w in scene.spec.get("walls", []):
        if w["kind"] == "halfplane":
            g = q @ np.array(w["normal"]) - (w["offset"] + w["velocity"] * t) - r
        else:
            a, b = np.array(w["a"]), np.array(w["b"])
            s = np.clip((q - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
            g = np.linalg.norm(q - (a + s[:, None] * (b - a)), axis=1) - r
        worst = min(worst, float(g.min(initial=math.inf)))
    for o in scene.spec.get("obstacles", []):
        g = np.linalg.norm(q - np.array(o["center"]), axis=1) - o["radius"] - r
        worst = min(worst, float(g.min(initial=math.inf)))
    return worst


def run_checked(sim: sc.Simulator, steps: int, each=None) -> None:
    for _ in range(steps):
        sim.step()
        q = sim.positions
        assert np.all(np.isfinite(q))
        assert true_gaps(sim.scene, sim.t, q) >= -TOL
        if each is not None:
            each(sim)


def box_crowd(sigma: float, rows: int = 4, cols: int = 4, law=None) -> dict:
    d = hex_jam(rows, cols, radius=0.2, spacing=0.5, sigma=sigma)
    d["agents"]["radius_law"] = law or {"kind": "constant"}
    d["walls"] = [{"kind": "halfplane", "normal": [1, 0], "offset": -0.3},
                  {"kind": "halfplane", "normal": [-1, 0], "offset": -2.2},
                  {"kind": "halfplane", "normal": [0, 1], "offset": -0.3},
                  {"kind": "segment", "a": [-1.0, 1.8], "b": [3.0, 1.8]}]
    d["obstacles"] = [{"kind": "circle", "center": [0.85, 0.65], "radius": 0.02}]
    d["agents"]["positions"] = [p for p in d["agents"]["positions"]
                                if np.hypot(p[0] - 0.85, p[1] - 0.65) > 0.25]
    return d


# -- noise: none, vanishing, huge -----------------------------------------------------------------
@pytest.mark.parametrize("name", ALL)
def test_sigma_zero_is_deterministic_and_feasible(name):
    scene = sc.Scene.from_dict(box_crowd(0.0))
    a = sc.Simulator(scene, dt=0.02, seed=1, scheme=name)
    b = sc.Simulator(scene, dt=0.02, seed=99, scheme=name)
    run_checked(a, 60)
    b.step(60)
    assert np.array_equal(a.positions, b.positions)  # the seed does not matter: no noise
    assert a.contacts > 5


@pytest.mark.parametrize("name", NEW)
def test_sigma_to_zero_error_is_linear_in_sigma(name):
    """Bernicot-Venel's stability (sup_t |X^sigma - x| <= c sigma) for the new schemes, on the
    scene of test_exact's projected-Euler version: agents pushed into a wall, sliding."""
    base = sc.Scene.from_dict({
        "agents": {"positions": [[0.7 * k, 0.3] for k in range(6)], "radius": 0.3},
        "walls": [{"kind": "halfplane", "normal": [0, 1], "offset": 0.0}],
        "drift": {"kind": "uniform", "velocity": [1.0, -0.5]}})
    ref = sc.Simulator(base, dt=0.01, seed=3, scheme=name)
    traj0 = []
    ref.run(1.0, callback=lambda s: traj0.append(s.positions))
    ratios = []
    for sigma in (0.2, 0.1, 0.05, 0.025):
        sim = sc.Simulator(base, dt=0.01, seed=3, scheme=name)
        sim.set_sigma(sigma)
        traj = []
        sim.run(1.0, callback=lambda s: traj.append(s.positions))
        ratios.append(np.max(np.linalg.norm(np.array(traj) - np.array(traj0), axis=2)) / sigma)
    assert max(ratios) <= 1.25 * min(ratios), ratios


@pytest.mark.parametrize("name", ALL)
def test_noise_far_above_the_radius_tunnels_through_nothing(name):
    """sigma sqrt(dt) = 0.32 m against radii of 0.1 m. In a corridor 0.35 m wide nobody can
    pass anybody (that needs 4 r = 0.4 m), so the order along it never changes; nobody
    leaves it through its walls, and the chord of every step misses a round obstacle."""
    r, width, n = 0.1, 0.35, 10
    scene = sc.Scene.from_dict({
        "agents": {"positions": [[0.3 * k, 0.175] for k in range(n)], "radius": r},
        "walls": [{"kind": "halfplane", "normal": [0, 1], "offset": 0.0},
                  {"kind": "segment", "a": [-1e3, width], "b": [1e3, width]}],
        "noise": {"sigma": 1.0}, "drift": {"kind": "uniform", "velocity": [2.0, 0.0]}})
    sim = sc.Simulator(scene, dt=0.1, seed=8, scheme=name)
    seen = np.zeros(n)

    def ordered(s):
        x = s.positions[:, 0]
        assert np.all(np.diff(x) >= 2 * r - width), "two agents swapped places"
        assert np.all(np.argsort(x, kind="stable") == np.arange(n))
        y = s.positions[:, 1]
        assert y.min() >= r - TOL and y.max() <= width - r + TOL
        seen[:] = np.maximum(seen, np.abs(s.reaction).max(axis=1))

    run_checked(sim, 50, ordered)
    assert seen.min() > 0  # every agent was pushed back at least once

    big_r, c = 1.0, np.array([0.0, 0.0])
    ring = sc.Scene.from_dict({
        "agents": {"positions": [[-1.2, 0.0], [1.2, 0.0], [0.0, 1.2], [0.0, -1.2]], "radius": r},
        "obstacles": [{"kind": "circle", "center": c.tolist(), "radius": big_r}],
        "noise": {"sigma": 1.0},
        "drift": {"kind": "goal", "goal": [0.0, 0.0], "speed": 3.0, "slow_radius": 0.1}})
    sim = sc.Simulator(ring, dt=0.1, seed=9, scheme=name)
    for _ in range(100):
        q0 = sim.positions
        sim.step()
        q1 = sim.positions
        assert true_gaps(ring, sim.t, q1) >= -TOL
        if getattr(sim.scheme, "last_substeps", 1) == 1:
            # the closest point of each chord [q0, q1] to the centre stays outside R + r
            d = q1 - q0
            s = np.clip(-np.einsum("ij,ij->i", q0 - c, d) / np.maximum(
                np.einsum("ij,ij->i", d, d), 1e-300), 0, 1)
            closest = np.linalg.norm(q0 + s[:, None] * d - c, axis=1)
            assert closest.min() >= big_r + r - TOL


@pytest.mark.parametrize("name", ALL)
@pytest.mark.parametrize("dt", [1e-5, 1e-3, 0.05, 0.5])
def test_time_steps_from_1e_5_to_half_a_second(name, dt):
    scene = sc.Scene.from_dict(box_crowd(0.3))
    sim = sc.Simulator(scene, dt=dt, seed=4, scheme=name)
    q0 = sim.positions
    run_checked(sim, 15)
    if dt == 1e-5:  # 15 tiny steps move an agent by about |U| t + sigma sqrt(t), no more
        assert np.abs(sim.positions - q0).max() < 15 * dt * 1.0 + 8 * 0.3 * math.sqrt(15 * dt)


# -- dense and tight configurations ----------------------------------------------------------------
def test_a_1000_agent_hexagonal_jam_pushed_to_one_point():
    scene = sc.Scene.from_dict(hex_jam(25, 40, radius=0.24, spacing=0.5, sigma=0.1))
    assert scene.n_agents == 1000
    sim = sc.Simulator(scene, dt=0.02, seed=6)
    for _ in range(30):
        sim.step()
    q = sim.positions
    assert np.all(np.isfinite(q))
    assert true_gaps(scene, sim.t, q) >= -TOL
    assert sim.contacts > 1000  # really jammed: more contacts than agents


@pytest.mark.parametrize("name", ALL)
def test_radii_growing_until_they_cannot_fit(name):
    """Two disks between walls 1 m apart, r(t) = 0.2 + 0.45 t: they fit while 4 r <= 1,
    i.e. t <= 1/9 s. Everything is collinear, so the linearised set is exact and empty first
    at the first (sub-)step after 1/9 s; the state stays at the last accepted step."""
    scene = sc.Scene.from_dict({
        "agents": {"positions": [[0.3, 0.0], [0.7, 0.0]], "radius": 0.2,
                   "radius_law": {"kind": "linear", "rate": 0.45}},
        "walls": [{"kind": "halfplane", "normal": [1, 0], "offset": 0.0},
                  {"kind": "halfplane", "normal": [-1, 0], "offset": -1.0}]})
    sim = sc.Simulator(scene, dt=0.01, seed=0, scheme=name)
    with pytest.raises(sc.InfeasibleError) as err:
        run_checked(sim, 20)
    t_star = 1 / 9
    if name == "adaptive":  # bisected down to dt / 2**max_depth
        assert t_star < err.value.t <= t_star + 0.01 / 2 ** sim.scheme.max_depth + 1e-12
    else:
        assert err.value.t == pytest.approx(0.12)
    assert sorted(err.value.agents) == [0, 1]
    assert "t = 0.1" in str(err.value)
    assert sim.t == pytest.approx(0.11)
    before = sim.positions
    assert true_gaps(scene, sim.t, before) >= -TOL
    with pytest.raises(sc.InfeasibleError):  # and again: nothing was half-applied
        sim.step()
    assert np.array_equal(sim.positions, before) and sim.t == pytest.approx(0.11)


@pytest.mark.parametrize("name", ALL)
def test_a_noisy_crowd_growing_in_a_box_stops_with_its_state_intact(name):
    """Fifteen disks in a 2.5 m box growing at 0.5 m/s with noise: the area bound
    15 pi r^2 <= 2.5^2 fails at r = 0.364 m (t = 0.33 s), so the error must come by then,
    and the last accepted state is feasible."""
    spec = box_crowd(0.2, law={"kind": "linear", "rate": 0.5})
    spec["walls"][3] = {"kind": "halfplane", "normal": [0, -1], "offset": -2.2}
    del spec["obstacles"]
    scene = sc.Scene.from_dict(spec)
    sim = sc.Simulator(scene, dt=0.01, seed=3, scheme=name)
    with pytest.raises(sc.InfeasibleError) as err:
        run_checked(sim, 40)
    assert scene.n_agents == 15
    assert err.value.t <= 0.33 + 1e-9 and err.value.agents
    assert err.value.t == pytest.approx(sim.t + 0.01) or name == "adaptive"
    before = sim.positions
    assert true_gaps(scene, sim.t, before) >= -TOL
    with pytest.raises(sc.InfeasibleError):
        sim.step()
    assert np.array_equal(sim.positions, before)


@pytest.mark.parametrize("name", ALL)
def test_radii_shrinking_to_near_their_floor(name):
    law = {"kind": "linear", "rate": -0.199}  # 0.2 m -> 1 mm at t = 1 s
    scene = sc.Scene.from_dict(box_crowd(0.1, law=law))
    sim = sc.Simulator(scene, dt=0.01, seed=2, scheme=name)
    run_checked(sim, 100)
    assert sim.radii.min() == pytest.approx(0.001, abs=1e-9)
    with pytest.raises(sc.SceneError, match="radius_law"):
        sim.run(1.1)  # past the floor: refused before any step
    assert sim.t == pytest.approx(1.0)


@pytest.mark.parametrize("name", ALL)
def test_agents_in_a_corner_touching_two_walls_and_each_other(name):
    r = 0.2
    spec = {"agents": {"positions": [[r, r], [3 * r, r], [r, 3 * r], [3 * r, 3 * r]], "radius": r},
            "walls": [{"kind": "halfplane", "normal": [1, 0], "offset": 0.0},
                      {"kind": "halfplane", "normal": [0, 1], "offset": 0.0}],
            "drift": {"kind": "uniform", "velocity": [-1.0, -1.0]}}
    still = sc.Simulator(sc.Scene.from_dict(spec), dt=0.05, seed=0, scheme=name)
    run_checked(still, 40)
    np.testing.assert_allclose(still.positions, spec["agents"]["positions"], rtol=0, atol=1e-9)
    assert still.contacts >= 8  # 4 pairs (square sides) + 4 wall contacts
    spec["noise"] = {"sigma": 0.3}
    noisy = sc.Simulator(sc.Scene.from_dict(spec), dt=0.05, seed=0, scheme=name)
    run_checked(noisy, 40)


@pytest.mark.parametrize("name", ALL)
@pytest.mark.parametrize("n", [0, 1])
def test_no_agent_and_one_agent(name, n):
    scene = sc.Scene.from_dict({
        "agents": {"positions": [[0.5, 0.5]][:n], "radius": 0.2},
        "walls": [{"kind": "halfplane", "normal": [1, 0], "offset": 0.0},
                  {"kind": "segment", "a": [0.0, 1.0], "b": [2.0, 1.0]}],
        "obstacles": [{"kind": "circle", "center": [1.0, 0.0], "radius": 0.2}],
        "drift": {"kind": "goal", "goal": [1.0, 0.0], "speed": 1.0}, "noise": {"sigma": 0.5}})
    sim = sc.Simulator(scene, dt=0.05, seed=1, scheme=name)
    run_checked(sim, 40)
    assert sim.positions.shape == (n, 2) and sim.t == pytest.approx(2.0)
    if n == 0:
        assert sim.min_gap == math.inf and sim.contacts == 0


def test_1e5_steps_keep_the_barycentre_of_two_equal_disks():
    """Two equal disks under the symmetric drift U = -k (q - c) with noise. Contact reactions
    are equal and opposite, so the barycentre m follows the linear recursion
    m' = m - h k (m - c) + sigma (dB_1 + dB_2) / 2 exactly, whatever the contacts do: after
    1e5 steps it must still agree with the recursion to rounding (no drift of the invariant),
    and the disks must never overlap."""
    k, c, sigma, h, r = 1.0, np.array([0.3, -0.2]), 0.05, 0.01, 0.25
    scene = sc.Scene.from_dict({
        "agents": {"positions": [[-0.5, -0.2], [1.1, -0.2]], "radius": r},
        "drift": {"kind": "linear", "matrix": [[-k, 0.0], [0.0, -k]], "offset": (k * c).tolist()},
        "noise": {"sigma": sigma}})
    sim = sc.Simulator(scene, dt=h, seed=0)
    rng = np.random.default_rng(2025)
    m = scene.positions.mean(axis=0)
    worst_gap, worst_bary, pushed = math.inf, 0.0, 0
    chunk = 1000
    for _ in range(100):
        dB = rng.normal(0.0, math.sqrt(h), (chunk, 2, 2))
        sim.step(chunk, dB=dB)  # the engine checks every step's true gaps (1e-9 m) itself
        for j in range(chunk):
            m = m - h * k * (m - c) + sigma * dB[j].mean(axis=0)
        q = sim.positions
        worst_gap = min(worst_gap, float(np.hypot(*(q[0] - q[1]))) - 2 * r)
        pushed += bool(np.any(sim.reaction))
        worst_bary = max(worst_bary, float(np.abs(q.mean(axis=0) - m).max()))
        assert np.all(np.isfinite(q))
    assert sim.n_steps == 100_000
    assert worst_gap >= -TOL
    assert worst_bary < 1e-9
    assert pushed > 10  # the contact really was active along the run


def test_a_centre_jumping_through_a_wall_is_caught_even_when_its_distance_looks_fine():
    """A wall from x = -1e16 to 1e16 (where one ulp is 2 m, so its distances are meaningless;
    scenes refuse it, the geometry is put in directly here): agents driven at it went through
    and ended on the far side with 'status completed'. The path of each centre is tested
    against the walls exactly, so the step that crosses is refused."""
    import dataclasses

    scene = sc.Scene.from_dict({"agents": {"positions": [[1, 4], [3, 4]], "radius": 0.3},
                                "walls": [{"kind": "segment", "a": [-100, 5], "b": [100, 5]}],
                                "drift": {"kind": "uniform", "velocity": [0, 1]}})
    far = dataclasses.replace(scene.geometry, segment_a=np.array([[-1e16, 5.0]]),
                              segment_b=np.array([[1e16, 5.0]]))
    sim = sc.Simulator(dataclasses.replace(scene, geometry=far), dt=0.01)
    with pytest.raises(sc.InfeasibleError, match=r"went through walls\[0\] \(segment\)"):
        sim.run(3.0)
    assert np.all(sim.positions[:, 1] <= 5.0)  # kept at the last step before the crossing


@pytest.mark.parametrize("wall", [
    {"kind": "segment", "a": [-5, 1], "b": [5, 1]},
    {"kind": "polyline", "points": [[-5, 1], [0, 1], [5, 1]], "closed": False}])
def test_a_step_that_jumps_through_a_thin_wall_is_refused(wall):
    """A scheme that lands agent 1 on the far side of a wall (0.5 m beyond it, so its end
    position satisfies every constraint): the straight path of its centre meets the wall, and
    the step is refused naming the agent and the wall; the state stays at the last step."""
    from dataclasses import replace

    from sweep_core.numerics.schemes import ProjectedEuler

    class Jumping(ProjectedEuler):
        def step(self, t, q, h, dB, drift, sigma):
            res = super().step(t, q, h, dB, drift, sigma)
            q_new = res.q_new.copy()
            if t > 0.015:
                q_new[1, 1] = 1.5  # from y = 0.5 to 1.5, through the wall at y = 1
            return replace(res, q_new=q_new)

    scene = sc.Scene.from_dict({"agents": {"positions": [[-2, 0.5], [2, 0.5]], "radius": 0.2},
                                "walls": [wall]})
    sim = sc.Simulator(scene, dt=0.01, scheme=Jumping)
    sim.step(2)
    with pytest.raises(sc.InfeasibleError, match=r"agents \[1\].*centre of agent 1 went "
                                                  r"through walls\[0\]"):
        sim.step()
    assert sim.n_steps == 2 and sim.positions[1, 1] == 0.5


try:
    from hypothesis import given, settings
    from hypothesis import strategies as st
except ImportError:  # pragma: no cover - hypothesis is in requirements-dev.txt
    given = None

if given is not None:
    @settings(max_examples=30, deadline=None, derandomize=True)
    @given(angle=st.floats(0.0, 2 * math.pi), half=st.floats(100.0, 2e4),
           cx=st.floats(-50.0, 50.0), cy=st.floats(-50.0, 50.0),
           speed=st.floats(0.5, 10.0), push=st.floats(-0.9, 0.9))
    def test_agents_driven_at_a_long_wall_stay_on_their_side(angle, half, cx, cy, speed, push):
        """A segment wall through (cx, cy) at least 100 m long each way, its ends as far as the
        coordinate bound allows (beyond the agents' reach in 20 steps), three
        agents 0.5 m from it driven into it (at an angle: push along the wall): after every
        step each centre is on its starting side (exact orientation sign) and its float
        distance to the wall is at least its radius - 1e-9 m."""
        from sweep_core.checks import COORDINATE_BOUND
        from sweep_core.model.outlines import orientation

        d = np.array([math.cos(angle), math.sin(angle)])
        n = np.array([-d[1], d[0]])
        c = np.array([cx, cy])
        # ends within the bound: shorten the half-length until both fit
        lim = min((COORDINATE_BOUND - abs(c[k])) / max(abs(d[k]), 1e-300) for k in range(2))
        half = min(half, lim)
        a, b = c - half * d, c + half * d
        r = 0.3
        q0 = np.array([c + n * (r + 0.5) + d * s for s in (-1.5, 0.0, 1.5)])
        scene = sc.Scene.from_dict({"agents": {"positions": q0.tolist(), "radius": r},
                                    "walls": [{"kind": "segment", "a": a.tolist(),
                                               "b": b.tolist()}],
                                    "drift": {"kind": "uniform",
                                              "velocity": (speed * (push * d - n)).tolist()}})
        a, b = scene.geometry.segment_a[0], scene.geometry.segment_b[0]
        side = orientation(a, b, scene.positions)
        assert np.all(side == 1)
        sim = sc.Simulator(scene, dt=0.05, seed=0)
        for _ in range(20):
            sim.step()
            q = sim.positions
            assert np.array_equal(orientation(a, b, q), side)
            s = np.clip((q - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
            dist = np.linalg.norm(q - (a + s[:, None] * (b - a)), axis=1)
            assert dist.min() >= r - TOL
