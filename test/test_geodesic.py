"""Navigation fields (issue 15): geodesic drift around geometry, several exits."""
import math

import numpy as np
import pytest

import sweep_core as sc
from sweep_core.analysis import replay, run
from sweep_core.cli import main
from sweep_core.errors import SceneError
from sweep_core.model import geodesic
from sweep_core.model.geodesic import Exits, Geodesic
from sweep_core.model.maps import OccupancyMap

ROOM = [{"kind": "polyline", "closed": True, "points": [[0, 0], [20, 0], [20, 10], [0, 10]]}]


def scene(drift, walls=ROOM, obstacles=(), positions=((2.0, 5.0),), radius=0.2, sigma=0.0):
    return sc.Scene.from_dict({"agents": {"positions": [list(p) for p in positions],
                                          "radius": radius},
                               "walls": list(walls), "obstacles": list(obstacles),
                               "drift": drift, "noise": {"sigma": sigma}})


def angles(u, v):
    """Angle (degrees) between rows of u and v."""
    cos = np.einsum("ij,ij->i", u, v) / (np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1))
    return np.degrees(np.arccos(np.clip(cos, -1, 1)))


@pytest.mark.parametrize("neighbours", [8, 16, 32])
def test_empty_room_travel_distance_within_the_metrication_error(neighbours):
    goal = np.array([10.0, 5.0])
    f = scene({"kind": "geodesic", "goal": goal.tolist(), "speed": 1.0,
               "neighbours": neighbours}).drift
    assert isinstance(f, Geodesic)
    yy, xx = np.meshgrid(f.y, f.x, indexing="ij")
    exact = np.hypot(xx - goal[0], yy - goal[1])
    inside = (xx > 0.31) & (xx < 19.69) & (yy > 0.31) & (yy < 9.69)
    assert np.all(f.free[inside] & np.isfinite(f.travel[inside]))
    out = (xx < 0.29) | (xx > 19.71) | (yy < 0.29) | (yy > 9.71)
    assert not np.any(np.isfinite(f.travel[out]))  # outside the room, or within 0.3 m of it
    far = inside & (exact > 1.0)
    rel = (f.travel[far] - exact[far]) / exact[far]
    assert rel.min() >= -1e-9  # a stencil path is never shorter than the straight line
    bound = geodesic.METRICATION[neighbours]
    assert 0.9 * bound < rel.max() <= bound + 1e-3  # the stated error, reached
    # direction: the faces of the stencil's polygon (16 neighbours: within about 13 degrees)
    nodes = np.stack([xx[far], yy[far]], axis=1)
    err = angles(f.direction[far], goal - nodes)
    assert 0.8 * geodesic.DIRECTION_ERROR[neighbours] < err.max()
    assert err.max() < geodesic.DIRECTION_ERROR[neighbours]
    # the field at agents' positions is speed x that direction, |U| <= speed
    q = np.array([[3.0, 2.0], [17.5, 8.2], [10.2, 5.1], [0.1, 0.1]])
    u = f(0.0, q)
    assert np.all(np.linalg.norm(u, axis=1) <= 1.0 + 1e-12)
    assert np.all(angles(u[:2], goal - q[:2]) < geodesic.DIRECTION_ERROR[neighbours])
    assert np.linalg.norm(u[2]) < 0.5  # slowing inside slow_radius 0.5 m of the goal


def rounded_detour(p, g, a, b):
    """Length of the shortest path from p (left) to g (right) over the top of the square
    [-a, a]^2 grown by b (rounded corners): tangent, arc, the top edge, arc, tangent."""
    def side(pt):
        c = np.array([-a, a])
        v = c - pt
        n = float(np.hypot(*v))
        theta = math.atan2(v[1], v[0]) + math.asin(b / n)  # leaving towards the top
        return math.sqrt(n * n - b * b) + b * theta
    return side(np.asarray(p)) + side(np.array([-g[0], g[1]])) + 2 * a


