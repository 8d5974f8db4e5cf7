"""With flows, people leave and enter, so the rows of the step's arrays are not the people's
ids: every message and error that names a person names them by id."""
from __future__ import annotations

import numpy as np
import pytest

from sweep_core import Scene, Simulator
from sweep_core.errors import InfeasibleError, SceneError
from sweep_core.model.fields import Field
from sweep_core.model.scene import default_scene_path
from sweep_core.model.yaml_files import load_yaml


def _left(robot: bool) -> Simulator:
    """The crowdnav corridor with a sink at its west end, stepped until people have left
    (then row i of the arrays is no longer person i); with its robot, or without robots."""
    data = load_yaml((default_scene_path().parent / "crowdnav.yaml").read_text())
    data["flows"]["sinks"] = [{"kind": "rectangle", "min": [-2.0, 0.0], "max": [2.5, 6.0]}]
    if robot:
        del data["robots"][0]["controller"]
        data["robots"][0]["pose"] = [12.5, 3.0, 0.0]  # out of the people's way
    else:
        del data["robots"]
    sim = Simulator(Scene.from_dict(data), dt=0.01, seed=3)
    while len(sim.positions) > 7:
        sim.step(10)
    ids = sim.ids
    assert not np.array_equal(ids, np.arange(len(ids)))  # rows and ids differ
    return sim


def _row_of_id_unlike(sim: Simulator) -> int:
    """A row whose person's id is not the row."""
    return int(np.flatnonzero(sim.ids != np.arange(len(sim.ids)))[0])


def test_a_placed_robot_names_the_person_it_overlaps_by_id():
    sim = _left(robot=True)
    row = _row_of_id_unlike(sim)
    x, y = sim.positions[row]
    with pytest.raises(SceneError) as info:
        sim.robots.place("robot", (x, y, 0.0), sim.t, sim.positions, sim.radii, sim.ids)
    assert f"overlaps agent {int(sim.ids[row])} " in info.value.problem


def test_new_walls_name_the_people_inside_them_by_id():
    sim = _left(robot=False)
    row = _row_of_id_unlike(sim)
    x, y = sim.positions[row]
    spec = dict(sim.scene.spec)
    spec["obstacles"] = [{"kind": "circle", "centre": [float(x), float(y)], "radius": 0.1}]
    with pytest.raises(SceneError) as info:
        sim.set_scene(Scene.from_dict(spec))
    who = int(sim.ids[row])
    assert f"agents [{who}]" in info.value.problem
    assert f"(agent {who} at [{x:g}, {y:g}])" in info.value.problem


class _Broken(Field):
    """A drift that is NaN at one person's position (the step then fails, naming them)."""

    kind = "broken"

    def __init__(self, at: np.ndarray) -> None:
        self.at = at

    def __call__(self, t: float, q: np.ndarray) -> np.ndarray:
        u = np.zeros_like(q)
        u[np.all(q == self.at, axis=1)] = np.nan
        return u


def test_a_failed_step_names_the_people_by_id():
    sim = _left(robot=False)
    row = _row_of_id_unlike(sim)
    sim.set_drift(_Broken(sim.positions[row].copy()))
    t, q = sim.t, sim.positions.copy()
    with pytest.raises(InfeasibleError) as info:
        sim.step()
    err = info.value
    assert err.agents == [int(sim.ids[row])]
    assert sim.t == t and np.array_equal(sim.positions, q)  # the state as before the step


def test_by_ids_renames_agents_and_their_mentions():
    err = InfeasibleError(1.5, [0, 2], "the centre of agent 2 went through wall 3 (agents 0)",
                          "move agent 0")
    named = err.by_ids(np.array([10, 11, 12]))
    assert named.agents == [10, 12]
    assert named.detail == "the centre of agent 12 went through wall 3 (agents 0)"
    assert named.fix_given == "move agent 10"
    assert named.t == 1.5
