"""The compiled forms of the robots' per-step glue against the numpy expressions they replace,
bit for bit, on random inputs (fixed seeds): multipliers zero, positive, negative and NaN,
values over many magnitudes."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from sweep_core.model.geometry import CIRCLE
from sweep_core.model.robots import ScanSpec
from sweep_core.numerics.constraints import Rows
from sweep_core.numerics.projection import Projection
from sweep_core.numerics.robots.contacts import set_contacts
from sweep_core.numerics.robots.control import within_reach
from sweep_core.numerics.robots.scan import (
    beam_directions,
    bounded_ranges,
    cast_beams,
    finite_count,
    ray_cast,
)


def bits(a: object) -> bytes:
    return np.ascontiguousarray(a).tobytes()


def wide(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """Normal draws scaled by powers of ten from 1e-9 to 1e3."""
    return rng.standard_normal(shape) * 10.0 ** rng.uniform(-9, 3, shape)


def multipliers(rng: np.random.Generator, k: int) -> np.ndarray:
    lam = np.abs(wide(rng, (k,)))
    pick = rng.integers(0, 5, k)
    lam[pick == 0] = 0.0
    lam[pick == 1] = -lam[pick == 1]
    lam[(pick == 2) & (rng.uniform(size=k) < 0.2)] = np.nan
    return lam


def contacts_by_numpy(states: list, proj: Projection, n: int, n_circles: int, h: float
                      ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Each robot's contacts as numpy expressions (the form the kernels replace)."""
    free = [k for k, st in enumerate(states) if not st.robot.prescribed]
    fixed = [k for k, st in enumerate(states) if st.robot.prescribed]
    rows, lam_p, lam_s = proj.rows, proj.lam_pair, proj.lam_single
    out = []
    for k, st in enumerate(states):
        if st.robot.prescribed:
            item = n_circles + fixed.index(k)
            pick = np.flatnonzero((rows.single_kind == CIRCLE) & (rows.single_item == item)
                                  & (lam_s > 0))
            ids = rows.single_a[pick]
            imp = lam_s[pick, None] * rows.single_n[pick] / h
        else:
            me = n + free.index(k)
            as_i = np.flatnonzero((rows.pair_i == me) & (rows.pair_j < n) & (lam_p > 0))
            as_j = np.flatnonzero((rows.pair_j == me) & (rows.pair_i < n) & (lam_p > 0))
            ids = np.concatenate([rows.pair_j[as_i], rows.pair_i[as_j]])
            imp = np.concatenate([-lam_p[as_i, None] * rows.pair_e[as_i],
                                  lam_p[as_j, None] * rows.pair_e[as_j]]) / h
        order = np.argsort(ids, kind="stable")
        got = ids[order].astype(np.int64)
        out.append((got, proj.y[got].copy(), imp[order].reshape(-1, 2)))
    return out


