"""``sweep/CrowdNav-v0``: one robot of a scene driven through its crowd, headless and seeded.

An episode is one run of the scene: :meth:`CrowdNavEnv.reset` builds a
:class:`~sweep_core.numerics.simulator.Simulator` with an engine seed drawn from the
environment's generator (so ``reset(seed=s)`` fixes the whole episode: the crowd's noise and the
scan's noise), and each :meth:`CrowdNavEnv.step` holds the action as the robot's command for one
step of ``dt`` s, as ``sweep run`` does with a controller. A seeded episode is reproduced bit for
bit (the engine's steps are).

Spaces (float64):

* action: the robot's command in its own frame (base_link): ``(v, omega)`` for a
  ``diff_drive`` robot, ``(vx, vy, omega)`` for a ``holonomic`` one (m/s, rad/s), boxed by its
  ``max_speed`` and ``max_angular_speed``; the engine clips it further (acceleration limits,
  |(vx, vy)| <= max_speed) and counts the clipped commands (``info["clipped"]``).
* observation, a dict: ``odom`` (x, y, yaw, vx, vy, omega: the pose in the map frame (m, rad)
  and the twist achieved over the last step in base_link (m/s, rad/s)), ``scan`` (the latest
  scan's ranges (m), clipped to [0, range_max]: nothing within range reads range_max), ``goal``
  (the goal in base_link, m).

Reward per step: the progress along the geodesic distance to the goal (m, round the walls; off
the goal field's grid, its distance at the grid's nearest point plus the straight line from
there), plus ``success_reward`` on reaching the goal, minus ``contact_penalty`` for a step
ending in contact with someone, minus ``discomfort_penalty * dt * (0.2 - clearance)`` when
closer than 0.2 m (the CrowdNav reward's shape). The episode terminates when the robot is
within its ``goal_radius`` of the goal, and is truncated after ``max_steps`` steps.

``info``: ``t_s``, ``clearance_m`` (to the nearest person), ``ttc_s``, ``contacts``,
``clipped``, ``blocked``; at the end of an episode also ``metrics``, the social-navigation
metrics of :mod:`sweep_core.analysis.social` (docs/social_metrics.md), computed by the functions
``sweep analyze`` uses on a recording (here from the engine's float64 state, where a recording
holds the people's velocities in float32).
"""
from __future__ import annotations

import math
import os
from dataclasses import replace
from importlib import resources
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from sweep_core import checks
from sweep_core.analysis import social
from sweep_core.envs.actions import Actions
from sweep_core.errors import SceneError, show
from sweep_core.io import limits
from sweep_core.model.scene import Scene, load_scene
from sweep_core.numerics.robots import episode
from sweep_core.numerics.robots.scan import bounded_ranges
from sweep_core.numerics.simulator import Simulator

#: the bundled scene of ``gymnasium.make("sweep/CrowdNav-v0")`` without a scene
DEFAULT_SCENE = Path(str(resources.files("sweep_core") / "scenes" / "crowdnav.yaml"))


#: share of the available memory an environment's episodes (or a vector environment's K)
#: may take
MEMORY_SHARE = 0.5
#: bytes an episode's history (its rows and contacts) keeps per step, rounded up (about
#: 1.6 kB measured on the bundled scene)
HISTORY_BYTES = 2048


def available_memory() -> int:
    """Bytes of memory available to a new allocation (MemAvailable of /proc/meminfo, else the
    physical memory)."""
    try:
        with Path("/proc/meminfo").open() as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))


#: the arguments of :class:`CrowdNavEnv` (an unknown one is refused naming them)
ARGUMENTS = ("scene", "robot", "dt", "max_steps", "scheme", "success_reward",
             "contact_penalty", "discomfort_penalty", "render_mode")
#: what a refused render mode or render() call says to do instead
NO_RENDER = ("leave render_mode unset (None); to watch the scene, record a run with `sweep run "
             "SCENE --out run.mcap` and animate it with `sweep render run.mcap` "
             "(docs/render.md)")