@pytest.mark.parametrize("p", [(-4.0, 0.3), (-2.5, 0.2), (-6.0, 1.2)])
def test_around_a_square_pillar_against_the_closed_form_geodesic(p):
    a, b, cell = 1.0, 0.12, 0.05
    g = (4.0, 0.8)
    walls = [{"kind": "polyline", "closed": True, "points": [[-8, -4], [8, -4], [8, 4], [-8, 4]]}]
    pillar = [{"kind": "polygon", "points": [[-a, -a], [a, -a], [a, a], [-a, a]]}]
    f = scene({"kind": "geodesic", "goal": list(g), "speed": 1.0, "cell": cell,
               "wall_buffer": b}, walls=walls, obstacles=pillar, positions=[p]).drift
    exact = rounded_detour(p, g, a, b)
    sharp = math.dist(p, (-a, a)) + 2 * a + math.dist((a, a), g)  # b = 0: |p-c| + |c-c'| + |c'-g|
    assert exact > sharp
    t = float(f.travel_distance(np.array([p]))[0])
    assert exact - cell <= t <= exact * (1 + geodesic.METRICATION[16]) + cell
    # heading for the pillar's upper-left corner, not straight at the goal through the pillar
    u = f(0.0, np.array([p]))[0]
    to_corner = np.array([-a - b, a + b]) - p
    assert angles(u[None], to_corner[None])[0] < 14.0


GAP_WALLS = [{"kind": "polyline", "closed": True, "points": [[0, 0], [12, 0], [12, 8], [0, 8]]},
             {"kind": "segment", "a": [6, 0], "b": [6, 6.2]}]  # a 1.8 m gap at the top


def evacuate(drift, t_end=14.0):
    xs, ys = np.meshgrid([1.5, 2.5, 3.5, 4.5], [1.0, 2.0, 3.0, 4.0, 5.0])
    pos = np.stack([xs.ravel(), ys.ravel()], axis=1)
    s = scene(drift, walls=GAP_WALLS, positions=pos, radius=0.2, sigma=0.05)
    sim = sc.Simulator(s, dt=0.05, seed=1)
    while sim.t < t_end - 1e-9:
        sim.step()
    return int(np.count_nonzero(sim.positions[:, 0] > 6.0))


def test_a_crowd_behind_a_wall_leaves_through_the_gap_only_with_the_geodesic_field():
    goal = [10.0, 2.0]
    assert evacuate({"kind": "geodesic", "goal": goal, "speed": 1.3}) == 20
    assert evacuate({"kind": "goal", "goal": goal, "speed": 1.3}) == 0


def test_two_exits_each_agent_takes_the_nearer_and_weights_count():
    walls = [{"kind": "polyline", "closed": True, "points": [[0, 0], [20, 0], [20, 6], [0, 6]]}]
    q = np.array([[5.0, 3.0], [15.0, 3.0]])
    exits = [{"goal": [1.0, 3.0]}, {"region": {"kind": "rectangle", "min": [18.5, 1],
                                                "max": [19.5, 5]}}]
    f = scene({"kind": "exits", "exits": exits, "speed": 1.0}, walls=walls, positions=q).drift
    assert isinstance(f, Exits)
    u = f(0.0, q)
    assert u[0, 0] < -0.99 and u[1, 0] > 0.99
    np.testing.assert_allclose(f.travel_distance(q), [4.0, 3.5], atol=0.05)
    # inside the exit region the agent stops
    assert np.allclose(f(0.0, np.array([[19.0, 3.0]])), 0.0)
    # the left exit four times as costly: the agent at x = 5 (4 m * 4 > 13.5 m) goes right
    exits[0]["weight"] = 4.0
    f = scene({"kind": "exits", "exits": exits, "speed": 1.0}, walls=walls, positions=q).drift
    u = f(0.0, q)
    assert u[0, 0] > 0.99 and u[1, 0] > 0.99


@pytest.mark.parametrize("drift, field, words", [
    ({"kind": "geodesic", "goal": [10, 5], "speed": 1, "cell": 0}, "drift.cell", "> 0"),
    ({"kind": "geodesic", "goal": [10, 5], "speed": 1, "cell": 0.5}, "drift.cell",
     "too coarse"),
    ({"kind": "geodesic", "goal": [10, 5], "speed": 1, "cell": 0.005, "wall_buffer": 0.3},
     "drift.cell", "nodes"),
    ({"kind": "geodesic", "goal": [10, 5], "speed": -1}, "drift.speed", ""),
    ({"kind": "geodesic", "speed": 1}, "drift", "neither"),
    ({"kind": "geodesic", "goal": [10, 5], "region": {"kind": "rectangle", "min": [0, 0],
                                                      "max": [1, 1]}, "speed": 1},
     "drift", "both"),
    ({"kind": "geodesic", "region": {"kind": "rectangle", "min": [3, 3], "max": [1, 1]},
      "speed": 1}, "drift.region", "not below"),
    ({"kind": "geodesic", "goal": [15, 5], "speed": 1}, "drift.goal", "obstacles[0]"),
    ({"kind": "geodesic", "goal": [30, 5], "speed": 1}, "drift", "agent 0"),
    ({"kind": "geodesic", "goal": [10, 5], "speed": 1, "colour": 1}, "drift", "colour"),
    ({"kind": "exits", "exits": [], "speed": 1}, "drift.exits", "non-empty"),
    ({"kind": "geodesic", "goal": [10, 5], "speed": 1, "neighbours": 12}, "drift.neighbours",
     "8, 16 or 32"),
    ({"kind": "geodesic", "goal": [10, 5], "speed": 1, "neighbours": 32, "cell": 0.2},
     "drift.cell", "3.606 cells"),
    ({"kind": "exits", "exits": [{"goal": [10, 5], "weight": 0}], "speed": 1},
     "drift.exits[0].weight", ""),
    ({"kind": "exits", "exits": [{"goal": [15, 5]}], "speed": 1}, "drift.exits[0].goal",
     "obstacles[0]"),
])
def test_bad_specs_are_refused_naming_the_field(drift, field, words):
    box = [{"kind": "polygon", "points": [[14, 4], [16, 4], [16, 6], [14, 6]]}]
    with pytest.raises(SceneError) as err:
        scene(drift, obstacles=box)
    text = str(err.value)
    assert text.startswith(field) and words in text and "fix:" in text
    assert "\n" not in text and "np." not in text and "array(" not in text


