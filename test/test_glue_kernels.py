"""The compiled forms of the projection's and the scan's per-step glue against the numpy forms
they replace, bit for bit, on random inputs (fixed seeds) with values over many magnitudes, NaN
included where numpy lets it through."""
from __future__ import annotations

import numpy as np
import pytest

from sweep_core.model.fields import Goal
from sweep_core.numerics import csm
from sweep_core.numerics.constraints import Rows
from sweep_core.numerics.projection import certified
from sweep_core.numerics.projection.project import first_cutoff
from sweep_core.numerics.projection.warm import carry_multipliers, contact_keys
from sweep_core.numerics.robots.scan import finish_ranges, finite_count


def bits(a: object) -> bytes:
    return np.ascontiguousarray(np.asarray(a, dtype=np.float64)).tobytes()


def wide(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """Normal draws scaled by powers of ten from 1e-9 to 1e3 (m)."""
    return rng.standard_normal(shape) * 10.0 ** rng.uniform(-9, 3, shape)


def random_rows(rng: np.random.Generator, n: int, pairs: int, singles: int) -> Rows:
    i = rng.integers(0, n - 1, pairs)
    j = i + 1 + rng.integers(0, n - 1 - i)
    e = rng.standard_normal((pairs, 2))
    e /= np.hypot(e[:, 0], e[:, 1])[:, None]
    nrm = rng.standard_normal((singles, 2))
    nrm /= np.hypot(nrm[:, 0], nrm[:, 1])[:, None]
    return Rows(i.astype(np.intp), j.astype(np.intp), e, wide(rng, (pairs,)),
                rng.integers(0, n, singles).astype(np.intp), nrm, wide(rng, (singles,)),
                rng.integers(0, 3, singles).astype(np.int8),
                rng.integers(0, 50, singles).astype(np.intp))


@pytest.mark.parametrize("seed", range(40))
def test_rows_in_displacement_form_and_their_agents(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 60))
    rows = random_rows(rng, n, int(rng.integers(0, 80)), int(rng.integers(0, 40)))
    q = wide(rng, (n, 2))
    ri, rj, re, h = rows.displacement_rows(q)
    hp = rows.pair_b - np.einsum("kc,kc->k", rows.pair_e, q[rows.pair_i] - q[rows.pair_j])
    hs = rows.single_b - np.einsum("kc,kc->k", rows.single_n, q[rows.single_a])
    assert bits(h) == bits(np.concatenate([hp, hs]))
    assert ri.dtype == rj.dtype == np.int64
    assert np.array_equal(ri, np.concatenate([rows.pair_i, rows.single_a]))
    assert np.array_equal(rj, np.concatenate([rows.pair_j, np.full(len(rows.single_a), -1)]))
    assert bits(re) == bits(np.concatenate([rows.pair_e, rows.single_n]))
    want = np.unique(np.concatenate([rows.pair_i, rows.pair_j, rows.single_a]))
    got = rows.agents()
    assert got.dtype == want.dtype and np.array_equal(got, want)


def keys_by_numpy(rows: Rows, n: int) -> np.ndarray:
    pairs = rows.pair_i.astype(np.int64) * n + rows.pair_j.astype(np.int64)
    singles = -1 - ((rows.single_a.astype(np.int64) << 26)
                    | (rows.single_kind.astype(np.int64) << 23)
                    | rows.single_item.astype(np.int64))
    return np.concatenate([pairs, singles])


def carried_by_numpy(old: Rows, lam: np.ndarray, new: Rows, n: int) -> np.ndarray:
    new_keys = keys_by_numpy(new, n)
    if len(lam) == 0 or len(new_keys) == 0:
        return np.zeros(len(new_keys))
    old_keys = keys_by_numpy(old, n)
    order = np.argsort(old_keys, kind="stable")
    ko, lo = old_keys[order], lam[order]
    pos = np.minimum(np.searchsorted(ko, new_keys), len(ko) - 1)
    return np.where(ko[pos] == new_keys, lo[pos], 0.0)


@pytest.mark.parametrize("seed", range(40))
def test_carried_multipliers(seed: int) -> None:
    """Rows drawn from a small set, so that old and new share contacts and some keys repeat
    (the first old row with a key gives its multiplier, as numpy's stable sort does)."""
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(2, 8))
    old = random_rows(rng, n, int(rng.integers(0, 30)), int(rng.integers(0, 30)))
    new = random_rows(rng, n, int(rng.integers(0, 30)), int(rng.integers(0, 30)))
    lam = np.abs(wide(rng, (old.count,)))
    for rows in (old, new):
        got, want = contact_keys(rows, n), keys_by_numpy(rows, n)
        assert got.dtype == want.dtype and np.array_equal(got, want)
    assert bits(carry_multipliers(old, lam, new, n)) == bits(carried_by_numpy(old, lam, new, n))


