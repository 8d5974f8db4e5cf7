"""The compiled wall rows and crossing test give exactly what the numpy forms give: the rows'
bits equal :func:`single_values`' (half-planes, segments, polyline pieces, polygon edges with
an agent inside, circles), and the path test equals the exact
:func:`segments_meet` on random, touching and collinear pairs."""
from __future__ import annotations

import numpy as np
import pytest

from sweep_core.model.geometry import single_rows, single_values
from sweep_core.model.outlines import segments_meet
from sweep_core.model.scene import Scene
from sweep_core.model.wall_kernels import paths_meet, paths_meet_exactly


def _scene() -> Scene:
    return Scene.from_dict({
        "agents": {"positions": [[1.0, 1.0]], "radius": 0.2},
        "walls": [{"kind": "halfplane", "normal": [0.0, 1.0], "offset": -1.0},
                  {"kind": "segment", "a": [-3.0, 5.0], "b": [4.0, 6.0]},
                  {"kind": "polyline", "points": [[6, -2], [7, 3], [9, 4]]}],
        "obstacles": [{"kind": "circle", "center": [2.0, 3.0], "radius": 0.7},
                      {"kind": "polygon", "points": [[-4, -0.5], [-2, -0.5], [-3, 1.5]]}]})


def _reference(geom, t, q, r, reach):  # the numpy form: single_values filtered
    out = []
    for g, nrm, foot in single_values(geom, t, q, r):
        a, k = np.nonzero(g <= reach)
        out.append((a, k, g[a, k], nrm[a, k], foot[a, k]))
    return out


@pytest.mark.parametrize("reach", [0.0, 0.5, 3.0, 1e3])
def test_rows_are_the_numpy_forms_bits(reach: float) -> None:
    geom = _scene().geometry
    rng = np.random.default_rng(1)
    q = rng.uniform(-5.0, 10.0, (300, 2))
    q[:4] = [[-3.0, 0.0], [-3.1, 0.2], [2.0, 3.0], [6.0, -2.0]]  # inside, centre, on a vertex
    r = rng.uniform(0.1, 0.3, 300)
    got, want = single_rows(geom, 0.7, q, r, reach), _reference(geom, 0.7, q, r, reach)
    assert len(got) == len(want) == 4
    assert sum(len(w[0]) for w in want) > 0
    for g_kind, w_kind in zip(got, want):
        for g, w in zip(g_kind, w_kind):
            assert g.shape == w.shape
            assert np.array_equal(g.view(np.uint8) if g.dtype.kind == "f" else g,
                                  w.view(np.uint8) if w.dtype.kind == "f" else w)


def test_an_agent_inside_the_polygon_has_negative_values() -> None:
    geom = _scene().geometry
    q, r = np.array([[-3.0, 0.0]]), np.array([0.2])
    a, k, g, _, _ = single_rows(geom, 0.0, q, r, 0.0)[1]
    assert len(g) == 3 and (g < 0).all()  # the triangle's three edges


def _meet(p0, p1, a, b):
    hit, unsure = np.empty(len(p0), dtype=bool), np.empty(len(p0), dtype=bool)
    paths_meet(p0, p1, a, b, hit, unsure)
    return hit, unsure


def test_paths_meet_is_segments_meet() -> None:
    rng = np.random.default_rng(2)
    p0, p1, a, b = (rng.uniform(-1, 1, (4000, 2)) for _ in range(4))
    # touching at an end, collinear overlapping, collinear apart, on the line of a segment
    p0[:4] = [[0, 0], [0, 0], [0, 0], [0.5, 0.5]]
    p1[:4] = [[1, 1], [2, 0], [1, 0], [0.5, 2.0]]
    a[:4] = [[1, 1], [1, 0], [2, 0], [0, 0]]
    b[:4] = [[3, 0], [3, 0], [3, 0], [1, 1]]
    # nearly collinear: the float determinant is not to be trusted there
    p0[4], p1[4], a[4], b[4] = [0.1, 0.1], [0.3, 0.3], [0.2, 0.2 + 1e-17], [0.5, 0.5]
    hit, unsure = _meet(p0, p1, a, b)
    exact = segments_meet(p0, p1, a, b)
    assert np.array_equal(hit[~unsure], exact[~unsure])
    decided = paths_meet_exactly(p0, p1, a, b)
    assert np.array_equal(decided, exact)
    assert decided[:4].tolist() == [True, True, False, True]
    assert unsure[[0, 1, 3, 4]].all()  # zero determinants: the filter vouches for none
    assert not unsure[2]  # collinear but the boxes are apart: decided by the boxes
    assert exact[4]  # (0.2, 0.2 + 1e-17) rounds onto the path's line
    assert 0 < hit.sum() < len(hit) and unsure.sum() < 10


