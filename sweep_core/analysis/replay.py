"""Re-simulate a recording and check it bit for bit (``sweep replay``).

Replay builds the simulator from the metadata record ``sweep_ros`` alone (scene, seed, dt,
scheme, solver settings; ``path_dt`` when the Brownian path was drawn finer than dt, see
:mod:`sweep_core.paths`), applies the recorded commands at their recorded steps (metadata
``command_*`` written by the node: the drift spec in effect from step ``step`` on), restarts at
each recorded reset (``reset_*``), applies recorded ``noise_sigma`` changes (``parameters`` at
start, ``parameter_*`` live) and the maps the node received (``map_*``: the scene's walls
rebuilt from the recorded packed map at its step, kept over later resets, as the node does),
and compares the raw float64 centres of every recorded
``/poses`` message with the simulator's, bit for bit, and every robot's recorded ``/NAME/odom``
(x, y and the yaw's quaternion) with its replayed pose encoded the same way. Steps that were
not recorded (``sweep run --record-every K``, node ticks of several steps) are simulated but not
compared. The same
versions of the libraries in :data:`~sweep_core.io.versions.SHAPING` give the same floats on any
x86-64 CPU (nothing that decides positions takes a CPU-dependent code path); the recorded
versions and platform are checked and differences are reported. After a first difference the
replay goes on along its own path to the end of the recording and reports how far it departs:
the largest distance from the recorded poses and the first step where it exceeds
:data:`DEPARTURE_M`.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sweep_core.analysis.frames import FrameReader, GapFinder, progress_bar
from sweep_core.analysis.report import jsonable
from sweep_core.analysis.robot_replay import (
    apply_commands,
    drive_by_recording,
    odometry_difference,
    place_recorded,
    recorded_commands,
    recorded_odometry,
)
from sweep_core.analysis.run import MapChange, RunMeta, load_run, require_replayable, scene_with_map
from sweep_core.errors import InfeasibleError, RecordingError, SweepError
from sweep_core.io.versions import SHAPING, platform_record, versions
from sweep_core.numerics import paths
from sweep_core.numerics.simulator import Simulator

#: a departure from the recorded poses (m) above the rounding of float64 positions
DEPARTURE_M = 1e-9
#: attempts at one step that keeps failing (the node retries a failed step after a resume,
#: drawing new increments each time)
MAX_ATTEMPTS = 100


@dataclass
class Divergence:
    """The first recorded state the replay does not reproduce."""

    step: int
    t_s: float
    segment: int
    agent: int
    recorded: list[float]
    replayed: list[float]
    distance_m: float
    agents_differing: int
    max_distance_m: float
    reason: str = "positions differ"
    #: over the frames from this one to the last one replayed: the largest distance of an
    #: agent from its recorded pose (m), and the first step (time, s) where it exceeds
    #: DEPARTURE_M (None: it never does)
    departure_max_m: float = 0.0
    departure_step: int | None = None
    departure_t_s: float | None = None
    frames_after: int = 0


@dataclass
class ReplayResult:
    path: str
    identical: bool
    frames_compared: int
    steps_simulated: int
    last_step: int
    last_t_s: float
    segments: int
    commands_applied: int
    truncated: bool
    read_until: str | None
    divergence: Divergence | None
    notes: list[str] = field(default_factory=list)
    #: recorded maps (``map_*``) the replay rebuilt the walls with
    maps_applied: int = 0
    #: /poses messages missing from the file (their steps were not compared), see ``gaps``
    missing_messages: int = 0
    #: [segment, after_step, before_step, missing] of each gap
    gaps: list[list[int]] = field(default_factory=list)
    #: messages skipped because they cannot be decoded (their steps were not compared)
    skipped_messages: int = 0
    #: chunks that could not be read (damaged: CRC mismatch, ...) and were skipped: the gaps
    #: may be their states
    skipped_chunks: int = 0
    #: one line per skipped chunk or message and per gap
    problems: list[str] = field(default_factory=list)
    #: why the comparison stopped before the end (robots' commands lost with an unreadable
    #: chunk: the steps after them cannot be replayed), or None
    stopped: str | None = None

    def to_dict(self) -> dict:
        d = dict(self.__dict__)
        d["divergence"] = None if self.divergence is None else dict(self.divergence.__dict__)
        return jsonable(d)


def version_notes(meta: RunMeta) -> list[str]:
    """Differences between the recorded versions and these that can change floats: sweep_ros
    itself (its engine) and the libraries of :data:`~sweep_core.io.versions.SHAPING`."""
    now = versions()
    out = []
    for name in ("sweep_ros", *SHAPING):
        rec = meta.versions.get(name)
        if rec is not None and rec != now.get(name):
            out.append(f"{name} {now.get(name)} here, {rec} in the recording: bit identity is "
                       "only guaranteed with the recorded versions")
    return out


def platform_notes(meta: RunMeta) -> list[str]:
    """Differences between the platform the recording was made on and this one (positions
    are the same on any x86-64 CPU with the same versions; another architecture or operating
    system may round differently)."""
    try:
        rec = json.loads(meta.raw.get("platform") or "{}")
    except ValueError:
        return ["the recording's platform record is not JSON"]
    if not isinstance(rec, dict) or not rec:
        return []
    here = platform_record()
    return [f"recorded on {key} {rec.get(key)!r}, replayed on {here[key]!r}"
            for key in here if key in rec and rec[key] != here[key]]


def make_simulator(meta: RunMeta) -> Simulator:
    """A simulator at t = 0 exactly as the recording describes it."""
    require_replayable(meta)
    return Simulator(meta.scene, dt=meta.dt, seed=meta.seed, scheme=meta.scheme,
                     solver=meta.solver_options())


class _Replayer:
    """Steps a simulator through the recorded segments, commands and parameter changes."""

    def __init__(self, meta: RunMeta) -> None:
        self.meta = meta
        self.sim = make_simulator(meta)
        self.path = (paths.FinePath(meta.seed, meta.dt, meta.path_dt, meta.scene.n_agents)
                     if meta.path_dt else None)
        self.segment = 0
        self.events: list[tuple[int, int, str, Any]] = []
        self.applied = 0
        self.simulated = 0
        self.retries = 0
        self.noise_sigma = self.meta.parameters.get("noise_sigma", -1.0)
        self.map_index: int | None = None  # the recorded map in effect (None: the scene's)
        self.maps_applied = 0
        lost: list[int] = []
        self.robot_commands = recorded_commands(meta, lost)  # robots' /NAME/cmd_vel, if any
        #: log time (ns) from which an unreadable chunk may have held robots' commands
        self.commands_lost_from: int | None = lost[0] if lost else None
        drive_by_recording(self.sim)
        self._start(0)

    def _map(self, change: MapChange) -> None:
        if self.meta.scene is None:
            return
        self.sim.set_scene(scene_with_map(self.meta.scene, change.spec))
        self.map_index = change.index
        self.maps_applied += 1

    def _sigma(self, value: Any) -> None:
        self.noise_sigma = value
        if value is None or value == -1.0:
            self.sim.set_sigma(self.meta.scene.sigma)
        else:
            self.sim.set_sigma(float(value) if np.ndim(value) == 0
                               else np.asarray(value, dtype=np.float64))

    def _start(self, segment: int) -> None:
        """Back to t = 0 for a segment: the node's reset (scene drift, sigma, then the
        noise_sigma parameter in effect)."""
        self.segment = segment
        self.sim.reset()
        if self.path is not None:
            self.path.reset()
        epoch = self.meta.resets[segment - 1] if segment else 0
        for ch in self.meta.parameter_changes:  # the value in effect at the reset
            if ch.name == "noise_sigma" and ch.segment < segment and ch.log_time_ns < epoch:
                self.noise_sigma = ch.value
        self._sigma(self.noise_sigma)
        # a map received before this segment is still in effect (the node keeps it on reset)
        earlier = [m for m in self.meta.maps if m.segment < segment]
        if earlier and earlier[-1].index != self.map_index:
            self._map(earlier[-1])
        ev: list[tuple[int, int, str, Any]] = [
            (c.step, c.index, "command", c.spec) for c in self.meta.commands
            if c.segment == segment]
        ev += [(m.step, m.index, "map", m) for m in self.meta.maps if m.segment == segment]
        ev += [(c.step, c.index, "parameter", c) for c in self.meta.parameter_changes
               if c.segment == segment and c.name == "noise_sigma"]
        ev += [(p.step, p.index, "robot_pose", p.spec) for p in self.meta.robot_poses
               if p.segment == segment]
        self.events = sorted(ev, key=lambda e: (e[0], e[2], e[1]))

    def advance_to(self, segment: int, step: int) -> None:
        if segment != self.segment:
            self._start(segment)
        if step < self.sim.n_steps:
            raise RecordingError(f"{self.meta.path}: a state of step {step} is recorded after "
                                 f"step {self.sim.n_steps} without a reset")
        while self.sim.n_steps < step:
            k = self.sim.n_steps
            while self.events and self.events[0][0] <= k:
                _, _, kind, what = self.events.pop(0)
                if kind == "command":
                    self.sim.set_drift(self.sim.scene.drift_from_spec(what))
                    self.applied += 1
                elif kind == "map":
                    self._map(what)
                elif kind == "robot_pose":
                    place_recorded(self.sim, what)
                else:
                    self._sigma(what.value)
            apply_commands(self.sim, self.robot_commands, self.segment, k + 1)
            for attempt in range(MAX_ATTEMPTS):
                try:
                    if self.path is not None:
                        paths.step(self.sim, self.path)
                    else:
                        self.sim.step()
                    break
                except InfeasibleError:
                    if attempt == MAX_ATTEMPTS - 1:
                        raise
                    self.retries += 1
            self.simulated += 1


def _depart(div: Divergence, step: int, t: float, distance: float) -> None:
    """Counts one frame at or after the first divergence, ``distance`` (m) from its pose."""
    div.frames_after += 1
    div.departure_max_m = max(div.departure_max_m, distance)
    if div.departure_step is None and distance > DEPARTURE_M:
        div.departure_step, div.departure_t_s = step, t


def _bits_equal(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per agent: both coordinates have the same float64 bits."""
    a = np.ascontiguousarray(a, dtype=np.float64).view(np.uint64)
    b = np.ascontiguousarray(b, dtype=np.float64).view(np.uint64)
    return np.all(a == b, axis=1)


