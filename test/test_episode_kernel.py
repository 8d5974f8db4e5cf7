"""The environment's compiled record of a step (:mod:`sweep_core.numerics.robots.episode`) and
its action checks (:mod:`sweep_core.envs.actions`) give the bits of the Python they replace:
``analysis.social.nearest``, the goal field's ``travel_distance`` clamped to the grid plus
Python's ``math.hypot`` off it, the odometry and the goal in base_link, the bounded scan, the
contacts' impulses summed, and numpy's checks and clip of an action; and the comparison fails
for a kernel one ulp off."""
from __future__ import annotations

import copy
import math
from collections.abc import Callable
from importlib.resources import files

import numpy as np
import pytest
from gymnasium import spaces

from sweep_core.analysis import social
from sweep_core.envs.actions import Actions
from sweep_core.envs.crowdnav import CrowdNavEnv
from sweep_core.errors import SceneError
from sweep_core.model import elementary
from sweep_core.model.scene import load_scene
from sweep_core.numerics.robots import episode
from sweep_core.numerics.robots.scan import bounded_ranges

CROWDNAV = str(files("sweep_core") / "scenes" / "crowdnav.yaml")


@pytest.fixture(scope="module")
def env() -> CrowdNavEnv:
    return CrowdNavEnv(max_steps=50)


def bits(values: list[float]) -> bytes:
    return np.array(values, dtype=np.float64).tobytes()


def distance_to_go(env: CrowdNavEnv, x: float, y: float) -> float:
    """The goal field's distance (m) at (x, y) clamped to its grid, plus the straight line
    from there (Python's hypot): the environment's Python path, ``_togo``."""
    return env._togo(x, y)


def reference(env: CrowdNavEnv, case: dict) -> list[float]:
    """What the environment computed in Python before the kernel (its _record, _togo and
    _observe): vx, vy, clearance, ttc, distance to go, odom (6), goal in base_link (2),
    the bounded ranges."""
    x, y, yaw = case["pose"]
    u, w, omega = case["twist"]
    s, c = elementary.sincos(yaw)
    vx, vy = c * u - s * w, s * u + c * w
    near, ttc = social.nearest(np.array([x, y]), np.array([vx, vy]), case["radius"],
                               case["people"], case["radii"], case["velocities"])
    togo = distance_to_go(env, x, y)
    goal = env.spec_robot.goal
    dx, dy = float(goal[0]) - x, float(goal[1]) - y
    ranges = np.empty(len(case["ranges"]))
    bounded_ranges(case["ranges"], 8.0, ranges)
    imp = case["impulses"]
    imp = np.hypot(imp[:, 0], imp[:, 1])
    total, most = (float(imp.sum()), float(imp.max())) if len(imp) else (0.0, 0.0)
    return [vx, vy, near, ttc, togo, x, y, yaw, u, w, omega, c * dx + s * dy,
            -s * dx + c * dy, *ranges.tolist(), len(imp), total, most]


def compiled(env: CrowdNavEnv, case: dict, record: Callable[..., None]) -> list[float]:
    """The same values from ``record`` (episode.record or a stand-in), completed as the
    environment completes them (Python's hypot off the grid)."""
    x, y, yaw = case["pose"]
    out, odom, goal = np.empty(episode.OUT), np.empty(6), np.empty(2)
    scan = np.empty(len(case["ranges"]))
    record(x, y, yaw, *case["twist"], 0.5, case["radius"], case["people"], case["radii"],
           case["velocities"], *env.grid, *env.goal_xy, len(case["impulses"]),
           case["impulses"], case["ranges"], 8.0, out, odom, goal, scan)
    togo, cx, cy = out[episode.TOGO], out[episode.CLAMPED_X], out[episode.CLAMPED_Y]
    if cx != x or cy != y:
        togo += math.hypot(x - cx, y - cy)
    return [out[4], out[5], out[6], out[7], float(togo), *odom.tolist(), *goal.tolist(),
            *scan.tolist(), out[8], out[9], out[10]]


