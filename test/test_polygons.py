"""Polyline walls and polygon obstacles (issue 13) against closed-form motions, and their
validation."""
import math

import numpy as np
import pytest

import sweep_core as sc
from sweep_core.errors import SceneError

R = 0.25
BOX = [[0, 0], [4, 0], [4, 2], [0, 2]]


def slide(dt: float, t_end: float, points: list = BOX) -> np.ndarray:
    """One disk on the top edge of a polygon pushed with U = (1, -1), no noise."""
    scene = sc.Scene.from_dict({"agents": {"positions": [[1.0, 2.0 + R]], "radius": R},
                                "obstacles": [{"kind": "polygon", "points": points}],
                                "drift": {"kind": "uniform", "velocity": [1.0, -1.0]}})
    sim = sc.Simulator(scene, dt=dt, seed=0)
    sim.step(int(round(t_end / dt)))
    return sim.positions[0]


def corner_exact(t: float) -> np.ndarray:
    """Closed form past the corner (4, 2): the disk slides along the top edge at speed 1
    until t = 3, then its centre follows the circle of radius R about the corner,
    theta' = -(sin theta + cos theta) / R from theta = 90 to 45 degrees (where U stops
    pointing into the obstacle), which takes R / sqrt(2) ln tan(3 pi / 8); then it moves
    freely with U."""
    t_arc = R / math.sqrt(2.0) * math.log(math.tan(3.0 * math.pi / 8.0))
    leave = np.array([4.0, 2.0]) + R * np.array([math.cos(math.pi / 4), math.sin(math.pi / 4)])
    return leave + (t - 3.0 - t_arc) * np.array([1.0, -1.0])


def test_sliding_along_an_edge_is_exact() -> None:
    # a flat edge: the projected Euler step is the exact solution x = 1 + t, y = 2 + R
    q = slide(1e-2, 2.0)
    assert abs(q[0] - 3.0) < 1e-9 and abs(q[1] - (2.0 + R)) < 1e-9


@pytest.mark.parametrize("points", [BOX, BOX[::-1]], ids=["ccw", "cw"])
def test_round_a_corner_first_order(points: list) -> None:
    # the catching-up scheme is first order on a smooth (here: rounded by R) boundary:
    # the error at t = 4 shrinks tenfold with dt, and is below |U| dt
    errors = [float(np.hypot(*(slide(dt, 4.0, points) - corner_exact(4.0)))) for dt in (1e-3, 1e-4)]
    assert errors[0] < math.sqrt(2.0) * 1e-3
    assert 7.0 < errors[0] / errors[1] < 14.0


def test_non_convex_polygon_keeps_agents_out() -> None:
    # an L-shaped obstacle and a noisy crowd pushed into its notch: never inside, never closer
    # than r to an edge (the post-step check would raise), gaps >= -1e-9 m
    ell = [[0, 0], [3, 0], [3, 1], [1, 1], [1, 3], [0, 3]]
    rng = np.random.default_rng(0)
    pos = np.array([[1.6 + 0.55 * i, 1.6 + 0.55 * j] for i in range(4) for j in range(4)])
    pos += rng.uniform(-0.02, 0.02, pos.shape)
    scene = sc.Scene.from_dict({"agents": {"positions": pos.tolist(), "radius": 0.2},
                                "obstacles": [{"kind": "polygon", "points": ell}],
                                "drift": {"kind": "goal", "goal": [0.5, 0.5], "speed": 1.0},
                                "noise": {"sigma": 0.1}})
    sim = sc.Simulator(scene, dt=0.01, seed=3)
    for _ in range(300):
        sim.step()
        gaps = sc.model.gaps.gaps(scene.geometry, sim.t, sim.positions, scene.radii(sim.t))
        assert gaps.min_gap >= -1e-9
    # they reached the notch: an agent sits in its corner, touching both inner edges (centre
    # near (1.2, 1.2), 0.2 sqrt 2 from the reflex vertex)
    corner = np.array([1.0, 1.0])
    assert np.min(np.hypot(*(sim.positions - corner).T)) < 0.2 * math.sqrt(2.0) + 0.01


