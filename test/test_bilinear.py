"""The compiled bilinear interpolation of the navigation fields gives the numpy form's bits:
inside cells, on nodes, on the grid's edges and clamped outside it, for T (H, W) and e
(H, W, 2)."""
from __future__ import annotations

import numpy as np

from sweep_core.model.fields import grid_cell
from sweep_core.model.scene import Scene


def _numpy_form(x: np.ndarray, y: np.ndarray, v: np.ndarray, q: np.ndarray) -> np.ndarray:
    fx, ix = grid_cell(x, q[:, 0])
    fy, iy = grid_cell(y, q[:, 1])
    w = [((1 - fy) * (1 - fx)), ((1 - fy) * fx), (fy * (1 - fx)), (fy * fx)]
    if v.ndim == 3:
        w = [c[:, None] for c in w]
    return (w[0] * v[iy, ix] + w[1] * v[iy, ix + 1] + w[2] * v[iy + 1, ix]
            + w[3] * v[iy + 1, ix + 1])


def test_field_values_are_the_numpy_forms_bits() -> None:
    scene = Scene.from_dict({
        "agents": {"positions": [[1.0, 1.0]], "radius": 0.2},
        "walls": [{"kind": "segment", "a": [3.0, -1.0], "b": [3.0, 2.5]}],
        "drift": {"kind": "geodesic", "goal": [6.0, 1.0], "speed": 1.2}})
    field = scene.drift
    rng = np.random.default_rng(6)
    q = rng.uniform(-3.0, 10.0, (500, 2))  # some outside the grid: clamped
    q[:3] = [[field.x[4], field.y[7]], [field.x[0], field.y[-1]], [field.x[-1], 1.23]]
    for v in (field.distance, field.direction):
        got, want = field._at(v, q), _numpy_form(field.x, field.y, v, q)
        assert got.shape == want.shape and np.isfinite(want).all()
        assert np.array_equal(got.view(np.uint8), want.view(np.uint8))
    assert len(np.unique(field.travel_distance(q))) > 200
