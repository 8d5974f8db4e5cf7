"""The robots of a running simulation (``Simulator.robots``): their commands, poses, contacts
and scans, and the step that moves people and robots together.

One step from t to t1 = t + h (the simulator's ``_advance`` calls :meth:`Fleet.step` in place
of the scheme's own step):

1. each robot's command is the one held (set by :meth:`Fleet.command` or asked of its
   controller), clipped to its limits (:func:`.kinematics.clip`); its target pose is the exact
   arc of that command over h (:func:`.kinematics.arc`);
2. the people's prediction is the scheme's (drift, noise, correction), plus, with
   ``crowd_reaction: avoid``, h times the avoidance term (:mod:`sweep_core.model.robots`);
3. the projection min sum_i w_i |x_i - p_i|^2 over the people (w = 1) and the robots of
   finite weight (appended after the people, their prediction the target); a robot of weight
   inf is not a variable: its target disk is an obstacle for this step, whose linearised rows
   <n, y_a> >= <n, c1> + R + r_a (n from c1 to the person at t) are single rows of the people
   (:mod:`.weighted` solves a scene with a weight other than 1 and inf);
4. a prescribed target that overlaps a wall, an obstacle, a map cell or another prescribed
   robot, or that makes the projection infeasible (a person pinned between it and a wall),
   is refused (for an infeasible projection: every prescribed robot moving in the step, since
   the solver does not say which one caused it): that robot stops for the step (its applied
   command becomes (0, 0, 0), its pose does not change), ``blocked`` counts the step and ``stopped`` says so;
5. the true gaps of people and robots together are checked (no overlap beyond 1e-9 m) and
   no robot's centre path crosses a wall segment.

On a small scene with static walls whose robots are all prescribed, a step in which nothing
stops, the prediction holds every row and nothing overlaps is taken by :mod:`.clear_step` in
one compiled call that asks the same kernels the same questions (the same bits).

Contact impulse of a robot-person row with multiplier lam (m) and unit normal e (from the
robot to the person): lam e / h, in m/s: the velocity change the contact imposed on that
person (weight 1) over the step; a person's mass in kg times it is the impulse in N s.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from sweep_core.errors import InfeasibleError, SceneError, show
from sweep_core.model import elementary
from sweep_core.model.gaps import Gaps
from sweep_core.model.geometry import Geometry
from sweep_core.model.robots import overlap
from sweep_core.model.scene import Scene
from sweep_core.numerics.projection import Projection, project
from sweep_core.numerics.robots import kinematics
from sweep_core.numerics.robots.clear_step import Rooms, checked_end
from sweep_core.numerics.robots.contacts import set_contacts
from sweep_core.numerics.robots.control import goal_field, observe
from sweep_core.numerics.robots.planners import Planner, controllers_of
from sweep_core.numerics.robots.reaction import avoidance
from sweep_core.numerics.robots.refusals import geometry_problem, goal_refusal, no_way, scene_map
from sweep_core.numerics.robots.scan import scan
from sweep_core.numerics.robots.small_step import robot_step
from sweep_core.numerics.robots.state import Command, RobotState
from sweep_core.numerics.robots.weighted import project_weighted
from sweep_core.numerics.schemes import Scheme, StepResult


def check_step_length(scene: Scene, dt: float) -> None:
    """SceneError naming the first robot of ``scene`` that a step of ``dt`` (s) at its
    max_speed moves by its radius or more (a step could jump a wall), and the longest dt."""
    for k, robot in enumerate(scene.robots):
        if robot.max_speed * dt >= robot.radius:
            raise SceneError(f"robots[{k}].kinematics.max_speed",
                             f"{robot.max_speed:g} m/s covers {robot.max_speed * dt:g} m "
                             f"in a step of {dt:g} s, not less than the radius "
                             f"{robot.radius:g} m (a step could jump a wall)",
                             f"use dt < {robot.radius / robot.max_speed:g} s or a lower "
                             "max_speed")


class Fleet:
    """The robots of ``scene`` stepped with time step ``dt`` (s); ``seed`` seeds the scans'
    noise. ``controllers`` maps a robot's name to a callable of a
    :class:`~sweep_core.numerics.robots.control.Observation` returning its command, asked at the
    start of every step in place of the held command; it starts with the scene's own
    (``controller:``, :mod:`.planners`); clear it to drive the robots by :meth:`command`
    alone."""

    def __init__(self, scene: Scene, dt: float, seed: int) -> None:
        self.scene = scene
        self.dt = dt
        self.seed = seed
        check_step_length(scene, dt)
        self.every = [max(1, round(1.0 / (r.scan.rate * dt))) if r.scan else 0
                      for r in scene.robots]
        try:
            self.controllers: dict[str, Callable] = dict(controllers_of(scene))
        except SceneError as err:
            raise goal_refusal(scene, err) from err
        self._use_map(scene)
        self.reset()

    def reset(self) -> None:
        """The robots at their scene's poses, at step 0, its bundled planners as new."""
        self.states = {r.name: RobotState(r, (r.pose[0], r.pose[1], kinematics.wrap(r.pose[2])))
                       for r in self.scene.robots}
        self.step_index = 0
        #: the people's gaps the last step's check computed: (t1, y, r1, geometry, Gaps,
        #: whether it found that no person's path might cross a wall segment)
        self.people_gaps: tuple[float, np.ndarray, np.ndarray, Geometry, Gaps, bool] | None \
            = None
        #: the compiled small steps' work arrays, kept from step to step
        self.rooms = Rooms()
        for c in self.controllers.values():  # the bundled planners forget the last run
            if isinstance(c, Planner):
                c.reset()

    def snapshot(self) -> tuple:
        """What a step changes (the robots' states, the step count, the bundled planners'
        tracks and last choices), for :meth:`restore`."""
        planners = [(c, c.state()) for c in self.controllers.values() if hasattr(c, "state")]
        return ({name: st.copy() for name, st in self.states.items()}, self.step_index,
                planners)

    def restore(self, saved: tuple) -> None:
        """The fleet as :meth:`snapshot` saw it (a failed step is undone)."""
        states, self.step_index, planners = saved
        for name, st in states.items():
            self.states[name].__dict__.update(st.copy().__dict__)
        for c, state in planners:
            c.set_state(state)

    def fields_for(self, scene: Scene) -> dict[str, Any]:
        """The goal fields round ``scene``'s walls, obstacles and map of the robots whose
        bundled controllers plan by one (for :meth:`use_scene`); SceneError when a goal
        cannot be planned for (nothing changed)."""
        try:
            return {name: goal_field(scene, self.states[name].robot)
                    for name, c in self.controllers.items() if hasattr(c, "rescene")}
        except SceneError as err:
            raise goal_refusal(scene, err) from err

    def use_scene(self, scene: Scene, fields: dict[str, Any]) -> None:
        """The robots move in ``scene`` from now on; their bundled controllers plan round its
        walls by ``fields`` (:meth:`fields_for`), keeping their tracks of the people."""
        for name, f in fields.items():
            planner: Any = self.controllers[name]  # a bundled one (fields_for)
            planner.rescene(scene, f)
        self.scene = scene
        self._use_map(scene)

    def _use_map(self, scene: Scene) -> None:
        """``scene``'s map, decoded once per scene (not per placement), and its test of whether
        points (N, 2) (m) lie in a blocked cell (None without a map): what placements and the
        robots' targets are checked against."""
        self._map = scene_map(scene)
        self._blocked = None if self._map is None else self._map.is_blocked

    def check_geometry(self, scene: Scene, t: float) -> str:
        """What a robot's current disk would overlap in ``scene``'s walls, obstacles and map
        at time t, or what of them would cut it off from its goal ('' when nothing)."""
        return geometry_problem(list(self.states.values()), scene, t)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.states)

    def state(self, name: str) -> RobotState:
        return self.states[self._name(name)]

    def _name(self, name: str) -> str:
        if name not in self.states:
            raise SceneError("robot", f"unknown robot {show(name)}",
                             f"use one of {list(self.states)}")
        return name

    def command(self, name: str, twist: Command, clip: bool = True) -> None:
        """Hold ``twist`` (vx, vy, omega) (m/s, m/s, rad/s, robot frame) from the next step on;
        ``clip=False`` applies it as given (a replay of applied commands)."""
        st = self.state(name)
        try:
            values = tuple(map(float, twist))
        except (TypeError, ValueError):
            values = ()
        if len(values) != 3 or not all(map(math.isfinite, values)):
            raise SceneError(f"{name}/cmd_vel", f"must be three finite numbers (vx, vy, omega), "
                             f"got {show(list(twist) if hasattr(twist, '__len__') else twist)}",
                             "send finite m/s and rad/s values")
        st.held = (values[0], values[1], values[2])
        st.raw = not clip

    def place(self, name: str, pose: Command, t: float, people: np.ndarray,
              radii: np.ndarray, ids: np.ndarray | None = None) -> None:
        """Put robot ``name`` at ``pose`` (x, y, yaw) between steps, commands reset to 0; else
        SceneError (``initialpose``) naming what it would overlap (a person by ``ids``)."""
        st = self.state(name)
        x, y, yaw = (float(v) for v in pose)
        if not all(math.isfinite(v) for v in (x, y, yaw)):
            raise SceneError("initialpose", f"must be finite, got {show([x, y, yaw])}",
                             "send a finite pose")
        others = [(s.pose[0], s.pose[1], s.robot.radius, f"robot {s.robot.name}")
                  for s in self.states.values() if s is not st]
        problem = overlap(st.robot, (x, y), self.scene.geometry, people, radii, others,
                          self._blocked, t, ids=ids) or no_way(st.robot, (x, y), self.scene, self._map)
        if problem:
            raise SceneError("initialpose", problem, "place the robot in free space, clear of "
                             "people, walls and other robots, where its goal can be reached")
        st.pose = (x, y, kinematics.wrap(yaw))
        st.twist, st.command, st.held, st.raw = (0.0,) * 3, (0.0,) * 3, (0.0,) * 3, False

    # -- one step ----------------------------------------------------------------------------
    def step(self, scheme: Scheme, t: float, q: np.ndarray, h: float, dB: np.ndarray | None,
             drift: object, sigma: np.ndarray, present: Scene) -> StepResult:
        """People and robots from t to t + h (module docstring); the people's StepResult.
        ``present``: the scene of the people present (the simulator's: with flows, the present
        agents alone, whose radii are theirs entry by entry; the scene's own are every
        agent's, those who have left included)."""
        t1 = t + h
        states = list(self.states.values())
        for st in states:
            st.stopped = False
            wanted = st.held
            if st.robot.name in self.controllers:
                wanted = self._ask(st.robot.name, observe(st, t, q, present.radii(t), h))
            if st.raw:
                st.command = wanted
            else:
                st.command, changed = kinematics.clip(st.robot, wanted, st.command, h)
                st.clipped += int(changed)
        pred = scheme.predict(t, q, h, dB, drift, sigma)  # type: ignore[arg-type]
        if self.scene.reaction.kind == "avoid" and len(q):
            pred = pred + h * avoidance(self.scene.reaction, q, states)
        pred = scheme.correct(t, q, h, dB, pred, sigma)
        r1 = present.radii(t1)
        targets = [kinematics.arc(st.pose, st.command, h) for st in states]
        moving = [st.robot.prescribed and st.command != (0.0, 0.0, 0.0) for st in states]
        simple = robot_step(self.scene.geometry, t1, q, pred, r1, states, targets, moving,
                            self._blocked is not None, scheme.warm, scheme.solver, h,
                            self.rooms)
        if isinstance(simple, tuple):  # the general path's bits, in one compiled call
            proj, people, gaps, paths_clear = simple
            self.people_gaps = (t1, people, r1, self.scene.geometry, gaps, paths_clear)
            scheme.warm = proj
            self.step_index += 1
            return StepResult(people, pred, proj)
        if not simple:  # (True: the call found that no robot stops)
            self._settle(states, targets, moving, t1)
        before = [st.copy() for st in states]
        try:
            proj = self._project(scheme, states, targets, t1, q, pred, r1)
            people = self._finish(states, targets, proj, q, r1, t1, h, len(q))
        except InfeasibleError:
            if not any(moving):
                raise
            # a person pinned between a moving robot and a wall (the projection has no
            # solution, and the solver does not say who caused it): every moving one stops
            for k, st in enumerate(states):
                self._restore(st, before[k])
                if moving[k]:
                    self._stop(st, targets, k)
            proj = self._project(scheme, states, targets, t1, q, pred, r1)
            people = self._finish(states, targets, proj, q, r1, t1, h, len(q))
        scheme.warm = proj
        self.step_index += 1
        return StepResult(people, pred, proj)

    def _settle(self, states: list[RobotState], targets: list, moving: list[bool],
                t1: float) -> None:
        """Stops, jointly, every moving prescribed robot whose target overlaps a wall, an
        obstacle, a blocked map cell or another prescribed robot where that one ends the step
        (its target, or its pose once stopped): rounds of stops until no moving target
        conflicts. A stopped robot's pose is feasible (it was the last step's), so the rounds
        end, at most one per robot; the outcome does not depend on the robots' order."""
        while True:
            stop = [k for k in range(len(states))
                    if moving[k] and self._target_blocked(k, states, targets, t1)]
            if not stop:
                return
            for k in stop:
                self._stop(states[k], targets, k)
                moving[k] = False

    @staticmethod
    def _restore(st: RobotState, saved: RobotState) -> None:
        for name in ("pose", "twist", "command", "blocked", "stopped", "contact_ids",
                     "contact_xy", "contact_impulse"):
            setattr(st, name, getattr(saved, name))

    def _ask(self, name: str, obs: object) -> Command:
        """The command robot ``name``'s controller returns for ``obs``: three finite numbers,
        else SceneError naming the robot and the controller (the step is not taken)."""
        controller = self.controllers[name]
        out = controller(obs)
        try:
            values = tuple(float(v) for v in out)
        except (TypeError, ValueError):
            values = ()
        if len(values) != 3 or not all(math.isfinite(v) for v in values):
            label = getattr(controller, "__name__", type(controller).__name__)
            raise SceneError(f"robot {name}", f"its controller {show(label)} returned "
                             f"{show(list(out) if isinstance(out, (tuple, list)) else out)}, "
                             "not three finite numbers (vx, vy, omega)",
                             f"make the controller of robot {name} return finite m/s and "
                             "rad/s values")
        return (values[0], values[1], values[2])

    def _stop(self, st: RobotState, targets: list, k: int) -> None:
        st.command = (0.0, 0.0, 0.0)
        targets[k] = st.pose
        st.blocked += 1
        st.stopped = True

    def _target_blocked(self, k: int, states: list[RobotState], targets: list,
                        t1: float) -> bool:
        st = states[k]
        others = [(targets[j][0], targets[j][1], s.robot.radius, f"robot {s.robot.name}")
                  for j, s in enumerate(states) if j != k and s.robot.prescribed]
        empty = np.empty((0, 2))
        return bool(overlap(st.robot, targets[k][:2], self.scene.geometry, empty, np.empty(0),
                            others, self._blocked, t1))

    def _project(self, scheme: Scheme, states: list[RobotState], targets: list, t1: float,
                 q: np.ndarray, pred: np.ndarray, r1: np.ndarray) -> Projection:
        free = [k for k, st in enumerate(states) if not st.robot.prescribed]
        fixed = [k for k, st in enumerate(states) if st.robot.prescribed]
        geom = self._with_disks(self.scene.geometry.at(t1), [targets[k][:2] for k in fixed],
                                [states[k].robot.radius for k in fixed])
        q_all, p_all, r_all = q, pred, r1  # read only: the projection copies what it changes
        if free:
            q_all = np.concatenate([q, np.array([states[k].pose[:2] for k in free])])
            p_all = np.concatenate([pred, np.array([targets[k][:2] for k in free])])
            r_all = np.concatenate([r1, [states[k].robot.radius for k in free]])
        weights = [states[k].robot.weight for k in free]
        warm = scheme.warm if scheme.warm is not None and len(scheme.warm.y) == len(q_all) \
            else None
        if all(w == 1.0 for w in weights):
            return project(geom, t1, q_all, p_all, r_all, scheme.solver, warm=warm)
        w_all = np.concatenate([np.ones(len(q)), weights])
        return project_weighted(geom, t1, q_all, p_all, r_all, w_all, scheme.solver)

    @staticmethod
    def _with_disks(geom: Geometry, centres: list, radii: list) -> Geometry:
        """The geometry (posed at the step's time) with the prescribed robots' disks added as
        circle obstacles (item indices after the scene's own circles)."""
        if not centres:
            return geom
        return geom.with_circles(np.array(centres, dtype=np.float64).reshape(-1, 2),
                                 np.array(radii, dtype=np.float64))

    def _finish(self, states: list[RobotState], targets: list, proj: Projection, q: np.ndarray,
                r1: np.ndarray, t1: float, h: float, n: int) -> np.ndarray:
        """Robots' new poses, twists and contacts; the true gaps of everyone checked. Returns
        the people's positions at the step's end (N, 2), a copy of the projection's."""
        free = [k for k, st in enumerate(states) if not st.robot.prescribed]
        fixed = [k for k, st in enumerate(states) if st.robot.prescribed]
        start = {k: states[k].pose for k in range(len(states))}
        for slot, k in enumerate(free):
            st = states[k]
            x, y = (float(v) for v in proj.y[n + slot])
            push = (x - targets[k][0], y - targets[k][1])
            yaw1 = targets[k][2]
            s, c = elementary.sincos(yaw1)
            st.twist = (st.command[0] + (c * push[0] + s * push[1]) / h,
                        st.command[1] + (-s * push[0] + c * push[1]) / h, st.command[2])
            st.pose = (float(x), float(y), yaw1)
        for k in fixed:
            states[k].pose = targets[k]
            states[k].twist = states[k].command
        set_contacts(states, proj, n, len(self.scene.geometry.circle_radius), h)
        ends = proj.y[:n].copy()
        people, paths = checked_end(self.scene.geometry, t1, q, ends, r1, states,
                                    [start[k] for k in range(len(states))],
                                    self._blocked is not None)
        # the people's gaps at the step's end, for the simulator's own check (the same call)
        self.people_gaps = None if people is None else (t1, ends, r1, self.scene.geometry,
                                                        people, paths)
        return ends

    def gaps_of(self, t1: float, geom: Geometry, y: np.ndarray, r1: np.ndarray
                ) -> tuple[Gaps, bool] | None:
        """The people's gaps (:func:`~sweep_core.model.gaps.gaps`) at (t1, y) with radii r1
        and geometry ``geom``, when the last step's check computed them with those very
        arguments, and whether that check found that no person's centre path from the step's
        start to ``y`` might meet a wall segment (the crossing check then has nothing to do);
        None otherwise. The time may differ by rounding (t + h here, (k + 1) h there) where it
        decides nothing: no obstacle or half-plane moves (the check computes no gaps with user
        constraints). ``y`` must be the very array the step returned."""
        kept = self.people_gaps
        if (kept is None or kept[3] is not geom or kept[1] is not y
                or (kept[0] != t1 and (geom.is_moving or not geom.fixed_halfplanes))
                or (kept[2] is not r1 and (kept[2].shape != r1.shape
                                           or not (kept[2] == r1).all()))):
            return None
        return kept[4], kept[5]

    def after_step(self, t: float, people: np.ndarray, radii: np.ndarray) -> None:
        """Scans due at this step (the step index counts steps taken; step 0 is the start)."""
        for k, st in enumerate(self.states.values()):
            spec = st.robot.scan
            if spec is None or self.step_index % self.every[k]:
                continue
            others = [s for s in self.states.values() if s is not st]
            disks, disk_r = people, radii
            if others:
                disks = np.concatenate([people, np.array([s.pose[:2] for s in others])])
                disk_r = np.concatenate([radii, [s.robot.radius for s in others]])
            # the noise: the stream of Generator(PCG64([seed, k, step]))
            st.scan = scan(spec, st.pose, t, self.step_index, self.scene.geometry, disks,
                           disk_r, (self.seed, k, self.step_index))

    def scanned(self, name: str) -> bool:
        """Robot ``name`` took a scan at the current step."""
        st = self.state(name)
        return st.scan is not None and st.scan.step == self.step_index


def robot_fleet(scene: Scene, dt: float, seed: int, scheme: Scheme) -> Fleet | None:
    """The fleet of a scene with robots (None without); the scheme must be predict-then-project
    (projected_euler, bridge)."""
    if not scene.robots:
        return None
    if type(scheme).step is not Scheme.step:
        raise SceneError("scheme", f"{scheme.name} cannot step robots (it sub-steps)",
                         "use projected_euler or bridge with robots")
    return Fleet(scene, dt, seed)
