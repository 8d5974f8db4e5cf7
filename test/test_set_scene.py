"""Simulator.set_scene: new walls (a map) between two steps, the state and the Brownian path
kept (issue 13, the node's map topic)."""
import numpy as np
import pytest

import sweep_core as sc
from sweep_core.errors import SceneError
from sweep_core.model.maps import OccupancyMap, map_from_spec
from sweep_core.model.scene import copy_spec
from sweep_core.numerics.simulator import violating_agents

# 4 agents in a row, drifting +x with noise
OPEN = {"agents": {"positions": [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]],
                   "radius": 0.2},
        "drift": {"kind": "uniform", "velocity": [0.5, 0.0]}, "noise": {"sigma": 0.2}}


def box_map(x0: float, y0: float, w: int, h: int, blocked: list[tuple[int, int]] = (),
            res: float = 0.5) -> dict:
    """A packed map: w x h cells of res m from (x0, y0), free but for ``blocked`` (row, col)
    and its border row/column of blocked cells all round."""
    cells = np.zeros((h, w), dtype=bool)
    cells[0, :] = cells[-1, :] = cells[:, 0] = cells[:, -1] = True
    for r, c in blocked:
        cells[r, c] = True
    data = np.where(cells, 100, 0).ravel()
    return OccupancyMap.from_occupancy_grid(data, w, h, res, (x0, y0, 0.0), source="test").to_spec()


def with_map(scene: sc.Scene, spec: dict) -> sc.Scene:
    return sc.Scene.from_dict({**copy_spec(scene), "map": spec})


def test_far_walls_change_nothing_else() -> None:
    """Time, positions, drift, noise and the Brownian path carry over: walls far from every
    agent leave the run bit-identical to one without them."""
    scene = sc.Scene.from_dict(OPEN)
    a, b = sc.Simulator(scene, dt=0.01, seed=3), sc.Simulator(scene, dt=0.01, seed=3)
    a.step(30)
    b.step(30)
    b.set_scene(with_map(scene, box_map(-50.0, -50.0, 200, 200)))
    assert b.t == a.t and b.n_steps == 30 and len(b.scene.geometry.segment_a) == 4
    a.step(50)
    b.step(50)
    assert np.array_equal(a.positions, b.positions)


def test_walls_take_effect_from_the_next_step_and_are_never_crossed() -> None:
    scene = sc.Scene.from_dict(OPEN)
    sim = sc.Simulator(scene, dt=0.01, seed=1)
    sim.step(10)
    # a room of free cells x in [-1, 5.5], y in [-1, 1] (cells of 0.5 m, a blocked border)
    spec = box_map(-1.5, -1.5, 15, 6)
    sim.set_scene(with_map(scene, spec))
    grid = map_from_spec(spec, "map", None)
    for _ in range(600):
        sim.step()
        assert not grid.is_blocked(sim.positions).any()
    # pushed +x for 6 s at 0.5 m/s: the crowd is held by the wall at x = 5.5
    assert 5.2 < sim.positions[:, 0].max() <= 5.5 - 0.2 + 1e-9


def test_a_wall_through_an_agent_is_refused_naming_it() -> None:
    three = {**OPEN, "agents": {"positions": [[0.25, 0.25], [1.25, 0.25], [2.25, 0.25]],
                                "radius": 0.2}, "noise": {"sigma": 0.0}}
    scene = sc.Scene.from_dict(three)
    sim = sc.Simulator(scene, dt=0.01, seed=0)
    sim.step(100)  # moved 0.5 m: agent 1 now at x = 1.75
    before = sim.scene
    # a blocked cell [1.5, 2) x [0, 0.5) round agent 1's new position, clear of where it started
    new = with_map(scene, box_map(-1.5, -1.5, 15, 6, blocked=[(3, 6)]))
    assert violating_agents(new, sim.t, sim.positions) == [1]
    with pytest.raises(SceneError) as err:
        sim.set_scene(new)
    assert "agents [1]" in str(err.value) and "[1.75, 0.25]" in str(err.value)
    assert err.value.fix and sim.scene is before
    sim.step(40)  # agent 2 at x = 2.95: a cell [3, 3.5) cuts its disk, its centre is free
    new = with_map(scene, box_map(-1.5, -1.5, 15, 6, blocked=[(3, 9)]))
    assert violating_agents(new, sim.t, sim.positions) == [2]
    with pytest.raises(SceneError, match=r"agents \[2\]"):
        sim.set_scene(new)