def random_case(seed: int) -> int:
    """One random fleet's contacts compared; how many robots had some."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 30))
    kinds = [bool(v) for v in rng.integers(0, 2, int(rng.integers(1, 5)))]  # prescribed?
    total = n + kinds.count(False)
    pairs, singles = int(rng.integers(0, 80)), int(rng.integers(0, 60))
    # pairs of distinct agents, either first (the kernels take both orders)
    i = rng.integers(0, total, pairs) if total > 1 else np.zeros(0, dtype=np.int64)
    j = (i + rng.integers(1, max(total, 2), len(i))) % total
    pairs = len(i)
    e = rng.standard_normal((pairs, 2))
    nrm = rng.standard_normal((singles, 2))
    n_circles = int(rng.integers(0, 3))
    item = rng.integers(0, n_circles + kinds.count(True) + 1, singles)
    rows = Rows(i.astype(np.intp), j.astype(np.intp), e, wide(rng, (pairs,)),
                rng.integers(0, n, singles).astype(np.intp), nrm, wide(rng, (singles,)),
                np.where(rng.uniform(size=singles) < 0.5, CIRCLE,
                         rng.integers(0, 3, singles)).astype(np.int8), item.astype(np.intp))
    proj = Projection(wide(rng, (total, 2)), rows, multipliers(rng, pairs),
                      multipliers(rng, singles), 0, 0, 0)
    h = float(10.0 ** rng.uniform(-3, 0))
    states = [SimpleNamespace(robot=SimpleNamespace(prescribed=p)) for p in kinds]
    want = contacts_by_numpy(states, proj, n, n_circles, h)
    set_contacts(states, proj, n, n_circles, h)
    for st, (ids, xy, imp) in zip(states, want, strict=True):
        assert st.contact_ids.dtype == np.int64 and np.array_equal(st.contact_ids, ids)
        assert st.contact_xy.shape == xy.shape and bits(st.contact_xy) == bits(xy)
        assert st.contact_impulse.shape == imp.shape and bits(st.contact_impulse) == bits(imp)
    return sum(len(st.contact_ids) > 0 for st in states)


@pytest.mark.parametrize("start", range(0, 200, 50))
def test_contacts_as_the_numpy_expressions(start: int) -> None:
    touched = sum(random_case(seed) for seed in range(start, start + 50))
    assert touched >= 20  # most draws give contacts: not only empty arrays compared


@pytest.mark.parametrize("seed", range(20))
def test_bounded_ranges_as_nan_assignment_and_clip(seed: int) -> None:
    rng = np.random.default_rng(seed)
    b = int(rng.integers(0, 90))
    range_max = float(10.0 ** rng.uniform(-1, 2))
    ranges = np.abs(wide(rng, (b,))) * rng.choice([1.0, -1.0], b, p=[0.9, 0.1])
    # (no -0.0: whether numpy's clip keeps its sign is its SIMD kernels' business)
    special = np.array([np.nan, np.inf, -np.inf, 0.0, range_max,
                        np.nextafter(range_max, np.inf), np.nextafter(0.0, -1.0)])
    pick = rng.uniform(size=b) < 0.3
    ranges[pick] = rng.choice(special, int(pick.sum()))
    want = ranges.copy()
    want[np.isnan(want)] = range_max
    want = np.clip(want, 0.0, range_max)
    got = np.empty(b)
    bounded_ranges(ranges, range_max, got)
    assert bits(got) == bits(want)


@pytest.mark.parametrize("seed", range(20))
def test_within_reach_as_the_numpy_distance(seed: int) -> None:
    rng = np.random.default_rng(seed)
    m = int(rng.integers(0, 60))
    people = wide(rng, (m, 2))
    radii = np.abs(wide(rng, (m,)))
    x, y = (float(v) for v in wide(rng, (2,)))
    d0 = np.hypot(people[:, 0] - x, people[:, 1] - y) - radii
    # reaches at some of the distances exactly, and between them
    reach = float(rng.choice(d0)) if m and rng.uniform() < 0.5 else float(10.0 ** rng.uniform(-3, 3))
    if m:
        people[rng.uniform(size=m) < 0.1] = np.nan
    want = np.hypot(people[:, 0] - x, people[:, 1] - y) - radii <= reach
    got = np.empty(m, dtype=np.bool_)
    within_reach(people, radii, x, y, reach, got)
    assert np.array_equal(got, want)


@pytest.mark.parametrize("seed", range(4))
def test_cast_beams_equals_directions_ray_cast_and_count(seed: int) -> None:
    """cast_beams gives the ranges and hit count of beam_directions, ray_cast and
    finite_count called one after the other, bit for bit (disks inside and outside, segments,
    half-planes, yaws over several turns)."""
    rng = np.random.default_rng(seed)
    for _ in range(50):
        spec = ScanSpec(0.05, float(rng.uniform(1.0, 10.0)), -float(rng.uniform(0.1, 3.1)),
                        float(rng.uniform(0.1, 3.1)), float(rng.uniform(0.01, 0.3)), 10.0, 0.0)
        yaw = float(rng.uniform(-20.0, 20.0))
        ox, oy = (float(v) for v in rng.uniform(-3.0, 3.0, 2))
        c, s, w = (int(v) for v in rng.integers(0, 12, 3))
        centers, radii = rng.uniform(-6.0, 6.0, (c, 2)), rng.uniform(0.05, 1.5, c)
        seg_a, seg_b = rng.uniform(-6.0, 6.0, (s, 2)), rng.uniform(-6.0, 6.0, (s, 2))
        hp_n = rng.standard_normal((w, 2))
        hp_n /= np.hypot(hp_n[:, 0], hp_n[:, 1])[:, None]
        hp_c = rng.uniform(-8.0, 0.0, w)
        ux, uy = beam_directions(yaw, spec)
        want = ray_cast(ox, oy, ux, uy, centers, radii, seg_a, seg_b, hp_n, hp_c, spec.range_max)
        got, hits = cast_beams(yaw, spec.angles(), ox, oy, centers, radii, seg_a, seg_b, hp_n,
                               hp_c, spec.range_max)
        assert bits(got) == bits(want) and hits == finite_count(want)
