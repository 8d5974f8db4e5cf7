"""The compiled cell list finds exactly the pairs a brute-force O(N^2) search finds."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sweep_core.model.neighbours import pairs_within


def brute(q: np.ndarray, reach: float) -> set[tuple[int, int]]:
    d = np.hypot(*(q[:, None, :] - q[None, :, :]).transpose(2, 0, 1))
    i, j = np.nonzero(np.triu(d <= reach, k=1))
    return set(zip(i.tolist(), j.tolist()))


def found(q: np.ndarray, reach: float) -> set[tuple[int, int]]:
    i, j = pairs_within(q, reach)
    assert np.all(i < j)
    got = list(zip(i.tolist(), j.tolist()))
    assert len(got) == len(set(got)), "a pair reported twice"
    return set(got)


@pytest.mark.parametrize("n, box, reach", [(2, 1.0, 0.5), (300, 5.0, 0.5), (300, 5.0, 2.0),
                                           (500, 1e4, 0.5), (400, 10.0, 1e-3)])
def test_random_crowds_match_brute_force(n, box, reach):
    """Dense (grid path) and spread-out (sorted path) crowds."""
    q = np.random.default_rng(n).uniform(-box, box, (n, 2))
    assert found(q, reach) == brute(q, reach)


def test_boundary_distance_and_coincident_centres_are_pairs():
    q = np.array([[0.0, 0.0], [0.5, 0.0], [0.5, 0.0], [1.0, 0.5], [-3.0, 7.0]])
    assert found(q, 0.5) == brute(q, 0.5) == {(0, 1), (0, 2), (1, 2)}


def test_order_is_a_function_of_the_positions():
    q = np.random.default_rng(3).uniform(0, 20, (2000, 2))
    a, b = pairs_within(q, 0.7), pairs_within(q.copy(), 0.7)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(-50, 50), st.floats(-50, 50)), min_size=0, max_size=60),
       st.floats(0.01, 30.0))
def test_any_configuration(points, reach):
    q = np.array(points, dtype=float).reshape(-1, 2)
    assert found(q, reach) == (brute(q, reach) if len(q) else set())