def cases(env: CrowdNavEnv, count: int = 400) -> list[dict]:
    """Random robots and crowds, on the goal field's grid and off it, people overlapping the
    robot, velocities unknown (NaN), no people, odd ranges."""
    rng = np.random.default_rng(7)
    lo = np.array([env.field.x[0], env.field.y[0]]) - 3.0
    hi = np.array([env.field.x[-1], env.field.y[-1]]) + 3.0
    out = []
    for k in range(count):
        n = int(rng.integers(0, 12))
        pose = [*rng.uniform(lo, hi).tolist(), float(rng.uniform(-8.0, 8.0))]
        people = rng.uniform(lo, hi, (n, 2))
        if n and k % 3 == 0:  # someone within reach of the robot
            people[0] = np.array(pose[:2]) + rng.normal(0.0, 0.3, 2)
        velocities = rng.normal(0.0, 1.0, (n, 2))
        if n and k % 4 == 0:
            velocities[rng.uniform(size=n) < 0.5] = np.nan
        impulses = rng.exponential(0.2, (int(rng.choice([0, 0, 1, 2, 5, 9, 17])), 2))
        impulses *= np.where(rng.uniform(size=impulses.shape) < 0.5, -1.0, 1.0)
        if k % 5 == 0:
            impulses[: k % 3] = 0.0
        ranges = rng.uniform(-1.0, 10.0, 9)
        ranges[rng.integers(0, 9, 3)] = [np.nan, np.inf, -np.inf]
        out.append({"pose": pose, "twist": rng.normal(0.0, 1.0, 3).tolist(),
                    "radius": float(rng.uniform(0.1, 0.5)), "people": people,
                    "radii": rng.uniform(0.1, 0.4, n), "velocities": velocities,
                    "ranges": ranges, "impulses": impulses})
    return out


def mismatches(env: CrowdNavEnv, record: Callable[..., None]) -> int:
    return sum(bits(reference(env, c)) != bits(compiled(env, c, record)) for c in cases(env))


def test_the_kernel_gives_the_python_values_bit_for_bit(env) -> None:
    assert mismatches(env, episode.record) == 0
    # the cases reach off the grid, no people, unknown velocities, contact
    off = [c for c in cases(env) if not env.field.x[0] <= c["pose"][0] <= env.field.x[-1]]
    assert off and any(len(c["people"]) == 0 for c in cases(env))


@pytest.mark.parametrize("slot", [4, 6, 7, 9, 10, episode.TOGO, "odom", "goal"])
def test_a_kernel_one_ulp_off_is_caught(env, slot) -> None:
    def mutated(*args: object) -> None:
        episode.record(*args)
        out, odom, goal = args[-4], args[-3], args[-2]
        target, k = ((odom, 3) if slot == "odom" else (goal, 1) if slot == "goal"
                     else (out, slot))
        target[k] = np.nextafter(target[k], np.inf)  # type: ignore[index]
    assert mismatches(env, mutated) > 0


def test_the_recorded_rows_are_the_references_at_each_step() -> None:
    """The environment's rows and distance to go after each step, on the grid and driven off
    it (westward), are social.nearest's and the goal field's of the engine's state."""
    spec = copy.deepcopy(load_scene(CROWDNAV).spec)
    spec["robots"][0]["pose"] = [1.0, 3.0, math.pi]
    env = CrowdNavEnv(scene=spec, max_steps=80)
    env.reset(seed=3)
    off = 0
    for _ in range(60):
        env.step(np.array([1.0, 0.2]))
        row, st, sim = env.rows[-1], env.sim.robots.state(env.name), env.sim
        near, ttc = social.nearest(np.array(row[1:3]), np.array(row[4:6]), env.spec_robot.radius,
                                   sim.positions, sim.radii, sim.velocities)
        assert bits([near, ttc]) == bits(row[6:8])
        assert bits([env.togo]) == bits([distance_to_go(env, *st.pose[:2])])
        off += row[1] < env.field.x[0]
    assert off > 0


def numpy_command(box: spaces.Box, holonomic: bool, action: object) -> tuple:
    a = np.minimum(np.maximum(np.asarray(action, dtype=np.float64).reshape(-1), box.low),
                   box.high)
    return (a[0], a[1], a[2]) if holonomic else (a[0], 0.0, a[1])


@pytest.mark.parametrize("holonomic", [False, True])
@pytest.mark.parametrize("high", [1.5, 0.0])
def test_actions_are_clipped_as_numpy_clips_them(holonomic, high) -> None:
    n = 3 if holonomic else 2
    box = spaces.Box(-np.full(n, high), np.full(n, high), dtype=np.float64)
    actions = Actions(box, holonomic)
    assert actions.fast == (high > 0)
    rng = np.random.default_rng(1)
    edge = [0.0, -0.0, high, -high, 2.0 * high + 1.0, -2.0 * high - 1.0, 1e-300, -5e-324]
    tried = [rng.uniform(-3.0, 3.0, n) for _ in range(200)]
    tried += [rng.choice(edge, n) for _ in range(200)]
    for a in tried:
        assert bits(list(actions.command(a))) == bits(list(numpy_command(box, holonomic, a)))
    for bad in ([np.nan] + [0.0] * (n - 1), [np.inf] + [0.0] * (n - 1), [0.0] * (n - 1)):
        with pytest.raises(SceneError, match=f"must be {n} finite numbers"):
            actions.command(np.array(bad))
