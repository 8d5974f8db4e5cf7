"""A simple robot step taken in one compiled call (``robots.clear_step``) has the bits the
general path gives it, and every step that is not simple goes to the general path."""
from __future__ import annotations

import hashlib

import numpy as np
import pytest

import sweep_core as sc
from sweep_core.model.scene import load_scene
from sweep_core.numerics import simulator
from sweep_core.numerics.robots import clear_step, fleet, overlaps, small_step

WALLS = [{"kind": "segment", "a": [-1.0, 0.0], "b": [9.0, 0.0]},
         {"kind": "segment", "a": [-1.0, 4.0], "b": [9.0, 4.0]},
         {"kind": "halfplane", "normal": [1.0, 0.0], "offset": -1.0}]


def two_robots(sigma: float) -> sc.Scene:
    """People walking slowly west between two walls, a circle obstacle, and two prescribed robots:
    ``a`` driving east towards ``b``, then turning towards the lower wall, ``b`` turning
    towards the upper wall (:func:`run`'s commands)."""
    rng = np.random.default_rng(5)
    q = np.column_stack([rng.uniform(3.0, 8.0, 12), rng.uniform(0.5, 3.5, 12)])
    q = q[np.argsort(q[:, 0])]
    keep: list[int] = []
    for k in range(len(q)):  # people clear of each other and of the obstacle
        if (np.hypot(*(q[k] - [5.0, 2.0])) > 0.6
                and (not keep or np.min(np.hypot(*(q[keep] - q[k]).T)) > 0.55)):
            keep.append(k)
    kin = {"type": "diff_drive", "max_speed": 1.2, "max_angular_speed": 2.0,
           "max_acceleration": 3.0, "max_angular_acceleration": 6.0}
    return sc.Scene.from_dict({
        "agents": {"positions": q[keep].tolist(), "radius": 0.25},
        "drift": {"kind": "goal", "goal": [-2.0, 2.0], "speed": 0.3},
        "noise": {"sigma": sigma},
        "walls": WALLS,
        "obstacles": [{"kind": "circle", "center": [5.0, 2.0], "radius": 0.3}],
        "robots": [{"name": "a", "radius": 0.3, "pose": [0.5, 2.0, 0.0], "kinematics": kin,
                    "weight": "inf"},
                   {"name": "b", "radius": 0.3, "pose": [1.6, 2.0, 0.0], "kinematics": kin,
                    "weight": "inf"}]})


def run(scene: sc.Scene, steps: int, dt: float, commands: bool) -> tuple[str, dict]:
    """A hash of everything a step leaves (people, robots' poses, twists, contacts, stops, the
    projection's rows, multipliers, counts and bound, the smallest gap) over ``steps`` steps,
    and the steps in which a robot was stopped."""
    sim = sc.Simulator(scene, dt=dt, seed=3)
    h = hashlib.sha256()
    for k in range(steps):
        if commands:
            sim.robots.command("a", (1.2, 0.0, 0.0) if k < 20 else
                               (0.5, 0.0, -1.2) if k < 40 else (0.0, 0.0, 0.0))
            sim.robots.command("b", (0.4 if k < 30 else 0.0, 0.0, 1.0 if k < 40 else 0.0))
        index = sim.robots.step_index
        sim.step()
        assert sim.robots.step_index == index + 1
        h.update(sim.positions.tobytes())
        for name in sim.robots.names:
            st = sim.robots.state(name)
            h.update(np.array(st.pose + st.twist + st.command).tobytes())
            h.update(st.contact_ids.tobytes() + st.contact_impulse.tobytes()
                     + st.contact_xy.tobytes())
            h.update(f"{st.blocked} {st.stopped}".encode())
        proj = sim.last.projection
        h.update(np.array([proj.active, sim.min_gap, proj.qp_size, proj.solves, proj.bound,
                           proj.sweeps]).tobytes())
        h.update(proj.lam_pair.tobytes() + proj.lam_single.tobytes() + proj.y.tobytes())
        for name in proj.rows.__dataclass_fields__:
            h.update(np.ascontiguousarray(getattr(proj.rows, name)).tobytes())
    blocked = sum(sim.robots.state(name).blocked for name in sim.robots.names)
    return h.hexdigest(), blocked


