"""Who is present in a run with ``flows`` (:mod:`sweep_core.model.flows`), and their wished
velocities: per-agent speeds, start delays, journeys, the headway law; agents leaving at sinks
and entering at sources, with ids kept.

Agents are known by id: the scene's agents are 0 .. N0 - 1, each entering agent takes the
next id. Per-id arrays (radius, group, speed, start time, leg) grow as agents enter; the
simulator's arrays hold the present agents in increasing id order. Draws (speeds and delays
from distributions, source positions and radii) come from a generator seeded by the run's
seed on a stream of its own, in a fixed order: the scene's agents' speeds, then their delays,
then each entering agent's position, radius, speed and delay, at its entry. So a seed fixes
the run, and the Brownian increments are drawn as without flows.

Entry: a source's agent is due at its time; at the end of each step the due agents of each
source (in order) are placed at uniform random points of its region where the disk (its radius
at that time) is clear of every wall, obstacle, blocked map cell and present agent
(:data:`TRIES` candidates per agent and step, checked against cell lists of the disks near
the source, :mod:`sweep_core.numerics.entry`); an agent that finds no room waits,
with the ones behind it, for the next step (``waiting``). Departure: an agent whose centre is
inside a sink at the end of a step leaves (``left_at[id]`` = that time). Conservation:
N0 + entered = present + left.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from sweep_core.model.fields import Field, Groups
from sweep_core.model.flows import Flows, Source, draw
from sweep_core.model.geometry import single_rows
from sweep_core.model.maps import OccupancyMap, map_from_spec
from sweep_core.model.scene import Scene
from sweep_core.numerics.csm import CUT, csm, wall_terms
from sweep_core.numerics.entry import EntryGrid
from sweep_core.numerics.exit_choice import towards
from sweep_core.numerics.headway import headway

#: the flows' random stream: a SeedSequence entry beside the run's seed
STREAM = 0x666C6F77
#: candidate positions drawn per entering agent and step
TRIES = 16


class FlowDrift(Field):
    """The wished velocities of the present agents (what the scheme calls the drift)."""

    kind = "flows"

    def __init__(self, population: Population, base: Field) -> None:
        self.population, self.base = population, base

    def __call__(self, t: float, q: np.ndarray) -> np.ndarray:
        return self.population.wished(t, q, self.base)

    def to_spec(self) -> dict:
        return self.base.to_spec()


class Population:
    """The present agents of a scene with flows (module docstring), from t = 0."""

    def __init__(self, scene: Scene, seed: int) -> None:
        flows = scene.flows
        assert flows is not None
        self.flows: Flows = flows
        self.rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, STREAM])))
        n0 = scene.n_agents
        self.n0 = n0
        self.ids = np.arange(n0, dtype=np.int64)
        self.radius = scene.radius.copy()
        group = np.full(n0, -1, dtype=np.int64)
        if isinstance(scene.drift, Groups):
            for k, idx in enumerate(scene.drift.members):
                group[idx] = k
        self.group = group
        gs = flows.group_speed
        self.scaled = flows.speeds is not None or any(s.speeds is not None
                                                      for s in flows.sources)
        self.speed = (draw(flows.speeds, self.rng, n0) if flows.speeds is not None
                      else gs[group].copy())
        self.start = (draw(flows.delays, self.rng, n0) if flows.delays is not None
                      else np.zeros(n0))
        self.waits = flows.delays is not None or any(s.delays is not None for s in flows.sources)
        self.leg = np.zeros(n0, dtype=np.int64)
        self.entered_at = np.zeros(n0)
        self.next = [0] * len(flows.sources)  # the next due agent of each source
        self.entered = 0
        self.left_at: dict[int, float] = {}
        self.sigma_new = float(scene.sigma[0]) if len(scene.sigma) else 0.0
        #: agents due at a source by the last step that found no room yet
        self.waiting = 0
        self._view: Scene | None = None
        #: :meth:`sigma`'s last answer: (the simulator's intensities, the ids, the answer)
        self._sigma: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._grid: OccupancyMap | None = None  # the scene's map, read when a source needs it
        # per-id values of the agents entering in this step: (radius, group, speed, start, t)
        self._entering: list[tuple[float, int, float, float, float]] = []
        self._base: Scene | None = None
        self.geometry = scene.geometry  # the walls the csm law's wall term sees
        self._journey = {j.group: j for j in flows.journeys}
        self._exits = {c.group: c for c in flows.exit_choices}

    # -- views ----------------------------------------------------------------------------
    @property
    def left(self) -> int:
        return len(self.left_at)

    @property
    def present(self) -> int:
        return len(self.ids)

    def view(self, scene: Scene, q: np.ndarray) -> Scene:
        """``scene`` restricted to the present agents at centres q (N, 2): what the scheme
        steps (radii, noise); cached until the agents or the scene change."""
        if self._view is None or self._base is not scene:
            ids = self.ids
            sigma = (np.full(len(ids), self.sigma_new) if self.flows.sources
                     else scene.sigma[ids])
            self._view = replace(scene, positions=q, radius=self.radius[ids], sigma=sigma)
            self._base = scene
            self.geometry = scene.geometry
        return self._view

    def sigma(self, sigma: np.ndarray) -> np.ndarray:
        """The present agents' noise intensities from the simulator's (N0,) ones: the same
        (read-only) array while neither ``sigma`` (that very array) nor the agents change."""
        kept = self._sigma
        if kept is not None and kept[0] is sigma and kept[1] is self.ids:
            return kept[2]
        out = (np.full(len(self.ids), float(sigma[0]) if len(sigma) else self.sigma_new)
               if self.flows.sources else sigma[self.ids])
        out.flags.writeable = False
        self._sigma = (sigma, self.ids, out)
        return out

    def drift(self, base: Field) -> FlowDrift:
        return FlowDrift(self, base)

    # -- wished velocities --------------------------------------------------------------------
    def wished(self, t: float, q: np.ndarray, base: Field) -> np.ndarray:
        """(N, 2) m/s: the wished velocity of each present agent at centres q (module
        docstring of :mod:`sweep_core.model.flows`)."""
        ids = self.ids
        group = self.group[ids]
        if not self.flows.changes_population:
            u = base(t, q)  # the agents are the scene's: the drift as without flows
        else:
            u = np.zeros_like(q)
            if isinstance(base, Groups):
                fields = list(base.fields) + [base.rest]
                for k, f in enumerate(fields):
                    sel = np.flatnonzero(group == (k if k < len(base.fields) else -1))
                    if len(sel):
                        u[sel] = f(t, q[sel])
            elif len(q):
                u = base(t, q)
        if self._journey:
            leg = self.leg[ids]
            for g, j in self._journey.items():
                ing = group == g
                for k, f in enumerate(j.fields):
                    sel = np.flatnonzero(ing & (leg == k))
                    if len(sel):
                        u[sel] = f(t, q[sel])
        for g, c in self._exits.items():  # each agent towards the exit it chooses now
            sel = np.flatnonzero(group == g)
            if len(sel):
                u[sel] = towards(c, t, q[sel], self.speed[ids[sel]])
        if self.scaled:
            u *= (self.speed[ids] / self.flows.group_speed[group])[:, None]
        if self.waits:
            u[t < self.start[ids]] = 0.0
        law = self.flows
        if law.time_gap is not None and law.law == "csm":
            r = self.radius[ids]
            walls = None
            if law.wall_repulsion > 0.0 and len(q):
                rows = single_rows(self.geometry, t, q, r, CUT * law.wall_range)
                walls = wall_terms(rows, len(q), law.wall_repulsion, law.wall_range)
            u = csm(q, r, u, law.time_gap, law.repulsion, law.repulsion_range,
                    law.lateral, law.fade, law.length, law.follow, walls)
        elif law.time_gap is not None:
            u = headway(q, self.radius[ids], u, law.time_gap, law.margin)
        return u

    # -- after a step ---------------------------------------------------------------------------
    def after_step(self, scene: Scene, t1: float, q: np.ndarray, *others: np.ndarray
                   ) -> tuple[bool, np.ndarray, list[np.ndarray]]:
        """Journeys advance, agents in sinks leave, due agents enter. q (N, 2): centres at t1
        (s); others: further (N, 2) arrays kept agent by agent (zeros for entering agents).
        Returns whether the agents changed, the new centres and the new others."""
        ids = self.ids
        if self._journey and len(ids):
            group, leg = self.group[ids], self.leg[ids]
            for g, j in self._journey.items():
                for k in range(len(j.fields) - 1):
                    sel = np.flatnonzero((group == g) & (leg == k))
                    if len(sel):
                        done = sel[j.reached(k, q[sel])]
                        self.leg[ids[done]] = k + 1
        changed = False
        if self.flows.sinks and len(ids):
            out = np.zeros(len(ids), dtype=bool)
            for s in self.flows.sinks:
                out |= s.contains(q)
            if out.any():
                for i in ids[out].tolist():
                    self.left_at[int(i)] = t1
                keep = ~out
                self.ids, q = ids[keep], q[keep]
                others = tuple(o[keep] for o in others)
                changed = True
        if self.flows.sources:
            new_q = self._enter(scene, t1, q)
            if len(new_q):
                q = np.concatenate([q, new_q])
                others = tuple(np.concatenate([o, np.zeros((len(new_q), 2))]) for o in others)
                changed = True
        if changed:
            self._view = None
        return changed, q, list(others)

    def _enter(self, scene: Scene, t1: float, q: np.ndarray) -> np.ndarray:
        """Place the agents due by t1 (s); returns their centres (M, 2) and appends their
        per-id values."""
        placed: list[np.ndarray] = []
        law = scene.radius_law
        grow = 0.0 if law.is_constant else float(law.offset(t1))  # r_i(t1) = base + grow
        r_present = self.radius[self.ids] + grow
        if self._grid is None and scene.spec.get("map") is not None:
            self._grid = map_from_spec(scene.spec["map"], "map", None)
        sources = self.flows.sources
        # the largest radius a disk filed in a source's grid can have (present or entering)
        r_top = max(float(r_present.max(initial=0.0)),
                    max((src.r_high for src in sources), default=0.0) + grow)
        for s_index, src in enumerate(sources):
            due = int(np.searchsorted(src.times, t1 + 1e-9, side="right"))
            if self.next[s_index] >= due:
                continue
            lo, hi = src.region.lo, src.region.hi
            others = np.concatenate([q] + placed) if placed else q
            entered = np.array([e[0] for e in self._entering])  # placed this step, base radii
            radii = np.concatenate([r_present, entered + grow]) if placed else r_present
            clear = EntryGrid(np.asarray(lo), np.asarray(hi), src.r_high + grow + r_top,
                              others, radii)
            while self.next[s_index] < due:
                r = (src.r_low if src.r_high == src.r_low
                     else src.r_low + self.rng.random() * (src.r_high - src.r_low))
                cand = lo + self.rng.random((TRIES, 2)) * (hi - lo)
                ok = src.region.contains(cand)
                if self._grid is not None:
                    ok &= ~self._grid.is_blocked(cand)
                if not scene.geometry.is_empty:
                    rr = np.full(TRIES, r + grow)
                    for a, _, _, _, _ in single_rows(scene.geometry, t1, cand, rr, 0.0):
                        ok[a] = False
                ok &= clear.clear(cand, r + grow)
                hit = np.flatnonzero(ok)
                if len(hit) == 0:
                    break  # no room now: this source's due agents wait for the next step
                placed.append(cand[hit[0]][None])
                clear.add(cand[hit[0]], r + grow)
                self._draw_entering(src, r, t1)
                self.next[s_index] += 1
        self._append_entered()
        self.waiting = sum(int(np.searchsorted(src.times, t1 + 1e-9, side="right")) - k
                           for src, k in zip(sources, self.next))
        return np.concatenate(placed) if placed else np.empty((0, 2))

    def _draw_entering(self, src: Source, r: float, t1: float) -> None:
        """Draws an entering agent's speed and delay (in this order, after its position and
        radius) and holds its per-id values until :meth:`_append_entered`."""
        speed = (draw(src.speeds, self.rng, 1)[0] if src.speeds is not None
                 else float(self.flows.group_speed[src.group]))
        delay = draw(src.delays, self.rng, 1)[0] if src.delays is not None else 0.0
        self._entering.append((r, src.group, speed, t1 + delay, t1))

    def _append_entered(self) -> None:
        """Appends the per-id values of the agents entered this step, in one copy each."""
        if not self._entering:
            return
        r, group, speed, start, at = (list(v) for v in zip(*self._entering))
        first = len(self.radius)
        m = len(r)
        self.radius = np.concatenate([self.radius, np.asarray(r, dtype=self.radius.dtype)])
        self.group = np.concatenate([self.group, np.asarray(group, dtype=self.group.dtype)])
        self.speed = np.concatenate([self.speed, np.asarray(speed, dtype=self.speed.dtype)])
        self.start = np.concatenate([self.start, np.asarray(start, dtype=self.start.dtype)])
        self.leg = np.concatenate([self.leg, np.zeros(m, dtype=self.leg.dtype)])
        self.entered_at = np.concatenate([self.entered_at,
                                          np.asarray(at, dtype=self.entered_at.dtype)])
        self.ids = np.concatenate([self.ids, np.arange(first, first + m, dtype=self.ids.dtype)])
        self.entered += m
        self._entering = []