def replay(path: str | Path, progress: bool = False) -> ReplayResult:
    """Re-simulates ``path`` and compares every recorded pose bit for bit (see module doc).

    Stops at the first differing frame and reports its step and agent (the first agent whose
    centre differs; ``max_distance_m`` over all agents).
    """
    meta = load_run(path)
    rep = _Replayer(meta)
    odometry = recorded_odometry(meta)
    reader, finder = FrameReader(meta, agents=False), GapFinder(meta.record_every)
    notes = version_notes(meta) + platform_notes(meta)
    compared, last_step, last_t = 0, 0, 0.0
    div: Divergence | None = None
    stopped: str | None = None
    bar = progress_bar(meta.frames or None, "frame", progress)
    with bar:
        for fr in reader:
            bar.update()
            seg = meta.segment_of(fr.log_ns)
            step = meta.step_of(fr.stamp_ns)
            t = step * meta.dt
            lost = rep.commands_lost_from
            if div is None and lost is not None and fr.log_ns >= lost:
                stopped = (f"the robots' commands recorded after step {last_step} (t = "
                           f"{last_t:.6g} s) were lost with an unreadable chunk, so the later "
                           "steps cannot be replayed")
                break
            finder.add(fr, seg, step)
            try:
                rep.advance_to(seg, step)
            except SweepError as err:
                if div is None:
                    q = fr.positions
                    div = Divergence(step, t, seg, -1, [], [], math.inf, len(q), math.inf,
                                     f"the replay cannot reach this step: {err}")
                break  # a replay departed already ends here on its own path
            q, mine = fr.positions, rep.sim.positions
            if q.shape != mine.shape:
                if div is None:
                    div = Divergence(step, t, seg, -1, [], [], math.inf, len(q), math.inf,
                                     f"{len(q)} poses recorded, {len(mine)} agents replayed")
                break
            if div is not None:  # departed already: how far, along the replay's own path
                _depart(div, step, t, float(np.hypot(*(q - mine).T).max()))
                continue
            same = _bits_equal(q, mine)
            if not same.all():
                bad = np.nonzero(~same)[0]
                dist = np.hypot(*(q - mine).T)
                i = int(bad[0])
                div = Divergence(step, t, seg, i, q[i].tolist(), mine[i].tolist(),
                                 float(dist[i]), int(len(bad)), float(dist.max()))
                _depart(div, step, t, div.max_distance_m)
                continue
            moved = odometry_difference(rep.sim, odometry.get((seg, step), {}))
            if moved:
                div = Divergence(step, t, seg, -1, [], [], math.inf, 0, math.inf, moved)
                _depart(div, step, t, 0.0)
                continue
            compared += 1
            last_step, last_t = step, t
    if reader.truncated is None:  # stopped early at a divergence: the file was not read out
        reader.truncated = meta.truncated
        reader.error = meta.error
    if compared == 0 and div is None:
        raise RecordingError(f"{meta.path}: no complete frame (poses) to replay"
                             + reader.none_read())
    if rep.retries:
        notes.append(f"{rep.retries} infeasible step attempts were retried, as the node does "
                     "when resumed")
    return ReplayResult(
        path=meta.path, identical=div is None and stopped is None, frames_compared=compared,
        steps_simulated=rep.simulated, last_step=last_step, last_t_s=last_t,
        segments=len(meta.resets) + 1, commands_applied=rep.applied,
        truncated=bool(reader.truncated), read_until=reader.error if reader.truncated else None,
        divergence=div, notes=notes, maps_applied=rep.maps_applied,
        missing_messages=finder.missing, gaps=(finder.to_dict() or {}).get("gaps", []),
        skipped_messages=reader.bad, problems=reader.problems + finder.lines(meta.path),
        stopped=stopped, skipped_chunks=len(reader.skipped_chunks))


