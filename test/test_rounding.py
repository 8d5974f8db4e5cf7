"""The certificate's rounding: x = d + A^T lam exact up to its last bits, and a skin floor set
by the rows that can be active, so that a hard-pushed jam is certified to the tolerance."""
from __future__ import annotations

from fractions import Fraction

import numpy as np
from test_certified import deep_jam

import sweep_core as sc
from sweep_core.numerics.projection import certified, dual


def test_multipliers_are_applied_exactly_up_to_the_last_bit():
    """Opposed rows with multipliers of hundreds of metres whose pushes nearly cancel, so that
    x is centimetres: x matches the exact rational d + A^T lam to 1 ulp. (Summed plainly, x
    carried an error of about eps times the multipliers, 1e-13 m, ten thousand ulp.)"""
    rng = np.random.default_rng(7)
    n, pairs = 6, 40
    d = rng.uniform(-0.03, 0.03, (n, 2))
    ri = rng.integers(0, n, 2 * pairs)
    rj = np.where(rng.random(2 * pairs) < 0.5, -1, (ri + 1 + rng.integers(0, n - 1, 2 * pairs)) % n)
    angle = rng.uniform(0, 2 * np.pi, pairs)
    e = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    re = np.concatenate([e, -e])  # row k + pairs pushes against row k
    big = rng.uniform(100.0, 1000.0, pairs)
    lam = np.concatenate([big, big + rng.uniform(0.0, 0.01, pairs)])
    rj[pairs:] = rj[:pairs]
    ri[pairs:] = ri[:pairs]
    x = dual.apply_multipliers(d, ri, rj, re, lam)
    exact = [[Fraction(float(v)) for v in row] for row in d]
    for k in range(len(ri)):
        for a in range(2):
            push = Fraction(float(lam[k])) * Fraction(float(re[k, a]))
            exact[ri[k]][a] += push
            if rj[k] >= 0:
                exact[rj[k]][a] -= push
    want = np.array([[float(v) for v in row] for row in exact])
    assert np.abs(want).max() < 1.0  # the pushes cancel down to small displacements
    ulp = np.spacing(np.abs(want))
    assert np.all(np.abs(x - want) <= ulp), np.max(np.abs(x - want) / ulp)


def test_rows_far_apart_do_not_raise_the_floor():
    """The floor is 64 ulp of the largest displacement or positive bound; a pair 0.5 m apart
    (bound -0.5 m), whose slack never needs the skin, leaves it unchanged."""
    d = np.array([[0.03, -0.01], [0.0, 0.02]])
    near = np.array([-1e-3, 2e-3])
    eps = float(np.finfo(float).eps)
    assert certified.rounding_floor(d, near) == 64.0 * eps * 0.03
    assert certified.rounding_floor(d, np.append(near, -0.5)) == 64.0 * eps * 0.03
    assert certified.rounding_floor(d, np.append(near, 0.04)) == 64.0 * eps * 0.04


def test_hard_pushed_polydisperse_jam_is_certified_to_the_tolerance():
    """300 disks of radii 0.20-0.27 m pushed to their centre at 4 m/s (multipliers summing to
    about 150 m): every step certified by the rounds within tol = 1e-6 m, every row held. With
    the floor set by the largest bound of any row (pairs up to the cutoff apart) the rounds
    stopped at that floor, and the bound of these steps reached 1.2e-6 m."""
    spec = deep_jam()
    spec["drift"]["speed"] = 4.0
    sim = sc.Simulator(sc.Scene.from_dict(spec), dt=0.02, seed=1)
    sim.step(30)
    total = 0.0
    for _ in range(10):
        sim.step()
        proj = sim.last.projection
        total = max(total, float(proj.lam_pair.sum() + proj.lam_single.sum()))
        assert proj.fallback_agents == 0
        assert proj.bound <= sim.scheme.solver.tol, proj.bound
        rp, rs = proj.rows.residuals(proj.y)
        assert min(rp.min(initial=0.0), rs.min(initial=0.0)) >= -1e-12
    assert total > 100.0  # deep enough that the skin's cost matters