def test_an_enclosed_goal_is_refused_naming_an_agent():
    inner = {"kind": "polyline", "closed": True, "points": [[8, 3], [12, 3], [12, 7], [8, 7]]}
    with pytest.raises(SceneError, match=r"^drift: agent 0 at \[2, 5\] has no way"):
        scene({"kind": "geodesic", "goal": [10, 5], "speed": 1}, walls=ROOM + [inner])
    # a passage narrower than 2 wall_buffer is closed too
    door = [{"kind": "segment", "a": [6, 0], "b": [6, 4.8]},
            {"kind": "segment", "a": [6, 5.2], "b": [6, 10]}]
    with pytest.raises(SceneError, match="agent 0"):
        scene({"kind": "geodesic", "goal": [10, 5], "speed": 1}, walls=ROOM + door)
    assert scene({"kind": "geodesic", "goal": [10, 5], "speed": 1, "wall_buffer": 0.15},
                 walls=ROOM + door).drift.kind == "geodesic"


def test_a_goal_beside_a_wall_is_seeded_from_its_own_side_only():
    """A goal 0.1 m behind a thin wall: the free nodes on the near side within reach do not
    see it, so T runs round the wall's end."""
    wall = [{"kind": "segment", "a": [10, 0], "b": [10, 8]}]
    f = scene({"kind": "geodesic", "goal": [10.1, 5], "speed": 1}, walls=ROOM + wall).drift
    t = float(f.travel_distance(np.array([[9.5, 5.0]]))[0])
    assert t > 2 * 3.0  # up to the wall's end at y = 8 and back down


def test_spec_round_trips_and_rebuilds_the_same_field(tmp_path):
    s = scene({"kind": "exits", "exits": [{"goal": [1, 5]}, {"region": {
        "kind": "polygon", "points": [[18, 4], [19, 4], [19, 6]]}, "weight": 2}],
        "speed": 1.2, "cell": 0.2, "wall_buffer": 0.25})
    spec = s.spec["drift"]
    assert spec == {"kind": "exits", "exits": [{"goal": [1.0, 5.0], "weight": 1.0}, {
        "region": {"kind": "polygon", "points": [[18.0, 4.0], [19.0, 4.0], [19.0, 6.0]]},
        "weight": 2.0}], "speed": 1.2, "cell": 0.2, "wall_buffer": 0.25, "slow_radius": 0.5,
        "neighbours": 16}
    again = sc.Scene.from_yaml_text(s.to_yaml())
    assert again.spec == s.spec
    for name in ("x", "y", "direction", "distance", "travel"):
        assert np.array_equal(getattr(again.drift, name), getattr(s.drift, name))


@pytest.mark.parametrize("moving", [False, True])
def test_sweep_run_of_a_geodesic_scene_replays_identically(tmp_path, moving):
    pillar = [{"kind": "circle", "center": [6, 5], "radius": 0.8}]
    drift = {"kind": "geodesic", "goal": [12, 5], "speed": 1.3, "cell": 0.2}
    if moving:  # the pillar drifts and the field follows it every 0.2 s
        pillar[0]["velocity"] = [-2.0, 0.5]
        drift["update_every"] = 0.2
    s = scene(drift, obstacles=pillar, positions=[(2, 5), (2, 6), (3, 4.5)], sigma=0.1)
    path = tmp_path / "s.yaml"
    path.write_text(s.to_yaml())
    out = tmp_path / "run.mcap"
    assert main(["run", str(path), "--t-end", "0.5", "--seed", "3", "--out", str(out),
                 "--quiet"]) == 0
    assert main(["replay", str(out), "--quiet"]) == 0
    res = replay.replay(out)
    assert res.identical and res.frames_compared > 10
    assert run.load_run(out).scene.spec["drift"] == s.spec["drift"]


