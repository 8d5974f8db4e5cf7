"""The compiled cell list finds exactly the pairs a brute-force O(N^2) search finds."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sweep_core.model.neighbours import SizedSearch, pairs_within


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


def test_segments_within_matches_brute_force() -> None:
    from sweep_core.model.neighbours import segments_within

    rng = np.random.default_rng(5)
    q = rng.uniform(-5, 5, (400, 2))
    a = rng.uniform(-7, 7, (150, 2))
    # long axis-aligned walls, short diagonal pieces, one far away, one of length ~0
    b = a + np.where(rng.random((150, 1)) < 0.5, [[6.0, 0.0]], rng.normal(0, 0.7, (150, 2)))
    a[0], b[0] = [100.0, 100.0], [120.0, 100.0]
    b[1] = a[1] + 1e-9
    for reach in (0.05, 0.3, 2.0):
        got_a, got_s = segments_within(q, a, b, reach)
        ab = b - a
        rel = q[:, None, :] - a[None]
        s = np.clip(np.einsum("nkc,kc->nk", rel, ab) / np.einsum("kc,kc->k", ab, ab), 0, 1)
        dist = np.hypot(*(rel - s[..., None] * ab[None]).transpose(2, 0, 1))
        want = set(zip(*np.nonzero(dist <= reach)))
        got = set(zip(got_a.tolist(), got_s.tolist()))
        assert got == want and len(got_a) == len(got)


def test_indexed_rows_equal_dense_rows() -> None:
    # a map-like scene with many segments: the indexed search builds the rows the dense
    # evaluation builds (same agents, items, values)
    import sweep_core as sc
    from sweep_core.model import geometry

    xs = np.arange(0.0, 30.0, 0.5)
    walls = [{"kind": "segment", "a": [x, 0.0], "b": [x + 0.5, 0.0]} for x in xs]
    walls += [{"kind": "segment", "a": [x, 3.0], "b": [x + 0.5, 3.0]} for x in xs]
    gx, gy = np.meshgrid(np.arange(0.5, 29.5, 0.45), np.arange(0.15, 2.9, 0.45))
    pos = np.stack([gx.ravel(), gy.ravel()], axis=1)
    pos = pos[(np.abs(pos[:, 0] - 10.5) > 1.0) | (np.abs(pos[:, 1] - 1.5) > 1.0)]
    scene = sc.Scene.from_dict({"agents": {"positions": pos.tolist(), "radius": 0.1},
                                "walls": walls,
                                "obstacles": [{"kind": "polygon",
                                               "points": [[10, 1], [11, 1], [11, 2]]}]})
    g = scene.geometry
    r = scene.radii(0.0)
    assert len(pos) * len(g.segment_a) > geometry.DENSE_SEGMENTS
    # and one centre inside the polygon (an infeasible state): its rows with every edge of
    # the polygon, negative, once each, as the dense evaluation has them
    pos = np.vstack([pos, [10.8, 1.3]])
    r = np.append(r, 0.1)
    for reach in (0.05, 0.4):
        fast = geometry.single_rows(g, 0.0, pos, r, reach)[geometry.SEGMENT]
        dense = [v for v in geometry.single_values(g, 0.0, pos, r)[geometry.SEGMENT]]
        a, k = np.nonzero(dense[0] <= reach)
        order = np.lexsort((fast[1], fast[0]))
        assert np.array_equal(fast[0][order], a) and np.array_equal(fast[1][order], k)
        assert np.allclose(fast[2][order], dense[0][a, k], rtol=0, atol=1e-12)


def test_room_made_first_does_not_change_the_pairs() -> None:
    """A search started with room for more or fewer pairs than it finds returns the same
    pairs in the same order; a SizedSearch keeps the last count and a quarter more."""
    rng = np.random.default_rng(5)
    q = rng.uniform(0, 6, (300, 2))
    want = pairs_within(q, 1.5)
    assert len(want[0]) > 4 * len(q)  # more than the room a search starts with
    for expect in (0, 10, len(want[0]) - 1, len(want[0]), 10 * len(want[0])):
        got = pairs_within(q, 1.5, expect)
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
    search = SizedSearch()
    for reach in (1.5, 0.4, 1.5):
        got = search(q, reach)
        ref = pairs_within(q, reach)
        assert np.array_equal(got[0], ref[0]) and np.array_equal(got[1], ref[1])
        assert search.expect == len(ref[0]) + len(ref[0]) // 4
