"""Robots among features combined (flows whose people leave, radius laws, obstacles): what a
robot reports names the right people."""
from __future__ import annotations

import numpy as np
import pytest

from sweep_core import Scene, Simulator
from sweep_core.model.scene import default_scene_path
from sweep_core.model.yaml_files import load_yaml

#: radii (m) that differ person by person
RADII = [0.2, 0.25, 0.3, 0.22, 0.25, 0.28, 0.21, 0.25, 0.26, 0.24]


def _sink_scene(weight: object) -> Scene:
    """The bundled crowdnav corridor with a sink at its west end and a robot without a
    controller standing in the people's way (they press on it, then pass and leave)."""
    data = load_yaml((default_scene_path().parent / "crowdnav.yaml").read_text())
    data["agents"]["radius"] = RADII
    data["flows"]["sinks"] = [{"kind": "rectangle", "min": [-2.0, 0.0], "max": [2.5, 6.0]}]
    robot = data["robots"][0]
    del robot["controller"], robot["scan"]
    robot["pose"], robot["weight"] = [4.0, 2.6, 0.0], weight
    return Scene.from_dict(data)


@pytest.mark.parametrize("weight", ["inf", 1])
def test_contact_ids_are_the_peoples_ids_after_some_left(weight):
    sim = Simulator(_sink_scene(weight), dt=0.05, seed=1)
    assert sim.flows is not None
    named = 0
    for _ in range(200):
        sim.step(1)
        st = sim.robots.state("robot")
        ids, q = sim.ids, sim.positions
        for who, xy in zip(st.contact_ids.tolist(), st.contact_xy):
            if who in ids:  # present: the contact's position is that person's
                assert np.array_equal(q[np.searchsorted(ids, who)], xy)
            else:  # left at the end of this very step
                assert sim.flows.left_at.get(who) == sim.t
            named += int(sim.flows.left > 0)
    assert named > 0  # contacts after people had left were checked


def test_analyze_robot_clearance_uses_float64_radii_after_people_left(tmp_path):
    """``sweep analyze``'s robot table: the clearance to people is computed with the scene's
    float64 radii of the people present, by their ids, after some left (docs/social_metrics.md),
    as the Python run sees it; not with the float32 radii of ``/agents``."""
    from sweep_core.analysis.metrics import analyze
    from sweep_core.cli import main
    from sweep_core.model.yaml_files import dump_yaml

    data = load_yaml((default_scene_path().parent / "crowdnav.yaml").read_text())
    data["agents"]["radius"] = RADII
    data["flows"]["sinks"] = [{"kind": "rectangle", "min": [-2.0, 0.0], "max": [2.5, 6.0]}]
    path = tmp_path / "sinks.yaml"
    path.write_text(dump_yaml(data))
    out = tmp_path / "run.mcap"
    assert main(["run", str(path), "--t-end", "8", "--dt", "0.05", "--seed", "2", "--out",
                 str(out), "--quiet"]) == 0
    sim = Simulator(Scene.from_dict(data), dt=0.05, seed=2)
    truth = []
    for _ in range(161):
        st = sim.robots.state("robot")
        q, r = sim.positions, sim.radii
        truth.append(np.min(np.hypot(q[:, 0] - st.pose[0], q[:, 1] - st.pose[1]) - r
                            - st.robot.radius) if len(q) else np.inf)
        sim.step(1)
    table = analyze(out, progress=False).robots
    clearance = table[:, 7]
    assert sim.flows.left > 3  # people had left while the robot was among the rest
    # float64 throughout (rounding of the distance's terms aside); float32 radii: ~1e-8 m
    assert np.abs(clearance - np.array(truth)[:len(clearance)]).max() <= 1e-12


