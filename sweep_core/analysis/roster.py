"""Agents by id across the frames of a recording whose scene has ``flows`` (sinks and sources
change the agents from frame to frame): who entered and when, who left and when, the radii of
the present agents, and the positions of the agents two frames share.

Ids come from the ``id`` field of ``/agents`` (float32: exact up to 2^24 ids). An agent's
entry time is the first frame that holds it, its leaving time the first frame (after one that
held it) that does not: with ``--record-every K`` both are late by less than K steps.
"""
from __future__ import annotations

import numpy as np

from sweep_core.analysis.arrivals import stats, time_for
from sweep_core.errors import RecordingError
from sweep_core.model.scene import Scene


def grow(a: np.ndarray, n: int, fill: float = np.nan) -> np.ndarray:
    """a (M,) extended to length n with ``fill`` (unchanged if M >= n)."""
    if len(a) >= n:
        return a
    return np.concatenate([a, np.full(n - len(a), fill, dtype=a.dtype)])


def id_bound(scene: Scene) -> int:
    """One more than the largest id an agent of ``scene`` can have: its initial agents and
    every agent its sources can emit."""
    flows = scene.flows
    return scene.n_agents + sum(len(s.times) for s in (flows.sources if flows else ()))


def agent_ids(agents: dict[str, np.ndarray] | None, n: int, t: float, path: str,
              top: int) -> np.ndarray:
    """The ids (n,) of a frame's n agents at t (s), from its ``/agents`` columns: distinct
    whole numbers below ``top`` (:func:`id_bound`: what a run of the scene can number), else a
    RecordingError (a recording's ids size the arrays kept by id: never taken on trust)."""
    if agents is None or "id" not in agents or len(agents["id"]) != n:
        raise RecordingError(f"{path}: the frame at t = {t:g} s has no readable /agents ids, "
                             "which a scene with flows needs to follow its agents (fix: "
                             "record /agents, as sweep run does)")
    raw = agents["id"].astype(np.float64)
    bad = ~(np.isfinite(raw) & (raw >= 0) & (raw < top) & (raw == np.rint(raw)))
    ids = np.where(bad, -1, raw).astype(np.int64)
    if np.any(bad) or len(np.unique(ids)) != n:
        what = (f"id {raw[np.argmax(bad)]:g} is not a whole number in [0, {top})" if np.any(bad)
                else "two agents have one id")
        raise RecordingError(f"{path}: the frame at t = {t:g} s: /agents {what}, the ids a "
                             "run of the recorded scene gives (its agents and what its "
                             "sources emit) (fix: use a recording made by sweep run or "
                             "sweep_node)")
    return ids