def check_render_mode(render_mode: Any) -> None:
    """Refuses a render mode other than None: the environment draws nothing."""
    if render_mode is not None:
        raise SceneError("render_mode", f"{show(render_mode)} is not available: the "
                         "environment draws nothing (its only render mode is None)", NO_RENDER)


def refuse_unknown(unknown: dict[str, Any], accepted: tuple[str, ...]) -> None:
    """Refuses the first of ``unknown`` keyword arguments, listing the ``accepted`` ones."""
    if unknown:
        name = next(iter(unknown))
        where = (" (workers and num_envs are the vector environment's: gymnasium.make_vec)"
                 if name in ("workers", "num_envs") and "workers" not in accepted else "")
        raise SceneError(name, f"is not an argument of sweep/CrowdNav-v0{where}",
                         f"give only {', '.join(accepted)}")


def check_options(options: Any, accepted: tuple[str, ...] = ()) -> None:
    """Refuses reset ``options`` that are neither None nor a dict, or that hold a key other
    than the ``accepted`` ones (a misspelt key would otherwise be ignored, silently)."""
    if options is None:
        return
    if not isinstance(options, dict):
        raise SceneError("options", f"must be a dict or None, got {show(options)} (a "
                         f"{type(options).__name__})", "give options=None or a dict")
    unknown = next((key for key in options if key not in accepted), None)
    if unknown is not None:
        takes = (f"takes only the key {', '.join(repr(a) for a in accepted)}" if accepted
                 else "takes no reset options")
        raise SceneError("options", f"has the key {show(unknown)}, but the environment "
                         f"{takes}", "remove the key (options=None resets with none)")


def seed_value(seed: Any) -> Any:
    """A 0-d numpy array as the scalar it holds (``np.array(3)`` is the seed 3, as numpy's
    generators read it), anything else as it is (then checked as a seed)."""
    return seed.item() if isinstance(seed, np.ndarray) and seed.ndim == 0 else seed


def _scene(scene: Scene | dict | str | Path | None) -> Scene:
    if isinstance(scene, Scene):
        return scene
    if isinstance(scene, dict):
        return Scene.from_dict(scene)
    return load_scene(str(scene if scene is not None else DEFAULT_SCENE))


