"""The projection: cutoff, clusters and closed forms against one reference QP over every row."""
from __future__ import annotations

import numpy as np
import pytest

import sweep_core as sc
from sweep_core import projection
from sweep_core.constraints import linearise


def random_crowd(rng: np.random.Generator, n: int, box: float, r: float) -> np.ndarray:
    pos: list[np.ndarray] = []
    while len(pos) < n:
        p = rng.uniform(r, box - r, 2)
        if all(np.hypot(*(p - o)) >= 2 * r for o in pos):
            pos.append(p)
    return np.array(pos)


def reference(scene: sc.Scene, t1: float, q: np.ndarray, pred: np.ndarray) -> np.ndarray:
    """Projection onto C~ with every pair and wall row built (no cutoff), solved exactly."""
    rows = linearise(scene.geometry, t1, q, scene.radii(t1), np.inf)
    n = len(q)
    c, b = projection._row_matrix(rows, np.arange(n), n)
    x, _, ok = projection._ldp(pred.ravel(), c.toarray(), b)
    assert ok
    return x.reshape(-1, 2)


@pytest.mark.parametrize("backend", ["clarabel", "proxsuite"])
@pytest.mark.parametrize("seed", range(6))
def test_projection_matches_reference_on_random_crowds(seed, backend):
    rng = np.random.default_rng(seed)
    r = 0.2
    q = random_crowd(rng, 25, 3.0, r)
    scene = sc.Scene.from_dict({
        "agents": {"positions": q.tolist(), "radius": r},
        "walls": [{"kind": "halfplane", "normal": [1, 0], "offset": 0.0},
                  {"kind": "segment", "a": [3.0, -1.0], "b": [3.0, 4.0]}]})
    pred = q + rng.normal(0.0, 0.15, q.shape)
    opts = sc.SolverOptions(backend=backend)
    got = projection.project(scene.geometry, 0.01, q, pred, scene.radii(0.01), opts)
    want = reference(scene, 0.01, q, pred)
    assert np.max(np.abs(got.y - want)) < 1e-8
    assert got.qp_size > 0  # something was projected


def test_far_pairs_are_never_built():
    rng = np.random.default_rng(1)
    q = random_crowd(rng, 40, 20.0, 0.2)
    scene = sc.Scene.from_dict({"agents": {"positions": q.tolist(), "radius": 0.2}})
    rows = linearise(scene.geometry, 0.0, q, scene.radii(0.0), 0.05)
    d = np.hypot(*(q[rows.pair_i] - q[rows.pair_j]).T) - 0.4
    assert np.all(d <= 0.05)
    assert len(rows.single_b) == 0  # no walls, no wall rows