@pytest.mark.parametrize("seed", range(30))
def test_first_cutoff_and_rounding_floor(seed: int) -> None:
    rng = np.random.default_rng(200 + seed)
    n = int(rng.integers(1, 40))
    q, pred, r = wide(rng, (n, 2)), wide(rng, (n, 2)), np.abs(wide(rng, (n,)))
    h = wide(rng, (int(rng.integers(0, 30)),))
    if seed % 5 == 4:  # a NaN propagates as numpy's max propagates it
        pred[int(rng.integers(0, n)), 1] = np.nan
        if len(h):
            h[-1] = np.nan
    step = np.sqrt(np.einsum("ij,ij->i", pred - q, pred - q))
    assert bits(first_cutoff(q, pred, r)) == bits(3.0 * float(step.max()) + 1e-3 * float(r.max()))
    d = pred - q
    scale = max(float(np.abs(d).max(initial=0.0)), float(np.max(h, initial=0.0)), 1e-3)
    assert bits(certified.rounding_floor(d, h)) == bits(64.0 * float(np.finfo(float).eps) * scale)


@pytest.mark.parametrize("seed", range(30))
def test_speed_law_reach_terms(seed: int) -> None:
    """The speed law's largest |u|^2 and 2 max r: numpy's max of einsum and of r, NaN
    included."""
    rng = np.random.default_rng(400 + seed)
    n = int(rng.integers(1, 40))
    u, r = wide(rng, (n, 2)), np.abs(wide(rng, (n,)))
    if seed % 5 == 4:
        u[int(rng.integers(0, n)), int(rng.integers(0, 2))] = np.nan
        r[int(rng.integers(0, n))] = np.nan
    square, top = csm.largest_square(u, r)
    assert bits(square) == bits(float(np.max(np.einsum("ij,ij->i", u, u))))
    assert bits(top) == bits(2.0 * float(r.max()))


@pytest.mark.parametrize("seed", range(30))
def test_goal_field(seed: int) -> None:
    """The goal drift: numpy's d * (speed / maximum(|d|, slow))[:, None], NaN included."""
    rng = np.random.default_rng(500 + seed)
    n = int(rng.integers(0, 40))
    q = rng.uniform(-3.0, 3.0, (n, 2)) * 10.0 ** rng.uniform(-3, 1)
    goal, speed, slow = rng.uniform(-1.0, 1.0, 2), float(rng.uniform(0.1, 2.0)), 0.5
    if seed % 5 == 4 and n:
        q[int(rng.integers(0, n)), int(rng.integers(0, 2))] = np.nan
    if seed % 7 == 3 and n:
        q[0] = goal  # at the goal: 0 m/s
    d = goal - q
    dist = np.sqrt(np.einsum("ij,ij->i", d, d))
    want = d * (speed / np.maximum(dist, slow))[:, None]
    got = Goal(goal=goal, speed=speed, slow_radius=slow)(0.0, q)
    assert bits(got) == bits(want)


@pytest.mark.parametrize("seed", range(30))
def test_budgets_and_gaps(seed: int) -> None:
    rng = np.random.default_rng(300 + seed)
    clusters = int(rng.integers(1, 30))
    label = rng.integers(-1, clusters, int(rng.integers(clusters, 200)))
    label[:clusters] = np.arange(clusters)  # every cluster has an agent
    total = np.abs(wide(rng, (clusters,))) * (rng.uniform(size=clusters) < 0.8)
    if seed % 7 == 0:
        total[:] = 0.0
    tol, floor = 10.0 ** rng.uniform(-9, -3), 10.0 ** rng.uniform(-18, -12)
    sizes = np.bincount(label[label >= 0], minlength=clusters).astype(float)
    share = sizes / max(float(sizes.sum()), 1.0)
    lam_all = float(total.sum())
    if lam_all > 0.0:
        share = 0.5 * (share + total / lam_all)
    want = np.maximum(0.5 * tol * tol * share, 4.0 * floor * total)
    assert bits(certified.budgets(label, clusters, total, tol, floor)) == bits(want)
    comp, low = wide(rng, (clusters,)), wide(rng, (clusters,))
    if seed % 3 == 0:
        comp[0], low[-1] = np.nan, np.nan
    gap, done = np.empty(clusters), np.empty(clusters, dtype=np.bool_)
    certified.judged(comp, low, want, gap, done)
    ref = np.where(low >= 0.0, np.maximum(comp, 0.0), np.inf)
    assert bits(gap) == bits(ref) and np.array_equal(done, ref <= want)


@pytest.mark.parametrize("seed", range(30))
def test_scan_ranges_finished(seed: int) -> None:
    rng = np.random.default_rng(400 + seed)
    beams = int(rng.integers(0, 400))
    ranges = rng.uniform(0.0, 12.0, beams)
    ranges[rng.uniform(size=beams) < 0.3] = np.inf  # no return
    ref, mine = ranges.copy(), ranges.copy()
    std, low, high = 0.05 if seed % 2 else 0.0, 0.05 + 0.2 * (seed % 3), 10.0
    hit = np.isfinite(ref)
    assert finite_count(mine) == int(hit.sum())
    draws = rng.standard_normal(int(hit.sum())) if std else np.empty(0)
    if std:
        ref[hit] += std * draws
    ref[ref < low] = -np.inf
    ref[ref > high] = np.inf
    finish_ranges(mine, draws, std, low, high)
    assert bits(mine) == bits(ref)