class CrowdNavEnv(gymnasium.Env):
    """One robot of a scene among its people (module docstring).

    Args:
        scene: a Scene, a scene dict or a YAML path (default: the bundled ``crowdnav.yaml``);
            it needs a robot with a goal and a scan.
        robot: the robot's name (default: the scene's first robot).
        dt: time step (s) of the engine, one per :meth:`step`.
        max_steps: steps before the episode is truncated.
        scheme: the engine's scheme.
        success_reward, contact_penalty, discomfort_penalty: the reward's terms.
        render_mode: None only: the environment draws nothing (:func:`check_render_mode`).
    """

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(self, scene: Scene | dict | str | Path | None = None, robot: str | None = None,
                 dt: float = 0.1, max_steps: int = 500, scheme: str = "projected_euler",
                 success_reward: float = 1.0, contact_penalty: float = 0.25,
                 discomfort_penalty: float = 0.5, render_mode: str | None = None,
                 **unknown: Any) -> None:
        refuse_unknown(unknown, ARGUMENTS)
        check_render_mode(render_mode)
        self.render_mode = None
        self.scene = _scene(scene)
        robots = self.scene.spec.get("robots") or []
        if not robots:
            raise SceneError("robots", "the scene has no robot",
                             "add a robot with a goal and a scan to the scene's robots list")
        names = [r["name"] for r in robots]
        name = names[0] if robot is None else robot
        if name not in names:
            raise SceneError("robot", f"{name!r} is not a robot of the scene",
                             f"give one of {', '.join(names)}")
        self.name, self.index = name, names.index(name)
        spec = robots[self.index]
        field = f"robots[{self.index}]"
        if not spec.get("enabled", True):
            raise SceneError(f"{field}.enabled", f"is false: robot {name} is left out of the "
                             "run, so the environment has nothing to drive",
                             f"set {field}.enabled: true, or give another robot")
        if spec.get("goal") is None:
            raise SceneError(f"{field}.goal", "is missing: the environment drives to a goal",
                             f"give {field}.goal: [x, y]")
        if not spec.get("scan"):
            raise SceneError(f"{field}.scan", "is missing: the observation holds a scan",
                             f"give {field}.scan (range_max, angle_min, angle_max, increment)")
        self.dt = limits.check_dt(dt, "dt")  # the range of sweep run and sweep_node
        self.max_steps = checks.integer(max_steps, "max_steps", low=1, fix="e.g. max_steps=500")
        have = available_memory()
        if self.max_steps * HISTORY_BYTES > MEMORY_SHARE * have:
            most = int(MEMORY_SHARE * have // HISTORY_BYTES)
            raise SceneError("max_steps", f"{self.max_steps} steps is too long an episode: its "
                             f"history would need about {self.max_steps * HISTORY_BYTES / 1e9:.2g}"
                             f" GB, more than half the {have / 1e9:.2g} GB available",
                             f"max_steps={most} or fewer")
        self.scheme = scheme
        # a NaN or infinite term would make every reward NaN or infinite, silently
        self.rewards = tuple(checks.number(v, k, fix=f"set {k} to a finite number, e.g. {d}")
                             for k, v, d in (("success_reward", success_reward, 1.0),
                                             ("contact_penalty", contact_penalty, 0.25),
                                             ("discomfort_penalty", discomfort_penalty, 0.5)))
        self.spec_robot = social.RobotSpec(name, float(spec["radius"]),
                                           np.asarray(spec["goal"], dtype=np.float64)[:2],
                                           float(spec.get("goal_radius",
                                                          social.DEFAULT_GOAL_RADIUS)))
        start = np.asarray(spec["pose"], dtype=np.float64)[:2]
        self.field = social.goal_field(self.scene, self.spec_robot.goal, self.spec_robot.radius,
                                       start)
        self.geodesic = float(self.field.travel_distance(start[None, :])[0])
        # the goal field's grid as its travel_distance reads it (episode.record's arguments)
        self.grid = (np.ascontiguousarray(self.field.x, dtype=np.float64),
                     np.ascontiguousarray(self.field.y, dtype=np.float64),
                     np.ascontiguousarray(self.field.distance[:, :, None], dtype=np.float64))
        self.on_grid = self.field.x.size >= 2 and self.field.y.size >= 2
        self.goal_xy = (float(self.spec_robot.goal[0]), float(self.spec_robot.goal[1]))
        #: episode.record's row and scratch
        self.out = np.empty(episode.OUT)
        kin = spec.get("kinematics") or {}
        self.holonomic = kin.get("type") == "holonomic"
        vmax = float(kin.get("max_speed", 1.0))
        wmax = float(kin.get("max_angular_speed", 1.0))
        high = np.array([vmax, vmax, wmax] if self.holonomic else [vmax, wmax])
        self.box = spaces.Box(-high, high, dtype=np.float64)
        self.actions = Actions(self.box, self.holonomic)
        self.action_space = self.box
        self.range_max = float(spec["scan"].get("range_max", 10.0))
        # the scene the episodes run: this robot without its controller, which the actions
        # replace (building it, a navigation field, cost more than a hundred steps per reset)
        self.run_scene = replace(self.scene, robots=tuple(
            replace(r, controller="none", controller_params=()) if r.name == name else r
            for r in self.scene.robots))
        self.sim = self._simulator(0)
        self.beams = len(self._ranges())
        self.observation_space = spaces.Dict({
            "odom": spaces.Box(-np.inf, np.inf, shape=(6,), dtype=np.float64),
            "scan": spaces.Box(0.0, self.range_max, shape=(self.beams,), dtype=np.float64),
            "goal": spaces.Box(-np.inf, np.inf, shape=(2,), dtype=np.float64),
        })
        self.rows: list[tuple] = []
        self.touched: list[np.ndarray] = []
        self.steps, self.togo = 0, self.geodesic
        self.started = False  # reset() called: step() refuses to run before it
        #: how the episode ended (step() refuses to go on until reset()), None while it runs
        self.ended: str | None = None

    # -- the engine ---------------------------------------------------------------------

    def _simulator(self, seed: int) -> Simulator:
        """A new run of the scene; this robot is driven by the actions (its controller, if the
        scene gives one, is set aside; the scene's other robots keep theirs)."""
        sim = Simulator(self.run_scene, self.dt, seed, scheme=self.scheme)
        assert sim.robots is not None
        sim.robots.controllers.pop(self.name, None)
        return sim

    def _state(self) -> Any:
        assert self.sim.robots is not None
        return self.sim.robots.state(self.name)

    def _ranges(self) -> np.ndarray:
        scan = self._state().scan
        if scan is None:
            return np.full(0, self.range_max)
        # NaN read as range_max; then +inf (no return) becomes range_max and -inf (too close)
        # 0 by the clip, as nan_to_num's posinf and neginf would (compiled, one pass)
        ranges = np.ascontiguousarray(scan.ranges, dtype=np.float64)
        out = np.empty(len(ranges))
        bounded_ranges(ranges, self.range_max, out)
        return out

    def _take(self) -> tuple[dict[str, np.ndarray], tuple, int, float, Any]:
        """Appends this instant to the episode's series and observes it, in one compiled call
        (:func:`~sweep_core.numerics.robots.episode.record`): (the observation, the row
        appended, the contacts, the distance to go along the geodesic field (m), the robot's
        state)."""
        st, sim = self._state(), self.sim
        p, v = st.pose, st.twist
        x, y = float(p[0]), float(p[1])
        ids = np.asarray(st.contact_ids, dtype=np.int64).reshape(-1)
        # the impulses of the people in contact (none without contact)
        impulses = (np.ascontiguousarray(st.contact_impulse, dtype=np.float64).reshape(-1, 2)
                    if len(ids) else _NO_IMPULSES)
        scan = st.scan
        ranges = (_NO_RANGES if scan is None
                  else np.ascontiguousarray(scan.ranges, dtype=np.float64))
        if len(ranges) == self.beams:
            bounded = np.empty(self.beams)
        else:  # no scan taken yet
            ranges, bounded = _NO_RANGES, np.full(self.beams, self.range_max)
        odom, goal, out = np.empty(6), np.empty(2), self.out
        episode.record(x, y, float(p[2]), float(v[0]), float(v[1]), float(v[2]),
                       self.steps * self.dt, self.spec_robot.radius, sim.positions, sim.radii,
                       sim.velocities, *self.grid, *self.goal_xy, len(ids), impulses, ranges,
                       self.range_max, out, odom, goal, bounded)
        values = out.tolist()
        row = tuple(values[:11])
        self.rows.append(row)
        self.touched.append(ids)
        if self.on_grid:
            togo, cx, cy = values[episode.TOGO], values[episode.CLAMPED_X], \
                values[episode.CLAMPED_Y]
            if cx != x or cy != y:  # Python's hypot (not the C library's): _togo's bits
                togo += math.hypot(x - cx, y - cy)
        else:
            togo = self._togo(x, y)
        return {"odom": odom, "scan": bounded, "goal": goal}, row, len(ids), togo, st

    def _togo(self, x: float, y: float) -> float:
        """The distance to go (m) from (x, y): the goal field's geodesic distance on its grid;
        off the grid, its value at the grid's nearest point plus the straight distance from
        there (continuous at the grid's edge, growing as the robot goes further away)."""
        gx, gy = self.field.x, self.field.y
        cx = min(max(x, float(gx[0])), float(gx[-1]))
        cy = min(max(y, float(gy[0])), float(gy[-1]))
        togo = float(self.field.travel_distance(np.array([[cx, cy]]))[0])
        if cx != x or cy != y:
            togo += math.hypot(x - cx, y - cy)
        return togo

    def metrics(self) -> dict[str, Any]:
        """The social-navigation metrics of the episode so far (docs/social_metrics.md)."""
        a = np.array(self.rows, dtype=np.float64).reshape(-1, 11)
        series = social.Series(t=a[:, 0], pose=a[:, 1:4], vel=a[:, 4:6], clearance=a[:, 6],
                               ttc=a[:, 7], contacts=a[:, 8], impulse=a[:, 9],
                               impulse_max=a[:, 10], touched=self.touched)
        return social.episode_metrics(self.spec_robot, series, self.geodesic)

    # -- gymnasium ----------------------------------------------------------------------

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        check_options(options)
        if seed is not None:
            seed = checks.integer(seed_value(seed), "seed",
                                  fix="give seed as an integer >= 0, or None")
        super().reset(seed=seed)
        engine_seed = int(self.np_random.integers(0, 2**31 - 1))
        self.sim = self._simulator(engine_seed)
        self.rows, self.touched, self.steps = [], [], 0
        obs, row, contacts, self.togo, st = self._take()
        self.started, self.ended = True, None
        return obs, self._info(row, contacts, st)

    def step(self, action: Any) -> tuple[dict[str, np.ndarray], float, bool, bool,
                                         dict[str, Any]]:
        if not self.started:
            raise SceneError("step", "called before the first reset(): there is no episode "
                             "yet", "call reset() first")
        if self.ended is not None:  # its rewards (a goal's among them) would be given again
            raise SceneError("step", f"called after the episode ended ({self.ended})",
                             "call reset() to start the next episode")
        if action is None:
            raise SceneError("action", f"must be {self.box.shape[0]} finite numbers, got None",
                             "give an element of env.action_space")
        cmd = self.actions.command(action)
        assert self.sim.robots is not None
        self.sim.robots.command(self.name, cmd)
        self.sim.step()
        self.steps += 1
        before = self.togo
        obs, row, contacts, self.togo, st = self._take()
        near = row[6]
        gx, gy = self.goal_xy
        reached = math.hypot(row[1] - gx, row[2] - gy) <= self.spec_robot.goal_radius
        success, contact, discomfort = self.rewards
        reward = before - self.togo
        reward += success if reached else 0.0
        reward -= contact if contacts else 0.0
        reward -= discomfort * self.dt * (social.DISCOMFORT - near) if near < social.DISCOMFORT \
            else 0.0
        truncated = not reached and self.steps >= self.max_steps
        info = self._info(row, contacts, st)
        if reached or truncated:
            info["metrics"] = self.metrics()
            self.ended = (f"the robot reached its goal at step {self.steps}" if reached else
                          f"truncated at max_steps = {self.max_steps}")
        return obs, float(reward), bool(reached), bool(truncated), info

    def render(self) -> None:
        """Refused in one line: the environment draws nothing (:data:`NO_RENDER`)."""
        raise SceneError("render", "the environment draws nothing (its only render mode is "
                         "None)", NO_RENDER)

    @staticmethod
    def _info(row: tuple, contacts: int, st: Any) -> dict[str, Any]:
        """A step's info (module docstring) from its row, contacts and the robot's state."""
        return {"t_s": row[0], "clearance_m": row[6], "ttc_s": row[7], "contacts": contacts,
                "clipped": int(st.clipped), "blocked": int(st.blocked)}


#: the impulses of no contact, (0, 2) m/s (writeable, as the engine's are, so that the
#: compiled record takes it with the same signature; never written)
_NO_IMPULSES = np.empty((0, 2))
#: the ranges of no scan (the same)
_NO_RANGES = np.empty(0)