@pytest.mark.parametrize("spread", [1.0, 8.0, 40.0])
def test_gaps_from_every_value_equal_the_doubling_search(monkeypatch: pytest.MonkeyPatch,
                                                         spread: float) -> None:
    """gaps() takes every value at once for a few segments; the search that doubles its reach
    (the path of many segments, forced here) finds the same minimum, contacts and near pairs."""
    from sweep_core.model import gaps as summary

    geom = _scene().geometry
    rng = np.random.default_rng(3)
    q = rng.uniform(-spread, spread, (60, 2))
    r = np.full(60, 0.2)
    fast = summary.gaps(geom, 0.0, q, r)
    monkeypatch.setattr(summary, "DENSE_SEGMENTS", -1)
    slow = summary.gaps(geom, 0.0, q, r)
    assert (fast.min_single, fast.contacts, fast.worst_single, fast.reach) == \
        (slow.min_single, slow.contacts, slow.worst_single, slow.reach)
    assert sorted(zip(fast.near_agent.tolist(), fast.near_segment.tolist())) == \
        sorted(zip(slow.near_agent.tolist(), slow.near_segment.tolist()))
    assert len(fast.near_agent) > 0 or spread != 8.0  # a crowd among the segments


def test_gaps_pairs_are_the_numpy_forms_bits() -> None:
    """The compiled pair gaps of gaps() hold the numpy form's bits, its contacts and its
    first smallest pair; agents touching and overlapping included."""
    from sweep_core.model.gaps import gaps

    rng = np.random.default_rng(4)
    q = rng.uniform(0.0, 6.0, (200, 2))
    q[1] = q[0] + [0.4, 0.0]  # touching (radii 0.2)
    q[3] = q[2] + [0.1, 0.3]  # overlapping
    r = np.full(200, 0.2)
    got = gaps(_scene().geometry, 0.0, q, r, contact_tol=1e-6)
    d = q[got.pair_i] - q[got.pair_j]
    want = np.sqrt(np.einsum("ij,ij->i", d, d)) - r[got.pair_i] - r[got.pair_j]
    assert len(want) > 10
    assert np.array_equal(got.pair_gap.view(np.uint8), want.view(np.uint8))
    w = int(np.argmin(want))
    assert got.worst_pair == (int(got.pair_i[w]), int(got.pair_j[w]), float(want[w]))
    assert got.min_pair == float(want.min()) < 0
    singles = sum(int(np.count_nonzero(g <= 1e-6)) for g, _, _ in
                  single_values(_scene().geometry, 0.0, q, r)[:3])
    assert got.contacts == int(np.count_nonzero(want <= 1e-6)) + singles


def _fields(g) -> tuple:
    arrays = tuple(np.asarray(a).view(np.uint8).tobytes() for a in
                   (g.pair_i, g.pair_j, g.pair_gap, g.near_agent, g.near_segment))
    return (g.min_pair, g.min_single, g.contacts, g.worst_pair, g.worst_single, g.reach) + arrays


