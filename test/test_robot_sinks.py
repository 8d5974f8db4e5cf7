"""Robots among flows whose people leave at sinks: the robot's step sees the radii of the
people present, entry by entry, not the scene's list of every agent's."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sweep_core import Scene, Simulator
from sweep_core.model.gaps import gaps
from sweep_core.model.scene import default_scene_path
from sweep_core.model.yaml_files import load_yaml
from sweep_core.numerics.simulator import FEASIBILITY_TOLERANCE

#: radii (m) that differ person by person, so that a radius read at the wrong index shows
RADII = [0.2, 0.25, 0.3, 0.22, 0.25, 0.28, 0.21, 0.25, 0.26, 0.24]


def _scene(controller: bool) -> Scene:
    """The bundled crowdnav corridor with a sink at its west end (the people's goal is
    beyond it, so they leave one by one) and people of different radii; the robot with its
    social-force planner, or holding a command (no controller)."""
    data = load_yaml((default_scene_path().parent / "crowdnav.yaml").read_text())
    data["agents"]["radius"] = RADII
    data["flows"]["sinks"] = [{"kind": "rectangle", "min": [-2.0, 0.0], "max": [2.5, 6.0]}]
    if not controller:
        del data["robots"][0]["controller"]
    return Scene.from_dict(data)


def _check(sim: Simulator) -> None:
    """No person overlaps another, a wall or the robot, by their true radii."""
    q, r = sim.positions, sim.radii
    assert len(r) == len(q)
    if len(q):
        assert gaps(sim.scene.geometry, sim.t, q, r).min_gap >= -FEASIBILITY_TOLERANCE
        st = sim.robots.state("robot")
        x, y = st.pose[0], st.pose[1]
        d = np.hypot(q[:, 0] - x, q[:, 1] - y) - r - st.robot.radius
        assert d.min() >= -FEASIBILITY_TOLERANCE


@pytest.mark.parametrize("controller", [True, False])
def test_a_robot_steps_on_after_people_leave(controller):
    sim = Simulator(_scene(controller), dt=0.01, seed=3)
    if not controller:  # straight ahead, slowly: people pass it on both sides
        sim.robots.command("robot", (0.2, 0.0, 0.0))
    present = []
    for _ in range(90):
        sim.step(10)
        _check(sim)
        present.append(len(sim.positions))
    # people left while the robot stepped on (each step's radii were the present people's)
    assert present[0] == len(RADII) and present[-1] <= len(RADII) - 5
    # the radii the simulator reports are the present people's own, in order
    assert all(any(math.isclose(v, w) for w in RADII) for v in sim.radii)
