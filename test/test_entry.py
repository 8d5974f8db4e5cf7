"""A source's room check (:mod:`sweep_core.numerics.entry`): the cell grid gives the same verdict
as the dense check over every disk, |c - x_j|^2 >= (rc + r_j)^2, candidate by candidate,
including disks that touch a candidate exactly and disks added after the grid was built."""
from __future__ import annotations

import numpy as np
import pytest

from sweep_core.numerics.entry import EntryGrid


def dense(cand: np.ndarray, rc: float, xs: np.ndarray, rs: np.ndarray) -> np.ndarray:
    d = cand[:, None, :] - xs[None]
    dist2 = np.einsum("mnc,mnc->mn", d, d)
    return np.all(dist2 >= (rc + rs[None]) ** 2, axis=1)


@pytest.mark.parametrize("seed", range(6))
def test_the_grid_agrees_with_the_dense_check(seed):
    rng = np.random.default_rng(seed)
    lo, hi = np.array([2.0, 1.0]), np.array([2.0, 1.0]) + rng.uniform(0.5, 12.0, 2)
    n = int(rng.integers(0, 400))
    xs = rng.uniform(lo - 2.0, hi + 2.0, (n, 2))  # some outside the reach of the region
    rs = rng.uniform(0.15, 0.3, n)
    rc = float(rng.uniform(0.15, 0.3))
    grid = EntryGrid(lo, hi, rc + 0.3, xs, rs)
    cand = lo + rng.random((64, 2)) * (hi - lo)  # drawn in the region's box, as a source does
    # candidates exactly touching a disk (at rc + r_j along an axis), halfway, at its centre
    inside = np.flatnonzero(np.all((xs > lo + 0.6) & (xs < hi - 0.6), axis=1))
    if len(inside):
        j = inside[0]
        cand[:4] = xs[j] + np.array([[1.0, 0.0], [-1.0, 0.0], [0.5, 0.0], [0.0, 0.0]]) * (
            rc + rs[j])
    assert np.all((cand >= lo) & (cand <= hi))
    assert np.array_equal(grid.clear(cand, rc), dense(cand, rc, xs, rs))
    # disks placed after the grid was built (more than its first capacity)
    more = lo + rng.random((40, 2)) * (hi - lo)
    for p in more:
        grid.add(p, rc)
    all_x = np.concatenate([xs, more])
    all_r = np.concatenate([rs, np.full(len(more), rc)])
    assert np.array_equal(grid.clear(cand, rc), dense(cand, rc, all_x, all_r))


def test_a_region_too_large_for_fine_cells_still_agrees():
    """A 20 km region: the grid takes wider cells (at most MAX_CELLS) and stays exact."""
    rng = np.random.default_rng(7)
    lo, hi = np.zeros(2), np.array([2e4, 2e4])
    xs = rng.uniform(0.0, 2e4, (500, 2))
    xs[250:] = xs[:250] + rng.uniform(-0.5, 0.5, (250, 2))  # close pairs
    rs = np.full(500, 0.25)
    grid = EntryGrid(lo, hi, 0.5, xs, rs)
    assert grid.nx * grid.ny <= 1 << 20
    cand = np.concatenate([xs[:100] + rng.uniform(-0.6, 0.6, (100, 2)),
                           rng.uniform(0.0, 2e4, (100, 2))])
    assert np.array_equal(grid.clear(cand, 0.25), dense(cand, 0.25, xs, rs))