def _obstacle_scene(weight: object) -> Scene:
    """The crowdnav corridor, a cart (a circle obstacle) driving west along y = 5.3 at
    0.4 m/s, and a robot without a controller standing still in its path."""
    data = load_yaml((default_scene_path().parent / "crowdnav.yaml").read_text())
    data["obstacles"] = [{"kind": "circle", "center": [12.5, 5.3], "radius": 0.4,
                          "velocity": [-0.4, 0.0]}]
    robot = data["robots"][0]
    del robot["controller"], robot["scan"]
    robot["pose"], robot["weight"] = [8.0, 5.3, 0.0], weight
    return Scene.from_dict(data)


def test_a_moving_obstacle_running_into_a_prescribed_robot_is_named_with_its_fix():
    """A robot of weight inf cannot yield: the step that the cart would push it fails, named
    as that (not as a solver's inaccuracy, whose fix, a tighter tol or smaller dt, cannot
    help), and leaves the simulation as before it."""
    from sweep_core.errors import InfeasibleError

    sim = Simulator(_obstacle_scene("inf"), dt=0.05, seed=1)
    with pytest.raises(InfeasibleError) as err:
        for _ in range(300):
            sim.step(1)
    text = str(err.value)
    assert "robot robot overlaps obstacles[0] (circle)" in text
    assert "moves" in text and "finite weight" in text and "tol" not in text
    t, pose = sim.t, sim.robots.state("robot").pose
    with pytest.raises(InfeasibleError):
        sim.step(1)
    assert sim.t == t and sim.robots.state("robot").pose == pose
    # of weight 1 the cart pushes it along, as it pushes people
    pushed = Simulator(_obstacle_scene(1), dt=0.05, seed=1)
    pushed.step(300)
    assert pushed.robots.state("robot").pose[0] < 7.0


@pytest.mark.parametrize("sinks", [False, True])
def test_a_prescribed_robot_pushing_a_robot_of_finite_weight_reports_no_person(sinks):
    """Robot ``robot`` (weight inf) drives into robot ``second`` (weight 1, a variable of the
    projection after the people): their contact is no person's, so neither robot's
    contact_ids names it (it had been reported as person N, the other robot's row; with
    flows, that row has no id)."""
    data = load_yaml((default_scene_path().parent / "crowdnav.yaml").read_text())
    if sinks:
        data["flows"]["sinks"] = [{"kind": "rectangle", "min": [-2.0, 0.0], "max": [0.5, 6.0]}]
    first = data["robots"][0]
    del first["controller"], first["scan"]
    second = dict(first, name="second", pose=[1.8, 3.0, 0.0], weight=1)
    data["robots"].append(second)
    sim = Simulator(Scene.from_dict(data), dt=0.05, seed=0)
    sim.robots.command("robot", (0.5, 0.0, 0.0))
    for _ in range(30):
        sim.step(1)
        for name in ("robot", "second"):
            st = sim.robots.state(name)
            assert set(st.contact_ids.tolist()) <= set(sim.ids.tolist())
            assert len(st.contact_xy) == len(st.contact_impulse) == len(st.contact_ids)
    assert sim.robots.state("second").pose[0] > 1.9  # it was pushed: the robots touched


@pytest.mark.parametrize("controller", ["social_force", "window", "orca"])
def test_a_reset_runs_the_bundled_planners_as_a_new_simulator_does(controller):
    """Simulator.reset (the node's reset service, sweep replay's segments) is back to t = 0
    for the robots' bundled planners too: the social force model's own velocity and the
    window planner's last choice are forgotten, so the run after a reset is a fresh one's."""
    data = load_yaml((default_scene_path().parent / "crowdnav.yaml").read_text())
    data["agents"]["radius"] = RADII
    data["flows"]["sinks"] = [{"kind": "rectangle", "min": [-2.0, 0.0], "max": [2.5, 6.0]}]
    data["robots"][0]["controller"] = controller
    scene = Scene.from_dict(data)
    again = Simulator(scene, dt=0.05, seed=3)
    again.step(150)
    again.reset()
    again.step(150)
    fresh = Simulator(scene, dt=0.05, seed=3)
    fresh.step(150)
    assert again.robots.state("robot").pose == fresh.robots.state("robot").pose
    assert np.array_equal(again.positions, fresh.positions)