@pytest.mark.parametrize("case", ["walls", "no walls", "touching", "packed", "nan", "two"])
def test_small_crowds_gaps_in_one_call_are_the_passes_one_by_one(
        monkeypatch: pytest.MonkeyPatch, case: str) -> None:
    """gaps() of at most SMALL agents (one compiled call: the neighbour search, the pairs' and
    the walls' passes) gives every field, bit for bit, that the passes called one by one
    give; crowds with more pairs than the call has room for, and NaN, included."""
    from sweep_core.model import gaps as summary

    geom = _scene().geometry
    rng = np.random.default_rng(11)
    n = {"two": 2, "packed": 30}.get(case, summary.SMALL)
    q = rng.uniform(-4.0, 9.0, (n, 2))
    r = rng.uniform(0.15, 0.3, n)
    if case == "no walls":
        geom = Scene.from_dict({"agents": {"positions": [[0.0, 0.0]], "radius": 0.2}}).geometry
    if case == "touching":
        q[1] = q[0] + [r[0] + r[1], 0.0]  # touching, overlapping, on a segment
        q[3] = q[2] + [0.1, 0.2]
        q[4] = [-3.0 + 7.0 * 0.3, 5.0 + 0.3 - r[4] / 2]
    if case == "packed":  # more pairs within reach than 4 N
        q = rng.uniform(0.0, 0.5, (n, 2))
    if case == "nan":
        q[5] = np.nan
    one_call = summary.gaps(geom, 0.0, q, r)
    monkeypatch.setattr(summary, "SMALL", 0)
    passes = summary.gaps(geom, 0.0, q, r)
    assert _fields(one_call) == _fields(passes)
    if case in ("walls", "touching"):
        assert one_call.worst_single is not None and len(one_call.pair_i) > 0


@pytest.mark.parametrize("with_near", [True, False])
def test_crossings_in_one_pass_are_the_searched_ones(monkeypatch: pytest.MonkeyPatch,
                                                     with_near: bool) -> None:
    """The compiled candidates-and-test pass of crossings() finds the pairs the spatial
    search (forced here) finds: paths through walls, a polygon's edges, a
    path ending on a wall, paths that stay put."""
    from sweep_core.model import crossing
    from sweep_core.model.gaps import gaps

    geom = _scene().geometry
    rng = np.random.default_rng(5)
    q0 = rng.uniform(-5.0, 10.0, (400, 2))
    q1 = q0 + rng.normal(0.0, 1.5, (400, 2))
    q1[:3] = q0[:3]  # did not move
    q0[3], q1[3] = [-3.0, 4.0], [-3.0, 6.0]  # through the segment wall
    q0[4], q1[4] = [0.5, 4.5], [0.5, 5.5]  # ends on it
    r = np.full(400, 0.2)
    near = gaps(geom, 0.0, q1, r) if with_near else None
    fast = crossing.crossings(geom, q0, q1, r, near)
    monkeypatch.setattr(crossing, "DENSE_PAIRS", -1)
    slow = crossing.crossings(geom, q0, q1, r, near)
    assert sorted(zip(*(v.tolist() for v in fast))) == sorted(zip(*(v.tolist() for v in slow)))
    assert 3 in fast[0].tolist() and 4 in fast[0].tolist() and len(fast[0]) > 10
    assert not {0, 1, 2} & set(fast[0].tolist())


@pytest.mark.parametrize("cut", [0.0, 0.3, 2.0])
def test_linearised_rows_in_one_pass_are_the_numpy_forms(monkeypatch: pytest.MonkeyPatch,
                                                         cut: float) -> None:
    """linearise()'s compiled pair rows and single rows hold the bits, order and kinds of the
    rows built through single_rows and numpy (the path of many segments, forced here)."""
    from sweep_core.numerics import constraints

    geom = _scene().geometry
    rng = np.random.default_rng(7)
    q = rng.uniform(-5.0, 10.0, (300, 2))
    r = rng.uniform(0.1, 0.3, 300)
    fast = constraints.linearise(geom, 0.4, q, r, cut)
    monkeypatch.setattr(constraints, "DENSE_SEGMENTS", -1)
    slow = constraints.linearise(geom, 0.4, q, r, cut)
    d = q[slow.pair_i] - q[slow.pair_j]
    dist = np.sqrt(np.einsum("ij,ij->i", d, d))
    assert np.array_equal(slow.pair_e, d / np.maximum(dist, 1e-300)[:, None])
    assert len(fast.pair_b) > 0 and len(fast.single_b) > 0
    assert set(fast.single_kind.tolist()) == {0, 1, 2}
    for name in ("pair_i", "pair_j", "pair_e", "pair_b", "single_a", "single_n", "single_b",
                 "single_kind", "single_item"):
        got, want = getattr(fast, name), getattr(slow, name)
        assert got.dtype == want.dtype and got.shape == want.shape, name
        assert np.array_equal(got.view(np.uint8), want.view(np.uint8)), name