def test_room_outline_corner_is_exact() -> None:
    room = {"kind": "polyline", "points": [[0, 0], [5, 0], [5, 4], [0, 4]], "closed": True}
    scene = sc.Scene.from_dict({"agents": {"positions": [[2.5, 2.0]], "radius": R},
                                "walls": [room],
                                "drift": {"kind": "uniform", "velocity": [1.0, 1.0]}})
    sim = sc.Simulator(scene, dt=0.01, seed=0)
    sim.step(500)
    assert np.allclose(sim.positions[0], [5.0 - R, 4.0 - R], atol=1e-9)


def test_open_polyline_agent_goes_round_its_end() -> None:
    # an open chain: nothing closes it, so an agent walks round its free end
    chain = {"kind": "polyline", "points": [[0, 1], [2, 1], [2, 3]]}
    scene = sc.Scene.from_dict({"agents": {"positions": [[1.0, 0.5]], "radius": R},
                                "walls": [chain],
                                "drift": {"kind": "uniform", "velocity": [0.0, 1.0]}})
    sim = sc.Simulator(scene, dt=0.01, seed=0)
    sim.step(100)
    assert abs(sim.positions[0, 1] - (1.0 - R)) < 1e-9   # held below the first piece


@pytest.mark.parametrize("obstacle, field, words", [
    ({"kind": "polygon", "points": [[0, 0], [1, 1], [1, 0], [0, 1]]}, "obstacles[0].points",
     "cross"),
    ({"kind": "polygon", "points": [[0, 0], [1, 0]]}, "obstacles[0].points", "at least 3"),
    ({"kind": "polygon", "points": [[0, 0], [1, 0], [1, 0], [0, 1]]}, "obstacles[0].points",
     "coincide"),
    ({"kind": "polygon"}, "obstacles[0]", "points"),
])
def test_bad_polygons_are_refused(obstacle: dict, field: str, words: str) -> None:
    with pytest.raises(SceneError) as err:
        sc.Scene.from_dict({"agents": {"positions": [[5, 5]], "radius": 0.2},
                            "obstacles": [obstacle]})
    assert err.value.field.startswith(field) and words in str(err.value) and err.value.fix


def test_agent_inside_a_polygon_is_refused() -> None:
    with pytest.raises(SceneError) as err:
        sc.Scene.from_dict({"agents": {"positions": [[2, 1]], "radius": 0.2},
                            "obstacles": [{"kind": "polygon", "points": BOX}]})
    assert "obstacles[0] (polygon edge" in str(err.value)


def test_polyline_round_trips_and_closed_must_be_boolean() -> None:
    spec = {"agents": {"positions": [[2, 1]], "radius": 0.2},
            "walls": [{"kind": "polyline", "points": [[0, 0], [3, 0], [3, 3], [0, 0]],
                       "closed": True}]}
    scene = sc.Scene.from_dict(spec)
    # the repeated closing point is dropped, the outline has three edges
    assert len(scene.geometry.segment_a) == 3
    again = sc.Scene.from_dict(scene.spec)
    assert np.array_equal(again.geometry.segment_a, scene.geometry.segment_a)
    spec["walls"][0]["closed"] = "yes"
    with pytest.raises(SceneError, match="closed"):
        sc.Scene.from_dict(spec)


def test_disk_pushed_by_a_moving_polygon() -> None:
    # a square moving right at 0.5 m/s meets a disk at rest 1 m ahead: from t = 2 s the
    # disk's centre is exactly R ahead of the square's front face, x = 3 + 0.5 t + R
    square = {"kind": "polygon", "points": [[0, 0], [2, 0], [2, 2], [0, 2]],
              "velocity": [0.5, 0.0]}
    scene = sc.Scene.from_dict({"agents": {"positions": [[3.0 + R, 1.0]], "radius": R},
                                "obstacles": [square]})
    sim = sc.Simulator(scene, dt=0.01, seed=0)
    sim.step(100)
    assert np.allclose(sim.positions[0], [3.0 + R, 1.0], atol=1e-12)  # not reached yet
    sim.step(300)
    assert np.allclose(sim.positions[0], [2.0 + 0.5 * 4.0 + R, 1.0], atol=1e-9)