class Roster:
    """Entry and leaving times by id (module docstring) of a recording of ``scene``."""

    def __init__(self, scene: Scene, path: str) -> None:
        self.scene, self.path = scene, path
        self.n0 = scene.n_agents
        #: one more than the largest id the scene's agents can have
        self.top = id_bound(scene)
        self.entered_at = np.zeros(0)
        self.left_at = np.zeros(0)
        self.present = np.zeros(0, dtype=np.int64)
        #: the most agents one frame holds
        self.present_max = 0
        self.frames = 0
        self.t_last = 0.0  # the last frame's time (s)
        flows = scene.flows
        sources = flows.sources if flows is not None else ()
        fixed = {s.r_low for s in sources if s.r_low == s.r_high}
        #: the radius (m) of every entering agent when all sources give the same one
        self.source_radius = (fixed.pop() if len(fixed) == 1 and all(
            s.r_low == s.r_high for s in sources) else None)

    def ids(self, agents: dict[str, np.ndarray] | None, n: int, t: float) -> np.ndarray:
        """The ids (n,) of a frame's agents at t (s), from its ``/agents`` columns."""
        return agent_ids(agents, n, t, self.path, self.top)

    def add(self, ids: np.ndarray, t: float) -> None:
        """Marks the agents ``ids`` present at t (s): new ones entered, missing ones left."""
        top = int(ids.max()) + 1 if len(ids) else 0
        self.entered_at = grow(self.entered_at, top, np.nan)
        self.left_at = grow(self.left_at, top, np.nan)
        new = ids[np.isnan(self.entered_at[ids])]
        self.entered_at[new] = 0.0 if self.frames == 0 else t
        gone = np.setdiff1d(self.present, ids, assume_unique=True)
        self.left_at[gone] = t
        self.present = ids
        self.present_max = max(self.present_max, len(ids))
        self.frames += 1
        self.t_last = t

    def radii(self, ids: np.ndarray, agents: dict[str, np.ndarray], t: float) -> np.ndarray:
        """Radii (n,) m of the agents ``ids`` at t (s): float64 from the scene for its own
        agents and for entering agents of a single source radius, else the float32 of
        ``/agents``."""
        r = agents["radius"].astype(np.float64)
        law = self.scene.radius_law
        own = ids < self.n0
        r[own] = self.scene.radius[ids[own]] + (0.0 if law.is_constant else law.offset(t))
        if self.source_radius is not None:
            r[~own] = self.source_radius + (0.0 if law.is_constant else law.offset(t))
        return r

    @staticmethod
    def common(ids_a: np.ndarray, q_a: np.ndarray, ids_b: np.ndarray, q_b: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The ids two frames share (increasing) and their centres in each, (M,), (M, 2) x 2."""
        both, ia, ib = np.intersect1d(ids_a, ids_b, assume_unique=True, return_indices=True)
        return both, q_a[ia], q_b[ib]

    @property
    def total(self) -> int:
        """Agents seen in all (the scene's and the entered)."""
        return int(np.count_nonzero(np.isfinite(self.entered_at)))

    def summary(self) -> dict:
        """Counts and times: entered, left, present at the end (N0 + entered = present + left)
        and at most (in one frame), leaving times (arrivals at the sinks) and travel times
        (leaving minus entry)."""
        left = self.left_at
        n = self.total
        entered = int(np.count_nonzero(np.isfinite(self.entered_at[self.n0:])))
        gone = int(np.count_nonzero(np.isfinite(left)))
        travel = left - self.entered_at
        # the sources' agents due by the last frame (an agent enters at the end of the step
        # it is due in, when its region has room; else it waits, and those behind it too)
        flows = self.scene.flows
        due = sum(int(np.count_nonzero(src.times <= self.t_last + 1e-9))
                  for src in (flows.sources if flows is not None else ()))
        return {
            "initial": self.n0, "entered": entered, "due": due,
            "waiting_at_end": max(due - entered, 0), "left": gone,
            "present_at_end": int(len(self.present)), "present_max": self.present_max,
            "conserved": self.n0 + entered == len(self.present) + gone,
            "left_t_first_s": stats(left, np.min), "left_t_50_s": time_for(left, n, 0.5),
            "left_t_90_s": time_for(left, n, 0.9), "left_t_all_s": time_for(left, n, 1.0),
            "travel_time_mean_s": stats(travel, np.mean),
            "travel_time_min_s": stats(travel, np.min),
            "travel_time_max_s": stats(travel, np.max),
            "precision": "times of the first recorded frame holding (entry) or no longer "
                         "holding (leaving) an agent, by its /agents id",
        }

    def report(self, summary: dict) -> np.ndarray:
        """Adds ``population`` (:meth:`summary`) and, when agents left, ``arrivals`` (the
        leaving times) to an analysis summary; returns the leaving time by id (NaN: stayed)."""
        pop = summary["population"] = self.summary()
        if pop["left"]:
            summary["arrivals"] = {
                "arrived": pop["left"], "t_first_s": pop["left_t_first_s"],
                "t_mean_s": stats(self.left_at, np.mean), "t_50_s": pop["left_t_50_s"],
                "t_90_s": pop["left_t_90_s"], "t_all_s": pop["left_t_all_s"],
                "precision": "agents that left at a sink: " + pop["precision"]}
        return self.left_at