def counted(monkeypatch: pytest.MonkeyPatch, taken: dict, paths: list) -> None:
    """Counts the steps the compiled call takes (simple ones, with no row, and those with
    contacts, projected in the call) and those it sends to the general path; ``paths`` gets
    whether each step it took found the people's paths clear of the walls."""
    original = small_step.simple_step

    def wrapped(*args, **kwargs):
        out = original(*args, **kwargs)
        if isinstance(out, tuple):
            taken["contact" if out[0].rows.count else "simple"] += 1
            paths.append(out[3])
        else:
            taken["general"] += 1
        return out

    monkeypatch.setattr(small_step, "simple_step", wrapped)


@pytest.mark.parametrize("case", ["crowdnav", "two robots", "two robots, noisy"])
def test_simple_steps_have_the_general_paths_bits(monkeypatch: pytest.MonkeyPatch,
                                                  case: str) -> None:
    """Runs with the compiled call and with the general path alone give the same bits; each
    run takes both (so that the cases the call sends back are covered too)."""
    if case == "crowdnav":
        scene, steps, dt, commands = load_scene("crowdnav"), 150, 0.1, False
    else:
        scene, steps, dt, commands = two_robots(0.4 if "noisy" in case else 0.05), 120, 0.05, True
    taken = {"simple": 0, "contact": 0, "general": 0}
    taken_paths: list[bool] = []
    counted(monkeypatch, taken, taken_paths)
    checked, ends = [], []
    crossings = simulator.crossings
    monkeypatch.setattr(simulator, "crossings", lambda *a: checked.append(1) or crossings(*a))
    checked_end = fleet.checked_end
    monkeypatch.setattr(fleet, "checked_end", lambda *a: ends.append(checked_end(*a)) or ends[-1])
    fast, blocked = run(scene, steps, dt, commands)
    assert taken["simple"] > 10 and taken["contact"] > 3, taken
    assert taken["general"] > 3 or case == "crowdnav", taken
    assert blocked > 0 or case == "crowdnav"  # robots stopped by the settle too
    # every step the call sends back ends on the general path's check; a step taken here, or
    # a general one whose end check found the same, checked the people's paths (none might
    # cross a wall): the simulator does not check them again
    assert len(ends) == taken["general"]
    assert 0 < sum(taken_paths) + sum(p for _, p in ends)
    assert len(checked) == sum(not p for _, p in ends) + sum(not p for p in taken_paths)
    monkeypatch.setattr(clear_step, "applies", lambda *args: False)
    monkeypatch.setattr(small_step, "applies", lambda *args: False)
    general, _ = run(scene, steps, dt, commands)
    assert fast == general


def test_a_stop_a_row_a_wall_or_nan_is_not_simple() -> None:
    """The compiled call answers only simple steps: a target overlapping another robot's or a
    wall sends the step back to the settle (NOT_CLEAR); a prediction failing a row, a robot's
    path through a wall, or NaN send it back past the settle (SETTLED); a simple one gives
    the rows holding with equality."""
    geom = two_robots(0.0).geometry
    hn, hc, sa, sb, cc, cr = geom.packed
    q = np.array([[3.0, 1.0], [3.0, 3.0]])
    r1 = np.full(2, 0.25)
    radius = np.full(2, 0.3)

    def verdict(pred, start, target, moving=(True, True)) -> int:
        n, ns = len(q), len(sa)
        ints = [np.empty(size, dtype=np.intp) for size in (4 * n, 4 * n, n * ns, n * ns)]
        return clear_step.clear_robot_step(
            q, np.asarray(pred, dtype=np.float64), r1, np.asarray(start, dtype=np.float64),
            np.asarray(target, dtype=np.float64), radius, np.array(moving), hn, hc, sa, sb,
            cc, cr, geom.static_segments, 1 << 16, True, ints[0], ints[1], np.empty(4 * n),
            np.empty(n * (len(hc) + ns + len(cr))), ints[2], ints[3],
            np.empty(2 * n * ns, dtype=np.intp), np.empty(2 * n * ns, dtype=np.intp),
            np.empty(2 * n * ns, dtype=np.bool_), np.empty(12))

    start = [[1.0, 2.0], [2.0, 2.0]]
    simple = [[1.05, 2.0], [2.05, 2.0]]
    assert verdict(q + 0.01, start, simple) == 0
    # people touching exactly at the prediction: one pair row holds with equality
    assert verdict([[3.0, 1.5], [3.0, 2.0]], start, simple) == 1
    # the settle would stop a robot: a's target on b's, b's in a wall
    assert verdict(q, start, [[1.5, 2.0], [2.05, 2.0]]) == clear_step.NOT_CLEAR
    assert verdict(q, start, [[1.05, 2.0], [2.05, 0.2]]) == clear_step.NOT_CLEAR
    # no robot stops, but the step is not simple: b goes through the wall (not moving, so not
    # settled), a person's prediction fails a pair row, or a robot's disk, or is NaN
    assert verdict(q, [[1.05, 2.0], [2.0, 2.0]], [[1.05, 2.0], [2.0, -0.5]],
                   (False, False)) == clear_step.SETTLED
    assert verdict([[3.0, 1.0], [3.0, 1.2]], start, simple) == clear_step.SETTLED
    assert verdict([[3.0, 1.0], [2.2, 2.0]], start, simple) == clear_step.SETTLED
    assert verdict([[np.nan, 1.0], [3.0, 3.0]], start, simple) == clear_step.SETTLED