def test_other_agents_are_refused() -> None:
    scene = sc.Scene.from_dict(OPEN)
    sim = sc.Simulator(scene, dt=0.01, seed=0)
    other = sc.Scene.from_dict({**OPEN, "agents": {"positions": [[0.0, 0.0]], "radius": 0.2},
                                "noise": {"sigma": 0.1}})
    with pytest.raises(SceneError, match="keep the agents"):
        sim.set_scene(other)


def test_a_navigation_field_follows_the_new_walls() -> None:
    """set_scene takes the new scene's own drift (its geodesic field computed round the new
    walls) unless a command replaced the drift."""
    import sweep_core as sc
    from sweep_core.analysis.run import scene_with_map
    from sweep_core.model.maps import OccupancyMap

    def room(wall: bool) -> dict:
        cells = np.zeros((20, 40), dtype=np.int8)
        cells[0, :] = cells[-1, :] = cells[:, 0] = cells[:, -1] = 100
        if wall:
            cells[:16, 20] = 100  # a wall from the south with a gap in the north
        return OccupancyMap.from_occupancy_grid(cells.ravel(), 40, 20, 0.25, (0.0, 0.0, 0.0),
                                                source="/map").to_spec()

    scene = sc.Scene.from_dict({"map": room(True),
                                "agents": {"positions": [[2.0, 1.5]], "radius": 0.2},
                                "drift": {"kind": "geodesic", "goal": [8.0, 1.5], "speed": 1.0}})
    sim = sc.Simulator(scene, dt=0.01, seed=0)
    before = sim.drift(0.0, sim.positions)[0]
    assert before[1] > 0.5  # round the wall: north first
    sim.set_scene(scene_with_map(scene, room(False)))
    after = sim.drift(0.0, sim.positions)[0]
    assert after[0] > 0.99  # no wall: straight east
    command = sc.field_from_spec({"kind": "uniform", "velocity": [0.0, -1.0]}, 1)
    sim.set_drift(command)
    sim.set_scene(scene_with_map(scene, room(True)))
    assert sim.drift is command


def test_a_commanded_navigation_field_is_computed_again_round_the_new_walls() -> None:
    """A goal command's geodesic field (the node's, or a replay's) follows a new map as the
    scene's own does; a goal the new walls block refuses the map, the simulator unchanged."""
    from sweep_core.analysis.run import scene_with_map

    def room(wall: bool, block_goal: bool = False) -> dict:
        cells = np.zeros((20, 40), dtype=np.int8)
        cells[0, :] = cells[-1, :] = cells[:, 0] = cells[:, -1] = 100
        if wall:
            cells[:16, 20] = 100  # a wall from the south with a gap in the north
        if block_goal:
            cells[2:10, 28:36] = 100  # a block over the goal
        return OccupancyMap.from_occupancy_grid(cells.ravel(), 40, 20, 0.25, (0.0, 0.0, 0.0),
                                                source="/map").to_spec()

    scene = sc.Scene.from_dict({"map": room(False),
                                "agents": {"positions": [[2.0, 1.5]], "radius": 0.2},
                                "drift": {"kind": "none"}})
    sim = sc.Simulator(scene, dt=0.01, seed=0)
    goal = {"kind": "geodesic", "goal": [8.0, 1.5], "speed": 1.0}
    sim.set_drift(scene.drift_from_spec(goal))
    assert sim.drift(0.0, sim.positions)[0][0] > 0.99  # open room: straight east
    walled = scene_with_map(scene, room(True))
    sim.set_scene(walled)
    assert sim.drift.to_spec() == scene.drift_from_spec(goal).to_spec()
    turned = sim.drift(0.0, sim.positions)[0]
    assert turned[1] > 0.5  # round the new wall: north first
    # the same floats as the field a replay builds against the walled scene
    again = walled.drift_from_spec(goal)
    assert np.array_equal(again(0.0, sim.positions), sim.drift(0.0, sim.positions))
    kept = sim.drift
    with pytest.raises(SceneError) as err:
        sim.set_scene(scene_with_map(scene, room(True, block_goal=True)))
    assert err.value.field == "scene" and "cannot follow the new walls" in err.value.problem
    assert "send a new goal" in err.value.fix
    assert sim.drift is kept and sim.scene is walled
