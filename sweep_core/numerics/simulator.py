"""The simulator: a scene, a scheme, a seeded Brownian path and the current state."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from sweep_core import checks
from sweep_core.errors import InfeasibleError, SceneError
from sweep_core.model.crossing import crossings
from sweep_core.model.fields import Field
from sweep_core.model.gaps import FEASIBILITY_TOLERANCE, SmallestGap, gaps, violating_agents
from sweep_core.model.geodesic import navigation_fields
from sweep_core.model.geometry import SEGMENT
from sweep_core.model.scene import Scene
from sweep_core.numerics import noise
from sweep_core.numerics.population import Population
from sweep_core.numerics.projection import SolverOptions
from sweep_core.numerics.robots.fleet import robot_fleet
from sweep_core.numerics.schemes import SCHEMES, Scheme, StepResult


@dataclass(frozen=True)
class State:
    """A snapshot.

    t: time (s); step: steps taken; positions (N, 2) m; radii (N,) m at t;
    velocities (N, 2) m/s: (q_n - q_{n-1}) / h of the last step (zero before the first);
    reaction (N, 2) m: prediction minus result of the last step (the increment of K);
    contacts: active constraints of the last step; min_gap: the smallest true gap over every
    pair and every wall and obstacle (m, inf if none); ids (N,) int: the agents' ids with
    ``flows`` (None: 0 .. N - 1).
    """

    t: float
    step: int
    positions: np.ndarray
    radii: np.ndarray
    velocities: np.ndarray
    reaction: np.ndarray
    contacts: int
    min_gap: float
    ids: np.ndarray | None = None


def _scheme_class(scheme: str | type[Scheme]) -> type[Scheme]:
    if isinstance(scheme, type) and issubclass(scheme, Scheme):
        return scheme
    if scheme not in SCHEMES:
        raise SceneError("scheme", f"unknown scheme {scheme!r}", f"use one of {sorted(SCHEMES)}")
    return SCHEMES[scheme]


class Simulator:
    """Steps a scene with a scheme.

    Args:
        scene: a validated :class:`Scene`.
        dt: time step h (s), > 0.
        seed: seed of the Brownian path (int >= 0).
        scheme: a name in ``SCHEMES`` or a Scheme subclass.
        solver: QP settings (``SolverOptions``).
        check: verify the true constraints after every step (costs one neighbour search).
    """

    def __init__(self, scene: Scene, dt: float = 0.01, seed: int = 0, *,
                 scheme: str | type[Scheme] = "projected_euler",
                 solver: SolverOptions | None = None, check: bool = True) -> None:
        if not isinstance(scene, Scene):
            raise SceneError("scene", f"must be a sweep_core.Scene, got {type(scene).__name__}",
                             "build it with Scene.from_yaml or Scene.from_dict")
        self.scene = scene
        self.dt = checks.number(dt, "dt", positive=True)
        self.seed = checks.integer(seed, "seed")
        self.scheme = _scheme_class(scheme)(scene, solver or SolverOptions())
        self.check = bool(check)
        #: the robots (None without): numerics/robots/fleet.py
        self.robots = robot_fleet(scene, self.dt, self.seed, self.scheme)
        self.reset()

    # -- state -------------------------------------------------------------------------
    def reset(self, seed: int | None = None) -> None:
        """Back to t = 0, the scene's initial positions, drift and noise, and the seed."""
        if seed is not None:
            self.seed = int(seed)
        self._rng = noise.generator(self.seed)
        self.scheme.reset()
        self._drift: Field = self.scene.drift
        self._sigma = self.scene.sigma.copy()
        #: the last step's noise intensities and whether any is non-zero (nothing is drawn
        #: when none is): kept while the step's intensities are that very array
        self._noisy: tuple[np.ndarray | None, bool] = (None, False)
        n = self.scene.n_agents
        self._k = 0
        self._q = self.scene.positions.copy()
        self._v = np.zeros((n, 2))
        self._reaction = np.zeros((n, 2))
        self._contacts = 0
        r = self.scene.radii(0.0)
        self._min_gap = SmallestGap(gaps(self.scene.geometry, 0.0, self._q, r), self._q, r)
        self.last: StepResult | None = None
        # flows (sinks, sources, speeds, delays, journeys, headway): who is present
        self._pop = Population(self.scene, self.seed) if self.scene.flows is not None else None
        if self.robots is not None:
            self.robots.seed = self.seed
            self.robots.reset()
            self.robots.after_step(0.0, self._q, self.scene.radii(0.0))

    def _live(self) -> Scene:
        """The scene the scheme steps: the present agents' (flows), else the scene."""
        return self.scene if self._pop is None else self._pop.view(self.scene, self._q)

    @property
    def ids(self) -> np.ndarray:
        """(N,) int ids of the present agents, increasing (0 .. N - 1 without flows)."""
        return (np.arange(len(self._q), dtype=np.int64) if self._pop is None
                else self._pop.ids.copy())

    @property
    def flows(self) -> Population | None:
        """Who entered, left, waits (``Population``) in a scene with flows; else None."""
        return self._pop

    @property
    def t(self) -> float:
        """Current time (s): steps * dt, never accumulated."""
        return self._k * self.dt

    @property
    def n_steps(self) -> int:
        return self._k

    @property
    def positions(self) -> np.ndarray:
        """(N, 2) centres (m), a copy."""
        return self._q.copy()

    @property
    def radii(self) -> np.ndarray:
        """(N,) radii at the current time (m)."""
        return np.array(self._live().radii(self.t), dtype=np.float64, copy=True)

    @property
    def reaction(self) -> np.ndarray:
        """(N, 2) prediction minus result of the last step (m)."""
        return self._reaction.copy()

    @property
    def velocities(self) -> np.ndarray:
        """(N, 2) displacement of the last step divided by dt (m/s)."""
        return self._v.copy()

    @property
    def contacts(self) -> int:
        return self._contacts

    @property
    def min_gap(self) -> float:
        """The smallest true gap (m) after the last step: between two people, or a person and
        a wall or obstacle (inf with the check off)."""
        return self._min_gap.value()

    @property
    def bound(self) -> float:
        """The last step's certified bound (m) on its distance to the exact projection onto
        the linearised set (0 before any step; ``Projection.bound``)."""
        return 0.0 if self.last is None else self.last.projection.bound

    @property
    def backend_agents(self) -> int:
        """Agents of the last step whose contact cluster was solved by the interior-point
        backend (to about 1e-6 m in degenerate jams) rather than exactly; 0 before a step."""
        return 0 if self.last is None else self.last.projection.backend_agents

    @property
    def state(self) -> State:
        return State(self.t, self._k, self.positions, self.radii, self.velocities,
                     self.reaction, self._contacts, self._min_gap.value(),
                     None if self._pop is None else self._pop.ids.copy())

    # -- commands ------------------------------------------------------------------------
    @property
    def drift(self) -> Field:
        return self._drift

    def set_drift(self, drift: Field) -> None:
        """Replace the wished-velocity field from the next step on."""
        if not isinstance(drift, Field):
            raise SceneError("drift", f"must be a sweep_core Field, got {type(drift).__name__}",
                             "build one with sweep_core.field_from_spec")
        self._drift = drift

    @property
    def sigma(self) -> np.ndarray:
        return self._sigma.copy()

    def set_sigma(self, sigma: float | np.ndarray) -> None:
        """Replace the noise intensities (scalar or (N,), m/sqrt(s)) from the next step on."""
        # a copy: the simulator's own (a caller's array changed later changes nothing here)
        self._sigma = np.array(checks.per_agent(sigma, self.scene.n_agents, "noise.sigma",
                                                nonnegative=True), dtype=np.float64)

    # -- geometry ------------------------------------------------------------------------
    def set_scene(self, scene: Scene) -> None:
        """Replace the scene (its walls, obstacles and map) from the next step on, keeping the
        time, the positions, the noise and the Brownian path, and the drift (the scene's own is
        taken from ``scene``; a command's navigation field, geodesic or exits, is computed again
        from its spec round the new walls; so a navigation field follows them); a later reset
        returns to ``scene``'s initial positions. ``scene`` must have the same
        agents (count and radius law). The warm start of the projection is dropped (its rows
        belong to the old walls), so a replay that replaces the scene at the same step gets
        the same floats.

        Raises:
            SceneError: other agents, or some agent at the current positions would violate a
                wall or obstacle of ``scene`` or sit in a blocked cell of its map (the message
                names every such agent), or a command's navigation field cannot be computed
                round the new walls (its goal blocked or out of an agent's reach); the
                simulator is then unchanged.
        """
        if not isinstance(scene, Scene):
            raise SceneError("scene", f"must be a sweep_core.Scene, got {type(scene).__name__}",
                             "build it with Scene.from_yaml or Scene.from_dict")
        old = self.scene
        if (scene.n_agents != old.n_agents or not np.array_equal(scene.radius, old.radius)
                or scene.radius_law.to_spec() != old.radius_law.to_spec()):
            raise SceneError("scene", f"has {scene.n_agents} agents (radii or radius law "
                             f"differing), the simulator {old.n_agents}",
                             "keep the agents and their radii; build a new Simulator for others")
        fields: dict = {}
        if self.robots is not None:
            problem = self.robots.check_geometry(scene, self.t)
            if problem:
                raise SceneError("scene", f"at t = {self.t:g} s {problem}",
                                 "keep the robots' current disks clear of the new walls and "
                                 "their goals reachable, or place the robots elsewhere first")
            fields = self.robots.fields_for(scene)  # the planners' new global plans
        live = scene if self._pop is None else self._pop.view(scene, self._q)
        rows = violating_agents(live, self.t, self._q)
        if rows:  # named by id (with flows, the rows of the people present are not)
            bad = rows if self._pop is None else self._pop.ids[rows].tolist()
            shown = ", ".join(str(a) for a in bad[:12])
            more = "" if len(bad) <= 12 else f" and {len(bad) - 12} more"
            first = self._q[rows[0]]
            raise SceneError("scene", f"agents [{shown}{more}] at t = {self.t:g} s would be "
                             f"inside the new walls, obstacles or blocked map cells (agent {bad[0]} "
                             f"at [{first[0]:g}, {first[1]:g}])",
                             "keep those agents' positions free in the new geometry")
        drift = self._drift
        if drift is old.drift:
            # the scene's own drift is in effect (no command replaced it): take the new scene's,
            # whose navigation field (geodesic, exits) was computed round the new walls
            drift = scene.drift
        elif navigation_fields(drift):
            # a command's navigation field: computed again round the new walls, from its spec
            # and the new scene's initial positions, as a replay of the recording does
            try:
                drift = scene.drift_from_spec(drift.to_spec())
            except SceneError as err:
                raise SceneError("scene", f"the drift in effect ({drift.kind}) cannot follow "
                                 f"the new walls: {err.field}: {err.problem}",
                                 "send a new goal (or another drift) before the new walls, "
                                 "or keep its goal reachable in them") from err
        self._drift = drift
        self.scene = scene
        self.scheme.scene = live
        self.scheme.reset()
        if self.robots is not None:  # the robots see the new walls too, and plan round them
            self.robots.use_scene(scene, fields)
        r = live.radii(self.t)
        self._min_gap = SmallestGap(gaps(scene.geometry, self.t, self._q, r) if len(r) else None,
                                  self._q, r)

    # -- stepping ------------------------------------------------------------------------
    def step(self, n: int = 1, dB: np.ndarray | None = None) -> None:
        """Take n steps. dB: Brownian increments, (N, 2) for one step or (n, N, 2) for n steps;
        by default they are drawn from the seeded path (nothing is drawn if sigma = 0)."""
        checks.integer(n, "n")
        shape = (len(self._q), 2)
        if dB is not None:
            dB = np.asarray(dB, dtype=np.float64)
            if dB.shape == shape and n == 1:
                dB = dB[None]
            if dB.shape != (n,) + shape:
                raise SceneError("dB", f"has shape {dB.shape}, expected {shape} for one step "
                                       f"or {(n,) + shape} for n = {n} steps")
            if not np.all(np.isfinite(dB)):
                raise SceneError("dB", "holds non-finite increments")
        for k in range(n):
            self._advance(None if dB is None else dB[k])

    def run(self, t_end: float, progress: bool = False,
            callback: Callable[[Simulator], None] | None = None,
            increments: Callable[[], np.ndarray] | None = None) -> None:
        """Step until t_end (s), calling callback(self) after every step.

        increments: source of the Brownian increments (N, 2), called once per step in which
        sigma is not zero everywhere; by default they are drawn from the seeded path.
        """
        t_end = checks.number(t_end, "t_end", nonnegative=True)
        steps = int(round((t_end - self.t) / self.dt))
        if steps < 0:
            raise SceneError("t_end", f"{t_end:g} s is before the current time {self.t:g} s")
        self.scene.check_horizon(t_end)
        bar = None
        if progress:
            from tqdm import tqdm
            bar = tqdm(total=steps, unit="step", dynamic_ncols=True)
        try:
            for _ in range(steps):
                self._advance(increments() if increments is not None and np.any(self._sigma)
                              else None)
                if callback is not None:
                    callback(self)
                if bar is not None:
                    bar.update()
        finally:
            if bar is not None:
                bar.close()

    def _advance(self, dB: np.ndarray | None) -> None:
        """One step; a step that raises leaves everything as before it (people, robots, time,
        the Brownian generator's state, the scheme's warm start and counters)."""
        rng = self._rng.bit_generator.state
        scheme = dict(self.scheme.__dict__)
        fleet = None if self.robots is None else self.robots.snapshot()
        try:
            self._advance_once(dB)
        except BaseException as err:
            self._rng.bit_generator.state = rng
            self.scheme.__dict__.clear()
            self.scheme.__dict__.update(scheme)
            if fleet is not None and self.robots is not None:
                self.robots.restore(fleet)
            if isinstance(err, InfeasibleError) and self._pop is not None:
                raise err.by_ids(self._pop.ids) from None  # rows named by the people's ids
            raise

    def _advance_once(self, dB: np.ndarray | None) -> None:
        h, t = self.dt, self.t
        t1 = (self._k + 1) * h
        scene = self._live()
        r1 = scene.radii(t1)
        # constant radii were checked positive when the scene was read
        if len(r1) and not scene.radius_law.is_constant and float(r1.min()) <= 0:
            raise SceneError("agents.radius_law", f"radii reach {float(r1.min()):.6g} m <= 0 at "
                             f"t = {t1:.6g} s", "stop earlier or shrink the radii more slowly")
        drift, sigma = self._drift, self._sigma
        if self._pop is not None:
            drift, sigma = self._pop.drift(drift), self._pop.sigma(sigma)
            self.scheme.scene = scene
        if sigma is not self._noisy[0]:
            self._noisy = (sigma, bool(sigma.any()))
        if dB is None and self._noisy[1]:
            dB = noise.increments(self._rng, h, len(self._q))
        if self.robots is not None:
            res = self.robots.step(self.scheme, t, self._q, h, dB, drift, sigma, scene)
        else:
            res = self.scheme.step(t, self._q, h, dB, drift, sigma)
        y = res.q_new
        if not np.isfinite(y).all():
            bad = np.nonzero(~np.all(np.isfinite(y), axis=1))[0]
            raise InfeasibleError(t1, bad.tolist(), "non-finite positions")
        min_gap = SmallestGap(None, y, r1)
        if self.check:
            # the robots' check computed the people's gaps already (the same call), and may
            # have found their paths clear of the wall segments
            kept = None if self.robots is None else self.robots.gaps_of(t1, scene.geometry, y,
                                                                        r1)
            g, clear = kept if kept is not None else (gaps(scene.geometry, t1, y, r1), False)
            if g.min_gap < -FEASIBILITY_TOLERANCE:
                worst = g.worst_pair if g.min_pair <= g.min_single else g.worst_single
                who = [] if worst is None else (
                    list(worst[:2]) if g.min_pair <= g.min_single else [worst[0]])
                raise InfeasibleError(t1, who, f"true constraint violated by {-g.min_gap:.3g} m")
            through, item = ((_NO_PATH, _NO_PATH) if clear
                             else crossings(scene.geometry, self._q, y, r1, g))
            if len(through):
                raise InfeasibleError(t1, sorted(set(through.tolist())), "the centre of agent "
                                      f"{int(through[0])} went through "
                                      f"{self.scene.geometry.describe(SEGMENT, int(item[0]))} "
                                      "during the step")
            min_gap = SmallestGap(g, y, r1)
        self._v = (y - self._q) / h
        self._reaction = res.prediction - y
        if self.robots is not None:  # the step's agents, before any leave or enter
            self.robots.after_step(t1, y, r1)
            if self._pop is not None:  # contacts name people by id, not by the step's row
                for st in self.robots.states.values():
                    if len(st.contact_ids):
                        st.contact_ids = self._pop.ids[st.contact_ids]
        if self._pop is not None:
            changed, y, (self._v, self._reaction) = self._pop.after_step(
                scene, t1, y, self._v, self._reaction)
            if changed:
                self.scheme.reset()  # the warm start's rows name the old agents
        self._q = y
        self._k += 1
        self._contacts = res.projection.active
        self._min_gap = min_gap
        self.last = res


#: no crossing (the robots' step found that no path might cross a wall)
_NO_PATH = np.empty(0, dtype=np.intp)