def test_rotating_bar_sweeps_agents_aside() -> None:
    # a bar rotating about its middle at 1 rad/s among resting agents: they are pushed, never
    # overlapped, and the markers follow the bar
    bar = {"kind": "polygon", "points": [[-2, -0.1], [2, -0.1], [2, 0.1], [-2, 0.1]],
           "angular_velocity": 1.0}
    pos = [[0.0, 1.0], [1.0, 1.2], [-1.5, -0.8], [0.8, -1.5]]
    scene = sc.Scene.from_dict({"agents": {"positions": pos, "radius": 0.2},
                                "obstacles": [bar]})
    assert scene.spec["obstacles"][0]["pivot"] == [0.0, 0.0]
    sim = sc.Simulator(scene, dt=0.005, seed=0)
    for _ in range(400):
        sim.step()
        g = sc.model.gaps.gaps(scene.geometry, sim.t, sim.positions, scene.radii(sim.t))
        assert g.min_gap >= -1e-9
    moved = np.hypot(*(sim.positions - np.array(pos)).T)
    assert moved.min() > 0.1
    a = scene.geometry.at(np.pi / 2).segment_a[0]
    assert np.allclose(a, [0.1, -2.0], atol=1e-12)


def test_moving_circle_into_a_pinned_agent_is_refused_with_time_and_agent() -> None:
    wall = {"kind": "halfplane", "normal": [-1, 0], "offset": -5.0}
    ball = {"kind": "circle", "center": [2, 0], "radius": 1.0, "velocity": [1.0, 0.0]}
    scene = sc.Scene.from_dict({"agents": {"positions": [[4.7, 0.0]], "radius": 0.25},
                                "walls": [wall], "obstacles": [ball]})
    sim = sc.Simulator(scene, dt=0.01, seed=0)
    with pytest.raises(sc.InfeasibleError) as err:
        sim.step(300)
    assert "0" in str(err.value) and 1.4 < err.value.t < 1.6


def test_collinear_vertices_are_accepted_and_true_crossings_refused() -> None:
    """Extra vertices on one side of a room (collinear edges) were refused as crossing edges;
    crossing, touching and folded-back outlines are still refused, decided exactly."""
    from sweep_core.model.outlines import chain_points

    room = [[0, 0], [3, 0], [6, 0], [10, 0], [10, 10], [0, 10]]
    scene = sc.Scene.from_dict({"agents": {"positions": [[5, 5]], "radius": 0.2},
                                "walls": [{"kind": "polyline", "points": room, "closed": True}],
                                "obstacles": [{"kind": "polygon",
                                               "points": [[1, 1], [2, 1], [3, 1], [3, 2]]}]})
    assert len(scene.spec["walls"][0]["points"]) == 6
    for bad, words in [([[0, 0], [4, 0], [0, 3], [4, 3]], "edges 1 and 3 cross or touch"),
                       ([[0, 0], [4, 0], [4, 4], [2, 0], [0, 4]], "edges 0 and 2 cross or touch"),
                       ([[0, 0], [3, 0], [1, 0], [1, 5]], "edges 0 and 1 fold back"),
                       ([[0, 0], [6, 0], [6, 2], [3, 0.0], [0, 2]], "cross or touch")]:
        with pytest.raises(SceneError, match=words):
            chain_points(bad, "walls[0].points", True, 3)


def test_orientation_is_exact_where_the_float_determinant_is_not() -> None:
    """Points on the line y = x at coordinates whose float products round: the sign is the
    exact one (0 on the line, +-1 one ulp off it), as rational arithmetic gives."""
    from fractions import Fraction

    from sweep_core.model.outlines import orientation

    rng = np.random.default_rng(3)
    p = rng.uniform(-100, 100, (2000, 2))
    q = rng.uniform(-100, 100, (2000, 2))
    t = rng.uniform(-2, 3, (2000, 1))
    r = p + t * (q - p)  # near the line pq, off it by rounding
    r[::3] = np.nextafter(r[::3], np.inf)
    got = orientation(p, q, r)

    def exact(p, q, r):
        (px, py), (qx, qy), (rx, ry) = ([Fraction(x) for x in v] for v in (p, q, r))
        d = (qx - px) * (ry - py) - (qy - py) * (rx - px)
        return (d > 0) - (d < 0)

    want = np.array([exact(*v) for v in zip(p.tolist(), q.tolist(), r.tolist())])
    naive = np.sign((q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1])
                    - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0]))
    assert np.any(naive != want)  # the float determinant alone gets some wrong
    assert np.array_equal(got, want)
