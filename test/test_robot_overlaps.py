"""The fleet's check after a step (``robots.overlaps.check_step``): the people's gaps computed
once and the robots' in one compiled pass say what everyone's gaps together say."""
from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np
import pytest

import sweep_core as sc
from sweep_core.errors import InfeasibleError
from sweep_core.model.gaps import gaps, smallest_gap
from sweep_core.model.scene import load_scene
from sweep_core.numerics.robots.overlaps import TOLERANCE, check_step

WALLS = [{"kind": "halfplane", "normal": [0, 1], "offset": 0.0},
         {"kind": "segment", "a": [4.0, -1.0], "b": [4.0, 5.0]},
         {"kind": "polyline", "points": [[-1.0, 4.0], [2.0, 4.2], [5.0, 4.0]]}]
OBSTACLES = [{"kind": "circle", "center": [2.0, 2.0], "radius": 0.3}]


def verdict_together(geom, states, y, r1, t1) -> str | None:
    """Everyone's gaps in one call (people first, then the robots): the overlap message, or
    None."""
    n = len(y)
    centres = np.array([s.pose[:2] for s in states]).reshape(-1, 2)
    radii = np.array([s.robot.radius for s in states])
    g = gaps(geom, t1, np.concatenate([y, centres]), np.concatenate([r1, radii]))

    def who(i: int) -> str:
        return f"robot {states[i - n].robot.name}" if i >= n else f"agent {i}"

    if g.min_gap >= -TOLERANCE:
        return None
    if g.min_pair <= g.min_single and g.worst_pair is not None:
        i, j, _ = g.worst_pair
        return f"{who(int(i))} and {who(int(j))} overlap by {-g.min_gap:.3g} m"
    i, kind, item, _ = g.worst_single
    return f"{who(int(i))} overlaps {geom.describe(int(kind), int(item))} by {-g.min_gap:.3g} m"


def robot(name: str, x: float, y: float, radius: float) -> SimpleNamespace:
    return SimpleNamespace(pose=(x, y, 0.0), robot=SimpleNamespace(name=name, radius=radius))


@pytest.mark.parametrize("seed", range(40))
def test_the_check_says_what_everyones_gaps_say(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(0, 12))
    y = rng.uniform(0.0, 4.0, (n, 2))
    r1 = rng.uniform(0.1, 0.3, n)
    spec = {"agents": {"positions": [[10.0, 10.0]], "radius": 0.2}, "walls": WALLS,
            "obstacles": OBSTACLES}
    geom = sc.Scene.from_dict(spec).geometry
    states = [robot(f"r{k}", *rng.uniform(0.0, 4.0, 2), float(rng.uniform(0.2, 0.4)))
              for k in range(int(rng.integers(1, 4)))]
    want = verdict_together(geom, states, y, r1, 0.5)
    start = [s.pose for s in states]  # no robot moved: no crossing
    if want is None:
        people = check_step(geom, states, start, y, r1, 0.5)
        assert people is not None
        ref = gaps(geom, 0.5, y, r1)
        assert (people.min_pair, people.min_single, people.worst_pair, people.worst_single) \
            == (ref.min_pair, ref.min_single, ref.worst_pair, ref.worst_single)
    else:
        with pytest.raises(InfeasibleError) as err:
            check_step(geom, states, start, y, r1, 0.5)
        assert want in str(err.value)


def test_each_kind_of_overlap_is_named() -> None:
    geom = sc.Scene.from_dict({"agents": {"positions": [[10.0, 10.0]], "radius": 0.2},
                               "walls": WALLS, "obstacles": OBSTACLES}).geometry
    y, r1 = np.array([[1.0, 1.0]]), np.array([0.25])
    cases = [([robot("a", 1.4, 1.0, 0.3)], "agent 0 and robot a overlap by 0.15 m"),
             ([robot("a", 3.0, 1.0, 0.3), robot("b", 3.5, 1.0, 0.3)],
              "robot a and robot b overlap by 0.1 m"),
             ([robot("a", 3.0, 0.25, 0.3)], "robot a overlaps walls[0] (halfplane) by 0.05 m"),
             ([robot("a", 3.8, 1.0, 0.3)], "robot a overlaps walls[1] (segment) by 0.1 m"),
             ([robot("a", 2.0, 2.5, 0.3)], "robot a overlaps obstacles[0] (circle) by 0.1 m")]
    for states, text in cases:
        assert verdict_together(geom, states, y, r1, 0.5) == text
        with pytest.raises(InfeasibleError, match=re.escape(text)):
            check_step(geom, states, [s.pose for s in states], y, r1, 0.5)


def test_a_robot_through_a_wall_is_found() -> None:
    geom = sc.Scene.from_dict({"agents": {"positions": [[10.0, 10.0]], "radius": 0.2},
                               "walls": WALLS}).geometry
    states = [robot("a", 4.5, 1.0, 0.3)]
    with pytest.raises(InfeasibleError, match="robot a went through a wall"):
        check_step(geom, states, [(3.5, 1.0, 0.0)], np.empty((0, 2)), np.empty(0), 0.5)


def test_the_simulator_takes_the_peoples_gaps_from_the_check() -> None:
    """crowdnav: the simulator's post-step check computes no gaps of its own (the robots'
    check did), and its minimum gap is the people's."""
    from importlib import resources

    import sweep_core.numerics.simulator as simulator
    scene = load_scene(str(resources.files("sweep_core") / "scenes" / "crowdnav.yaml"))
    sim = sc.Simulator(scene, 0.1, 0)
    calls = []
    real = simulator.gaps

    def counted(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    simulator.gaps = counted
    try:
        for _ in range(30):
            sim.step()
            q, r = sim.positions, scene.radii(sim.t)
            assert sim.min_gap == smallest_gap(gaps(scene.geometry, sim.t, q, r), q, r)[0]
    finally:
        simulator.gaps = real
    assert not calls


@pytest.mark.parametrize("where", ["person", "robot", "halfplane", "segment", "circle"])
def test_a_nan_value_of_any_kind_is_reported_as_nan(where: str) -> None:
    """robot_gaps' kind is NAN when any one value is NaN, whichever kind and wherever it comes
    in the pass (a smaller finite value before or after it does not hide it)."""
    from sweep_core.numerics.robots.overlaps import NAN, robot_gaps

    c, rc = np.array([[0.0, 0.0], [3.0, 0.0]]), np.array([0.3, 0.3])
    q, r = np.array([[1.0, 0.0], [0.3, 0.0]]), np.array([0.2, 0.2])
    hn, hc = np.array([[0.0, 1.0]]), np.array([-2.0])
    sa, sb = np.array([[-1.0, 1.0]]), np.array([[1.0, 1.0]])
    cc, cr = np.array([[0.0, -1.0]]), np.array([0.2])
    arrays = {"person": q, "robot": c, "halfplane": hc, "segment": sb, "circle": cr}
    out = np.empty(4)
    robot_gaps(c, rc, q, r, hn, hc, sa, sb, cc, cr, out)
    assert out[1] >= 0 and out[0] == pytest.approx(-0.2)  # robot 0 and person 1 overlap
    target = arrays[where]
    target.reshape(-1)[-1] = np.nan
    robot_gaps(c, rc, q, r, hn, hc, sa, sb, cc, cr, out)
    assert out[1] == NAN
