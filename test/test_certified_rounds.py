"""The certified rounds compiled (``certified.solve``) against the Python loop of the same
arithmetic written here, bit for bit, on the QPs of real steps (jams that need the factored
face step, a crowd with walls, a robot scene), and numpy's summation order in compiled code."""
from __future__ import annotations

import numpy as np
import pytest
from scenes import hex_jam
from test_certified import deep_jam, random_jam

import sweep_core as sc
from sweep_core.numerics.projection import certified, dual, factored, pairwise, small
from sweep_core.numerics.robots import small_step


def bits(a: object) -> bytes:
    return np.ascontiguousarray(np.asarray(a, dtype=np.float64)).tobytes()


@pytest.mark.parametrize("seed", range(12))
def test_numpy_sum_is_numpys_order(seed: int) -> None:
    """pairwise.numpy_sum against ndarray.sum on every length to 600 and some long ones (the
    pairwise split several levels deep), values over 40 orders of magnitude, and NaN and
    infinities where they appear."""
    rng = np.random.default_rng(seed)
    lengths = list(range(seed, 600, 12)) + [1023, 1024, 1025, 4099, 20011]
    for n in lengths:
        a = rng.standard_normal(n) * 10.0 ** rng.uniform(-20, 20, n)
        if seed % 4 == 3 and n:
            a[int(rng.integers(0, n))] = [np.nan, np.inf, -np.inf][seed % 3]
        assert bits(pairwise.numpy_sum(a)) == bits(a.sum()), n


def python_rounds(d, ri, rj, re, h, lam0, tol, max_rounds):
    """The rounds of certified.solve as a Python loop over the compiled kernels (numpy's sums,
    maxima and Python's max and min): the reference the compiled rounds must equal."""
    n = len(d)
    lam = np.array(lam0, dtype=float)
    label, clusters = dual.cluster_labels(n, ri, rj)
    floor = certified.rounding_floor(d, h)
    x = dual.apply_multipliers(d, ri, rj, re, lam)
    rounds = stall = factored_steps = 0
    best, skin, settled = np.inf, floor, None
    while True:
        comp, low, total = dual.cluster_certificates(x, ri, rj, re, h, lam, label, clusters)
        budget = np.empty(clusters)
        certified.shares(label, total, float(total.sum()), 0.5 * tol * tol, 4.0 * floor,
                         budget)
        gap, done = np.empty(clusters), np.empty(clusters, dtype=np.bool_)
        certified.judged(comp, low, budget, gap, done)
        if done.all() or rounds >= max_rounds:
            break
        undone = ~done
        worst = max(float(np.max(np.sqrt(gap[undone & np.isfinite(gap)]), initial=0.0)),
                    float(-np.min(np.minimum(low, 0.0)[undone], initial=0.0)))
        if worst < 0.5 * best:
            best, stall = worst, 0
        else:
            stall += 1
            if stall >= certified.STALL:
                break
        skin = max(floor, min(1e-8 * tol, tol * tol / (16.0 * max(float(lam.sum()), 1e-300))))
        tight = h + skin
        dual.pgs(x, ri, rj, re, tight, lam, certified.SWEEPS)
        face = lam > 0.0
        same = settled is not None and np.array_equal(face, settled)
        factored_steps += same
        if not (same and factored.face_step(x, d, ri, rj, re, tight, lam)):
            dual.face_step(x, d, ri, rj, re, tight, lam, certified.CG_ITERS, certified.PASSES)
        settled = lam > 0.0
        x = dual.apply_multipliers(d, ri, rj, re, lam)
        rounds += 1
    return x, lam, label, gap, budget, done, rounds, skin, floor, factored_steps