def test_with_circles_is_replace_with_the_packed_arrays_carried() -> None:
    """Geometry.with_circles (the robots' disks, every step) gives the fields replace() gives
    and the packed arrays a fresh geometry packs."""
    import dataclasses

    from sweep_core.model.geometry import Geometry

    geom = _scene().geometry
    geom.packed  # noqa: B018 - packed before, as in a run
    centres, radii = np.array([[1.0, 2.0], [4.0, 0.5]]), np.array([0.3, 0.25])
    got = geom.with_circles(centres, radii)
    want = dataclasses.replace(
        geom, circle_center=np.concatenate([geom.circle_center, centres]),
        circle_radius=np.concatenate([geom.circle_radius, radii]),
        circle_index=np.concatenate([geom.circle_index, [-1, -1]]),
        circle_motion=np.concatenate([geom.circle_motion, [-1, -1]]))
    for f in dataclasses.fields(Geometry):
        a, b = getattr(got, f.name), getattr(want, f.name)
        if isinstance(a, np.ndarray):
            assert a.dtype == b.dtype and np.array_equal(a, b), f.name
        else:
            assert a == b, f.name
    for a, b in zip(got.packed, want.packed):
        assert np.array_equal(a, b)
    assert len(got.circle_radius) == len(geom.circle_radius) + 2
    # the index and motion columns kept per count of added disks: another count, then again
    for m in (1, 2, 1):
        more = geom.with_circles(centres[:m], radii[:m])
        assert np.array_equal(more.circle_index, np.concatenate([geom.circle_index, [-1] * m]))
        assert np.array_equal(more.circle_motion,
                              np.concatenate([geom.circle_motion, [-1] * m]))
        assert np.array_equal(more.circle_center, np.concatenate([geom.circle_center,
                                                                  centres[:m]]))


def test_row_residuals_have_the_bits_of_the_numpy_form() -> None:
    """Rows.residuals (compiled) gives, bit for bit, <e, y_i - y_j> - b and <n, y_a> - b as
    numpy's einsum writes them, on random rows at scales from 1e-2 to 1e3 m."""
    from sweep_core.numerics.constraints import Rows

    rng = np.random.default_rng(11)
    for _ in range(300):
        n, p, m = int(rng.integers(1, 40)), int(rng.integers(0, 50)), int(rng.integers(0, 30))
        y = rng.normal(size=(n, 2)) * 10.0 ** rng.uniform(-2, 3)
        e = rng.normal(size=(p, 2))
        e /= np.linalg.norm(e, axis=1)[:, None]
        rows = Rows(rng.integers(0, n, p), rng.integers(0, n, p), e, rng.normal(size=p),
                    rng.integers(0, n, m), rng.normal(size=(m, 2)), rng.normal(size=m),
                    np.zeros(m, np.int8), np.zeros(m, np.intp))
        rp, rs = rows.residuals(y)
        want_p = np.einsum("ij,ij->i", rows.pair_e, y[rows.pair_i] - y[rows.pair_j]) \
            - rows.pair_b
        want_s = np.einsum("ij,ij->i", rows.single_n, y[rows.single_a]) - rows.single_b
        assert rp.tobytes() == want_p.tobytes() and rs.tobytes() == want_s.tobytes()


def test_beam_directions_are_elementary_cos_and_sin_per_beam() -> None:
    """A scan's beam directions (compiled) are elementary.cos and elementary.sin of yaw + each
    beam's angle, bit for bit."""
    import math

    from sweep_core.model import elementary
    from sweep_core.model.robots import ScanSpec
    from sweep_core.numerics.robots.scan import beam_directions

    spec = ScanSpec(0.05, 8.0, -2.0944, 2.0944, 0.0872665, 10.0, 0.01)
    rng = np.random.default_rng(2)
    for yaw in [0.0, -math.pi, math.pi, *rng.uniform(-10.0, 10.0, 200)]:
        ux, uy = beam_directions(float(yaw), spec)
        angles = (float(yaw) + spec.angles()).tolist()
        assert ux.tobytes() == np.array([elementary.cos(v) for v in angles]).tobytes()
        assert uy.tobytes() == np.array([elementary.sin(v) for v in angles]).tobytes()