def test_the_field_is_lipschitz_on_the_grid_scale_and_bounded():
    f = scene({"kind": "geodesic", "goal": [18, 5], "speed": 1.5},
              obstacles=[{"kind": "polygon", "points": [[9, 3], [11, 3], [11, 7], [9, 7]]}]).drift
    rng = np.random.default_rng(0)
    q = rng.uniform([0.3, 0.3], [19.7, 9.7], (4000, 2))
    dq = rng.normal(size=(4000, 2)) * 1e-3
    u0, u1 = f(0.0, q), f(0.0, q + dq)
    assert np.all(np.linalg.norm(u0, axis=1) <= 1.5 + 1e-12)
    ratio = np.linalg.norm(u1 - u0, axis=1) / np.linalg.norm(dq, axis=1)
    assert ratio.max() <= 4 * 1.5 / 0.1 + 1.5 / 0.5


def test_map_cells_are_walls_for_the_field():
    """A map of 10 x 5 m (0.25 m cells) with a wall of cells across it but for a gap at the
    top: the way from the lower left to the lower right goes through the gap."""
    blocked = np.zeros((20, 40), dtype=bool)
    blocked[[0, -1], :] = blocked[:, [0, -1]] = True
    blocked[:14, 20] = True  # x in [5, 5.25], y < 3.5: open above y = 3.5 up to 4.75
    packed = OccupancyMap(blocked, 0.25, (0.0, 0.0, 0.0), "test").to_spec()
    drift = {"kind": "geodesic", "goal": [8.0, 1.0], "speed": 1.0}
    s = sc.Scene.from_dict({"agents": {"positions": [[2.0, 1.0]], "radius": 0.2},
                            "map": packed, "drift": drift})
    f = s.drift
    # round the gap's lower corners (5, 3.5), (5.25, 3.5) grown by 0.3 m: about 8.4 m (the
    # square-cornered path below is a little longer: the grown corners are round)
    exact = math.dist((2, 1), (4.7, 3.8)) + 0.85 + math.dist((5.55, 3.8), (8, 1))
    t = float(f.travel_distance(np.array([[2.0, 1.0]]))[0])
    assert exact - 0.1 <= t <= exact * (1 + geodesic.METRICATION[16]) + 0.2
    u = f(0.0, np.array([[2.0, 1.0]]))[0]
    assert u[1] > 0.5  # up towards the gap, not straight at the goal
    with pytest.raises(SceneError, match=r"^drift.goal: \[5.1, 1\] lies in or on a blocked"):
        sc.Scene.from_dict({"agents": {"positions": [[2.0, 1.0]], "radius": 0.2},
                            "map": packed, "drift": {**drift, "goal": [5.1, 1.0]}})


def test_moving_obstacles_count_where_they_are_at_t0():
    box = {"kind": "polygon", "points": [[9, 0], [11, 0], [11, 9], [9, 9]], "velocity": [0, 1]}
    f = scene({"kind": "geodesic", "goal": [15, 5], "speed": 1.0}, obstacles=[box]).drift
    q = np.array([[5.0, 5.0]])
    assert float(f.travel_distance(q)[0]) > math.dist((5, 5), (8.7, 9.3)) + 2.6
    assert f(0.0, q)[0, 1] > 0.5  # round the top of the box, as it stands at t = 0


CORRIDOR = [{"kind": "polyline", "closed": True, "points": [[0, 0], [20, 0], [20, 3], [0, 3]]}]


def test_two_groups_crossing_in_a_corridor_both_arrive():
    left = [(1.0 + 0.7 * k, 0.8) for k in range(4)]
    right = [(19.0 - 0.7 * k, 2.2) for k in range(4)]
    drift = {"kind": "groups", "groups": [
        {"agents": {"range": [0, 4]}, "drift": {"kind": "geodesic", "goal": [19.5, 0.8],
                                                "speed": 1.3}},
        {"agents": [4, 5, 6, 7], "drift": {"kind": "goal", "goal": [0.5, 2.2], "speed": 1.0}}]}
    s = scene(drift, walls=CORRIDOR, positions=left + right, radius=0.25, sigma=0.02)
    assert s.spec["drift"]["groups"][0]["agents"] == {"range": [0, 4]}
    assert sc.Scene.from_yaml_text(s.to_yaml()).spec == s.spec
    sim = sc.Simulator(s, dt=0.05, seed=2)
    while sim.t < 25.0:
        sim.step()
    q = sim.positions
    assert np.all(q[:4, 0] > 15.0) and np.all(q[4:, 0] < 5.0)