def test_it_applies_only_to_small_static_scenes() -> None:
    geom = two_robots(0.0).geometry
    assert clear_step.applies(geom, 12, True, False)
    assert not clear_step.applies(geom, 12, False, False)  # a robot of finite weight
    assert not clear_step.applies(geom, 12, True, True)  # a map of blocked cells
    assert not clear_step.applies(geom, 0, True, False)
    assert not clear_step.applies(geom, 65, True, False)
    moving = load_scene("moving_obstacle").geometry
    assert moving.is_moving and not clear_step.applies(moving, 10, True, False)


def end_of(steps: int) -> tuple:
    """crowdnav after ``steps`` steps: its geometry, the people's positions before the next
    step and at its end (their prediction), radii, the robots' states and their poses."""
    sim = sc.Simulator(load_scene("crowdnav"), dt=0.1, seed=3)
    sim.step(steps)
    states = list(sim.robots.states.values())
    q = sim.positions.copy()
    y = q + np.random.default_rng(steps).normal(0.0, 0.01, q.shape)
    return (sim.scene.geometry, sim.t + sim.dt, q, y, sim.radii.copy(), states,
            [st.pose for st in states])


def outcome(call) -> tuple:
    try:
        return ("ok", call())
    except sc.InfeasibleError as e:
        return ("error", str(e))


@pytest.mark.parametrize("steps", [0, 12, 40])
def test_the_end_check_is_check_steps(steps: int) -> None:
    """checked_end against check_step on crowdnav's states: the same people's gaps, paths
    called clear only where the crossing check finds nothing; a person on the robot, a robot
    through a wall and a NaN radius: the same error (or, NaN, the same answer)."""
    geom, t1, q, y, r1, states, start = end_of(steps)
    gaps, paths = clear_step.checked_end(geom, t1, q, y, r1, states, start, False)
    want = overlaps.check_step(geom, states, start, y, r1, t1)
    assert repr(gaps) == repr(want)
    assert paths and not len(simulator.crossings(geom, q, y, r1, want)[0])
    robot = states[0].pose
    on_robot = y.copy()
    on_robot[3] = [robot[0] + 0.1, robot[1]]
    through = [(robot[0], -1.0, robot[2])]  # from beyond the wall below (y = 0)
    nan = r1.copy()
    nan[2] = np.nan
    for yy, rr, ss in ((on_robot, r1, start), (y, r1, through), (y, nan, start)):
        fast = outcome(lambda: clear_step.checked_end(geom, t1, q, yy, rr, states, ss, False))
        slow = outcome(lambda: (overlaps.check_step(geom, states, ss, yy, rr, t1), False))
        assert repr(fast) == repr(slow)
    assert outcome(lambda: overlaps.check_step(geom, states, through, y, r1, t1))[0] == "error"