def format_replay(res: ReplayResult) -> str:
    lines = []
    if res.truncated:
        lines.append(f"truncated recording: read up to its last complete chunk "
                     f"({res.read_until})")
    lines.append(f"frames compared    {res.frames_compared} (last: step {res.last_step}, "
                 f"t = {res.last_t_s:.6g} s)")
    lines.append(f"steps simulated    {res.steps_simulated} in {res.segments} segment(s), "
                 f"{res.commands_applied} command(s) applied"
                 + (f", {res.maps_applied} map(s)" if res.maps_applied else ""))
    d = res.divergence
    unread = res.missing_messages + res.skipped_messages
    missing = "missing from the file" + (" or in a skipped chunk" if res.skipped_chunks else "")
    if res.stopped is not None:
        lines.append(f"result             NOT COMPARED to the end: {res.stopped}")
    elif d is None and unread:
        lines.append(f"result             IDENTICAL on the {res.frames_compared} frames read; "
                     f"{unread} recorded states were not compared ({res.missing_messages} "
                     f"{missing}, {res.skipped_messages} unreadable)")
    elif d is None:
        lines.append("result             IDENTICAL: every recorded pose reproduced bit for bit")
    elif d.agent < 0:
        lines.append(f"result             DIVERGED at step {d.step} (t = {d.t_s:.6g} s, "
                     f"segment {d.segment}): {d.reason}")
    else:
        lines.append(f"result             DIVERGED at step {d.step} (t = {d.t_s:.6g} s, "
                     f"segment {d.segment}), first agent {d.agent}: recorded "
                     f"{d.recorded}, replayed {d.replayed} ({d.distance_m:.3g} m); "
                     f"{d.agents_differing} agents differ, at most by {d.max_distance_m:.3g} m")
        over = ("never beyond 1e-9 m" if d.departure_step is None else
                f"beyond {DEPARTURE_M:g} m from step {d.departure_step} "
                f"(t = {d.departure_t_s:.6g} s)")
        lines.append(f"departure          over {d.frames_after} frames from there: at most "
                     f"{d.departure_max_m:.3g} m, {over}")
    lines += [f"not compared       {g[3]} states between the recorded steps {g[1]} and {g[2]}"
              + (f" of segment {g[0]}" if g[0] else "") + f" ({missing})"
              for g in res.gaps[:5]]
    if len(res.gaps) > 5:
        lines.append(f"not compared       {len(res.gaps) - 5} more gaps")
    lines += [f"note               {n}" for n in res.notes]
    return "\n".join(lines)