@pytest.mark.parametrize("drift, field, words", [
    ({"kind": "groups", "groups": []}, "drift.groups", "non-empty"),
    ({"kind": "groups", "groups": [{"agents": [0, 7], "drift": None}]}, "drift.groups[0].agents",
     "agent 7"),
    ({"kind": "groups", "groups": [{"agents": {"range": [1, 1]}, "drift": None}]},
     "drift.groups[0].agents.range", "no agent"),
    ({"kind": "groups", "groups": [{"agents": [0], "drift": None},
                                   {"agents": [1, 0], "drift": None}]},
     "drift.groups[1].agents", "second group"),
    ({"kind": "groups", "groups": [{"agents": [0], "drift": {"kind": "groups", "groups": []}}]},
     "drift.groups[0].drift.kind", "inside"),
    ({"kind": "groups", "groups": [{"agents": [0, 1], "drift": {
        "kind": "per_agent", "velocities": [[1, 0]]}}]}, "drift.groups[0].drift.velocities",
     "2 agents"),
    ({"kind": "groups", "groups": [{"agents": [1], "drift": {
        "kind": "geodesic", "goal": [15, 5], "speed": 1}}]}, "drift.groups[0].drift.goal",
     "obstacles[0]"),
])
def test_bad_groups_are_refused_naming_the_field(drift, field, words):
    box = [{"kind": "polygon", "points": [[14, 4], [16, 4], [16, 6], [14, 6]]}]
    with pytest.raises(SceneError) as err:
        scene(drift, obstacles=box, positions=[(2, 5), (3, 5), (4, 5)])
    text = str(err.value)
    assert text.startswith(field) and words in text and "fix:" in text, text


def test_update_every_recomputes_the_field_as_an_obstacle_moves():
    """A box across the room but for a gap at the top slides down at 1 m/s: at t = 0 the way
    is over it; recomputed each second, the way is straight once it has gone below y = 4."""
    box = {"kind": "polygon", "points": [[9, 0], [11, 0], [11, 9], [9, 9]], "velocity": [0, -1]}
    drift = {"kind": "geodesic", "goal": [15, 5], "speed": 1.0, "update_every": 1.0}
    f = scene(drift, obstacles=[box]).drift
    q = np.array([[5.0, 5.0]])
    assert f(0.0, q)[0, 1] > 0.5 and f(0.99, q)[0, 1] > 0.5
    assert float(f.travel_distance(q, 0.0)[0]) > 11.0
    np.testing.assert_allclose(f.travel_distance(q, 5.5), 10.0, rtol=0.01)
    np.testing.assert_allclose(f(5.5, q), [[1.0, 0.0]], atol=0.02)
    assert f(0.5, q)[0, 1] > 0.5  # back to t = 0 (a reset): the first field again
    assert sc.Scene.from_dict(scene(drift, obstacles=[box]).spec).drift.update_every == 1.0
    # a block rising at 1 m/s covers the goal from t = 3 to t = 5: no way to it, U = 0
    up = {"kind": "polygon", "points": [[12, 0], [16, 0], [16, 2], [12, 2]], "velocity": [0, 1]}
    g = scene(drift, obstacles=[up]).drift
    assert np.allclose(g(4.5, q), 0.0)
    assert g(6.5, q)[0, 0] > 0.9
    with pytest.raises(SceneError, match=r"^drift.update_every: is 1 s but no obstacle moves"):
        scene(drift)


def test_navigation_targets_name_each_exit_and_tell_arrivals():
    spec = {"kind": "exits", "exits": [{"goal": [1, 5]}, {"region": {
        "kind": "rectangle", "min": [18, 4], "max": [19, 6]}, "weight": 2}]}
    named = geodesic.navigation_targets(spec)
    assert [n for n, _ in named] == ["exits[0]", "exits[1]"]
    q = np.array([[1.3, 5.0], [18.5, 5.0], [17.9, 5.0]])
    assert named[0][1].arrived(q, 0.5).tolist() == [True, False, False]
    assert named[1][1].arrived(q, 0.5).tolist() == [False, True, False]
    assert geodesic.navigation_targets({"kind": "geodesic", "goal": [3, 4]})[0][0] == "goal"
