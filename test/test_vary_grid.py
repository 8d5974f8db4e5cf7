"""The grid of an ensemble's ``vary``: each value once, compared by value, and numpy's numbers
taken as the Python numbers they hold (``sweep_core.ensemble.run(vary=...)``)."""
from __future__ import annotations

import numpy as np
import pytest

from sweep_core.ensemble import grid
from sweep_core.errors import SceneError

SPEC = {"agents": {"positions": [[1.0, 1.0]], "radius": 0.2}, "noise": {"sigma": 0.05}}


@pytest.mark.parametrize("values", [[0, 0.0], [1, 1.0], [0.1, 1e-1]])
def test_a_value_given_twice_is_refused_by_value(values: list) -> None:
    """1 and 1.0 are one value of noise.sigma: two grid points would run the same runs twice
    (two points, two labels, the same results)."""
    with pytest.raises(SceneError) as err:
        grid.grid({"noise.sigma": values}, SPEC)
    assert str(err.value).startswith("--vary: noise.sigma: repeated value"), err.value


def test_the_command_lines_repeated_value_is_refused() -> None:
    with pytest.raises(SceneError, match="repeated value"):
        grid.grid(grid.parse_vary(["noise.sigma=0,0.0"]), SPEC)


@pytest.mark.parametrize("values", [np.array([0.05, 0.1]), [np.float32(0.5), np.float64(0.1)],
                                    [np.int64(0), np.int64(1)]])
def test_numpy_numbers_are_the_python_numbers_they_hold(values: object) -> None:
    points = grid.grid({"noise.sigma": values}, SPEC)
    want = [float(v) if isinstance(v, np.floating) else int(v) for v in values]
    assert [p["noise.sigma"] for p in points] == want
    assert all(type(p["noise.sigma"]) in (int, float) for p in points)
    # the same grid points (and ids, which name the runs' files) as the Python list's
    assert [grid.point_id(p) for p in points] == [grid.point_id(p) for p in
                                                  grid.grid({"noise.sigma": want}, SPEC)]