def qps_of(spec: dict, steps: int, dt: float = 0.01) -> list[tuple]:
    """The arguments of every certified.solve call of ``steps`` steps of a scene (projected
    through ``project``'s own path)."""
    calls: list[tuple] = []
    orig = certified.solve

    def record(d, ri, rj, re, h, lam0, *, tol, max_rounds):
        calls.append(tuple(np.copy(v) for v in (d, ri, rj, re, h, lam0)) + (tol, max_rounds))
        return orig(d, ri, rj, re, h, lam0, tol=tol, max_rounds=max_rounds)

    # the small scenes' compiled first pass (their projections and robot steps) calls the
    # rounds' kernel itself: project's own path, which calls certified.solve, is recorded
    kept = small.applies, small_step.applies
    certified.solve = record
    small.applies = small_step.applies = lambda *args: False
    try:
        sc.Simulator(sc.Scene.from_dict(spec), dt=dt, seed=2).step(steps)
    finally:
        certified.solve = orig
        small.applies, small_step.applies = kept
    return calls


ROBOT = {"agents": {"positions": [[2.0 + 0.45 * (k % 4), 1.0 + 0.45 * (k // 4)]
                                  for k in range(12)], "radius": 0.2},
         "walls": [{"kind": "polyline", "points": [[0, 0], [5, 0], [5, 3], [0, 3], [0, 0]]}],
         "drift": {"kind": "none"}, "noise": {"sigma": 0.3},
         "robots": [{"name": "r", "radius": 0.3, "pose": [0.6, 1.6, 0.0], "weight": "inf",
                     "kinematics": {"type": "holonomic", "max_speed": 1.0},
                     "goal": [4.5, 1.6], "controller": {"kind": "pursuit",
                                                        "slow_distance": 0.01}}]}


@pytest.mark.parametrize("spec,steps,factors", [(hex_jam(8, 8), 8, True),
                                                (deep_jam(120, seed=3), 20, False),
                                                (random_jam(4), 12, False), (ROBOT, 60, False)],
                         ids=["hex64", "deep120", "rand4", "robot"])
def test_compiled_rounds_equal_the_python_loop(spec: dict, steps: int, factors: bool) -> None:
    calls = qps_of(spec, steps)
    assert calls
    factored_steps = rounds = 0
    for d, ri, rj, re, h, lam0, tol, max_rounds in calls:
        got = certified.solve(d, ri, rj, re, h, lam0, tol=tol, max_rounds=max_rounds)
        want = python_rounds(d, ri, rj, re, h, lam0, tol, max_rounds)
        x, lam, label, gap, budget, done, n_rounds, skin, floor, used = want
        assert bits(got.x) == bits(x) and bits(got.lam) == bits(lam)
        assert np.array_equal(got.label, label) and np.array_equal(got.done, done)
        assert bits(got.gap) == bits(gap) and bits(got.budget) == bits(budget)
        assert (got.rounds, bits(got.skin), bits(got.floor)) == (n_rounds, bits(skin),
                                                                 bits(floor))
        factored_steps += used
        rounds += n_rounds
    assert rounds > 0
    if factors:  # the hexagonal jam takes the factored face step, and comes back from it
        assert factored_steps > 0


def test_a_nan_slack_and_a_round_cap_stop_as_the_loop_does() -> None:
    """A NaN bound leaves the progress measure to the gaps (Python's max keeps its first
    argument); max_rounds 0 certifies the start only."""
    calls = qps_of(random_jam(5), 4)
    d, ri, rj, re, h, lam0, tol, _ = calls[-1]
    h = h.copy()
    h[0] = np.nan
    for cap in (0, 1, 3):
        got = certified.solve(d, ri, rj, re, h, lam0, tol=tol, max_rounds=cap)
        x, lam, _, gap, _, done, n_rounds, skin, floor, _ = python_rounds(d, ri, rj, re, h, lam0,
                                                                          tol, cap)
        assert bits(got.x) == bits(x) and bits(got.lam) == bits(lam) and bits(got.gap) == bits(gap)
        assert got.rounds == n_rounds <= cap and bits(got.floor) == bits(floor)
