"""An agent's speed as crowd science measures it: its displacement over a time window centred
on the frame, from the recorded positions (:class:`WindowSpeeds`).

For an agent present at a frame of time t (s) and a window w (s)::

    v(t) = (q(t_b) - q(t_a)) / (t_b - t_a),  speed = |v(t)|

with t_a the recorded frame nearest t - w/2 and t_b the one nearest t + w/2 (so t_b - t_a is w
to within a frame interval; the times are the recorded simulation times, whatever the spacing
of the frames). Where the agent is not present at t_a (it entered later, or the recording or
its reset segment starts later) the window is one-sided, t_a = t; likewise t_b = t where it is
not present at t_b. An agent present at neither has no speed at that frame (NaN). This is
PedPy's ``compute_individual_speed`` with ``frame_step`` n = w / (2 h) for frames h apart and
``SpeedCalculation.BORDER_SINGLE_SIDED``, and JPSreport's velocity with ``frame_step`` 2n
(docs/analysis.md, "How speed is measured").

The default window :data:`DEFAULT_WINDOW_S` = 0.625 s is the Jülich group's practice:
JPSreport's default ``frame_step`` of 10 frames on their experiments' 16 frames per second.

Frames are fed in recording order (:meth:`WindowSpeeds.push`); a frame comes back with its
velocities once the frame nearest t + w/2 has been read (or its segment has ended), so memory
holds about one window of frames. Every step is vectorised over the agents of a frame.
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from sweep_core.analysis.crowd import Fundamental
from sweep_core.analysis.frames import Frame, FrameReader
from sweep_core.analysis.roster import grow
from sweep_core.analysis.run import RunMeta
from sweep_core.errors import SweepError

__all__ = ["DEFAULT_WINDOW_S", "Ready", "SpeedStats", "WindowSpeeds", "check_spacing",
           "check_window", "choose_window", "fits", "window_speeds", "with_speeds"]

#: the default window (s): JPSreport's default frame_step (10 frames) at the 16 frames per
#: second of the Jülich experiments' trajectories
DEFAULT_WINDOW_S = 0.625
#: what every figure and summary says of the speed it shows
WHAT = "displacement over a window centred on the frame"
#: width of the speed histogram bins (m/s); speed quantiles are exact to half of it
SPEED_BIN = 1e-3


def check_window(window: Any, option: str = "--speed-window") -> float:
    """The window (s) as a float, or a SweepError naming ``option``, the value and the fix."""
    ok = (not isinstance(window, bool) and isinstance(window, (int, float))
          and math.isfinite(window) and window > 0)
    if not ok:
        raise SweepError(f"{option}: must be a positive number of seconds, got {window!r} "
                         f"(fix: give a window such as {DEFAULT_WINDOW_S:g}, the default)")
    return float(window)


def check_spacing(window: float, interval: float, option: str = "--speed-window") -> None:
    """Refuses a window shorter than two frame intervals of ``interval`` s (then no frame lies
    either side of a window's centre)."""
    if window < 2.0 * interval * (1.0 - 1e-9):
        raise SweepError(f"{option}: {window:g} s is shorter than two of the recording's frame "
                         f"intervals ({interval:g} s apart) (fix: give at least "
                         f"{2.0 * interval:g} s)")


def fits(window: float, times: np.ndarray, option: str = "--speed-window",
         given: bool = True) -> str | None:
    """Refuses a window longer than the recording (its frame times ``times`` (K,) s) or shorter
    than two of its (median) frame intervals. The default window (``given`` False) is not
    refused: when it is longer than the recording, the note the summary carries says so (its
    speeds are one-sided or missing); else None."""
    span = float(times[-1] - times[0]) if len(times) else 0.0
    if not given:
        return None if window <= span else (
            f"the default window {window:g} s is longer than the recording ({span:g} s from "
            "its first to its last frame): every speed is one-sided or missing (fix: give "
            f"--speed-window of at most {span:g} s)")
    if window > span:
        raise SweepError(f"{option}: {window:g} s is longer than the recording ({span:g} s "
                         f"from its first to its last frame) (fix: give a window of at most "
                         f"{span:g} s)")
    steps = np.diff(times)
    steps = steps[steps > 0]
    check_spacing(window, float(np.median(steps)) if len(steps) else 0.0, option)
    return None


def choose_window(given: Any, interval: float | None, option: str = "--speed-window"
                  ) -> float:
    """The window (s) to use: ``given`` checked (:func:`check_window`, and not shorter than two
    frame intervals of ``interval`` s when the recording says it), else the default widened to
    two frame intervals."""
    if given is not None:
        window = check_window(given, option)
        if interval:
            check_spacing(window, interval, option)
        return window
    return max(DEFAULT_WINDOW_S, 2.0 * interval) if interval else DEFAULT_WINDOW_S


@dataclass
class _Entry:
    t: float
    ids: np.ndarray  # (N,) int64 as recorded
    q: np.ndarray  # (N, 2) m
    sorted_ids: np.ndarray  # (N,) increasing
    order: np.ndarray  # argsort of ids
    payload: Any


@dataclass
class Ready:
    """A frame whose velocities are known: what :meth:`WindowSpeeds.push` was given
    (``payload``, ``t`` s, ``ids`` (N,), ``q`` (N, 2) m), the velocities ``v`` (N, 2) m/s and
    ``speed`` (N,) m/s (NaN: no window), and ``span`` (N,) s, the time each displacement spans."""

    payload: Any
    t: float
    ids: np.ndarray
    q: np.ndarray
    v: np.ndarray
    speed: np.ndarray
    span: np.ndarray


class WindowSpeeds:
    """Velocities over a centred window of ``window`` s (module docstring), frame by frame."""

    def __init__(self, window: float) -> None:
        self.window = check_window(window, "window")
        self.half = 0.5 * self.window
        self.frames: deque[_Entry] = deque()  # kept frames of the current segment
        self.pending = 0  # the last ``pending`` kept frames have not been given back
        self.segment: Any = None
        self.first_gap = math.nan  # the segment's first frame interval (s)
        self.t_first = math.nan

    def push(self, t: float, ids: np.ndarray, q: np.ndarray, payload: Any = None,
             segment: Any = 0) -> list[Ready]:
        """One frame: time t (s, increasing within a segment), the agents' ids (N,) and
        centres (N, 2) m; windows never reach across segments (resets). Returns the frames
        now complete, in order."""
        out: list[Ready] = []
        if self.frames and segment != self.segment:
            out += self.finish()
        if not self.frames:
            self.segment, self.t_first, self.first_gap = segment, t, math.nan
        elif math.isnan(self.first_gap):
            self.first_gap = t - self.t_first
        ids = np.asarray(ids, dtype=np.int64)
        order = np.argsort(ids, kind="stable")
        self.frames.append(_Entry(float(t), ids, np.asarray(q, dtype=np.float64),
                                  ids[order], order, payload))
        self.pending += 1
        while self.pending and self.frames[-1].t >= self._oldest().t + self.half:
            out.append(self._emit(len(self.frames) - self.pending))
        return out

    def finish(self) -> list[Ready]:
        """The frames still waiting (the segment or recording ended), in order."""
        out = [self._emit(len(self.frames) - self.pending) for _ in range(self.pending)]
        self.frames.clear()
        return out

    def _oldest(self) -> _Entry:
        return self.frames[len(self.frames) - self.pending]

    def _nearest(self, target: float) -> int | None:
        """Index of the kept frame nearest ``target`` (ties: the later), None when the target
        lies beyond the segment's frames by more than half a frame interval."""
        times = np.fromiter((e.t for e in self.frames), dtype=np.float64, count=len(self.frames))
        if target < times[0]:
            # the oldest waiting frame's past is never dropped (_emit), so times[0] is the
            # segment's first frame here
            if math.isnan(self.first_gap):
                return None
            return 0 if times[0] - target <= 0.5 * self.first_gap else None
        if target > times[-1]:  # only once the segment has ended (push waits otherwise)
            if len(times) < 2:
                return None
            return len(times) - 1 if target - times[-1] <= 0.5 * (times[-1] - times[-2]) \
                else None
        j = int(np.searchsorted(times, target, side="left"))
        if times[j] == target or j == 0:
            return j
        return j if times[j] - target <= target - times[j - 1] else j - 1

    def _emit(self, k: int) -> Ready:
        cur = self.frames[k]
        a, b = self._nearest(cur.t - self.half), self._nearest(cur.t + self.half)
        pa, ta = self._side(cur, a, k)
        pb, tb = self._side(cur, b, k)
        span = tb - ta
        with np.errstate(invalid="ignore", divide="ignore"):
            v = np.where(span[:, None] > 0, (pb - pa) / span[:, None], np.nan)
        self.pending -= 1
        # frames before the oldest waiting frame's past target cannot be nearest to it again
        if self.pending:
            target = self._oldest().t - self.half
            while len(self.frames) > 1 and self.frames[1].t <= target:
                self.frames.popleft()
        return Ready(cur.payload, cur.t, cur.ids, cur.q, v, np.hypot(v[:, 0], v[:, 1]), span)

    def _side(self, cur: _Entry, j: int | None, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Positions (N, 2) and times (N,) of the agents of ``cur`` at kept frame j: their own
        centre and time where they are not there (or j is None or the frame itself)."""
        n = len(cur.ids)
        if j is None or j == k:
            return cur.q, np.full(n, cur.t)
        other = self.frames[j]
        if len(other.ids) == 0 or n == 0:
            return cur.q, np.full(n, cur.t)
        idx = np.minimum(np.searchsorted(other.sorted_ids, cur.ids), len(other.ids) - 1)
        found = other.sorted_ids[idx] == cur.ids
        p = np.where(found[:, None], other.q[other.order[idx]], cur.q)
        return p, np.where(found, other.t, cur.t)


def with_speeds(meta: RunMeta, window: float | None, problems: list[str] | None = None
                ) -> Iterator[tuple[Frame, np.ndarray | None]]:
    """The recording's frames in order, each with its agents' speeds (N,) m/s over ``window``
    s (:mod:`sweep_core.analysis.speed`; NaN: none), or None without a window. Once read to
    the end, what was skipped (chunks, messages: one line each) is added to ``problems``."""
    reader = FrameReader(meta)
    if window is None:
        yield from ((fr, None) for fr in reader)
        if problems is not None:
            problems += reader.problems
        return
    ws = WindowSpeeds(window)
    for fr in reader:
        n = len(fr.positions)
        ag = fr.agents
        ids = (np.rint(ag["id"].astype(np.float64)).astype(np.int64)
               if ag is not None and "id" in ag and len(ag["id"]) == n else np.arange(n))
        for r in ws.push(fr.stamp_ns / 1e9, ids, fr.positions, fr, meta.segment_of(fr.log_ns)):
            yield r.payload, r.speed
    if problems is not None:
        problems += reader.problems
    for r in ws.finish():
        yield r.payload, r.speed


def window_speeds(times: np.ndarray, q: np.ndarray, window: float) -> np.ndarray:
    """Speeds (K, N) m/s of N agents present at all K frames (times (K,) s, centres (K, N, 2)
    m) over a centred window of ``window`` s: :class:`WindowSpeeds` on whole arrays."""
    ws = WindowSpeeds(window)
    ids = np.arange(q.shape[1])
    out = []
    for t, p in zip(times, q):
        out += ws.push(float(t), ids, p)
    out += ws.finish()
    return np.array([r.speed for r in out]).reshape(len(times), q.shape[1])


def _quantile(hist: np.ndarray, p: float) -> float | None:
    total = int(hist.sum())
    if total == 0:
        return None
    i = int(np.searchsorted(np.cumsum(hist), p * total))
    return (i + 0.5) * SPEED_BIN


class SpeedStats:
    """What ``sweep analyze`` keeps of the speeds (:class:`Ready` frames fed by
    :meth:`add`): per frame their mean and max, a histogram (bins of :data:`SPEED_BIN`), the
    fundamental diagram, and each agent's sum, for the groups' means."""

    def __init__(self, window: float) -> None:
        self.window = window
        self.rows: list[tuple[float, float]] = []  # per frame: mean, max (m/s)
        self.hist = np.zeros(0, dtype=np.int64)
        self.total, self.count, self.max = 0.0, 0, 0.0
        self.spans = 0.0  # sum of the times the speeds' displacements span (s)
        self.no_window = 0  # agent-frames without a speed (present at neither end)
        self.agent_sum = np.zeros(0)  # per agent id: sum of its speeds (m/s)
        self.agent_frames = np.zeros(0)  # ... and how many
        self.fundamental = Fundamental()

    def frame(self) -> int:
        """A new frame (its speeds come later); returns its index."""
        self.rows.append((math.nan, math.nan))
        return len(self.rows) - 1

    def add(self, ready: list[Ready], index: Any = lambda r: r.payload[0]) -> None:
        """Frames whose windows are complete (``index(r)``: the frame's index)."""
        for r in ready:
            ok = np.isfinite(r.speed)
            v = r.speed[ok]
            self.no_window += int(len(ok) - len(v))
            if not len(v):
                continue
            self.rows[index(r)] = (float(v.mean()), float(v.max()))
            self.total += math.fsum(v)
            self.count += len(v)
            self.spans += math.fsum(r.span[ok])
            self.max = max(self.max, float(v.max()))
            counts = np.bincount(np.floor(v / SPEED_BIN).astype(np.int64))
            self.hist = grow(self.hist, len(counts), 0)
            self.hist[:len(counts)] += counts
            self.fundamental.add(r.q[ok], v)
            top = int(r.ids.max()) + 1
            self.agent_sum = grow(self.agent_sum, top, 0.0)
            self.agent_frames = grow(self.agent_frames, top, 0.0)
            self.agent_sum += np.bincount(r.ids[ok], weights=v, minlength=len(self.agent_sum))
            self.agent_frames += np.bincount(r.ids[ok], minlength=len(self.agent_frames))

    def table(self) -> np.ndarray:
        """(frames, 2): each frame's mean and max speed (m/s; NaN: none)."""
        return np.array(self.rows, dtype=np.float64).reshape(-1, 2)

    def summary(self) -> dict[str, Any]:
        """The summary's ``speed`` section."""
        some = self.count > 0
        return {
            "window_s": self.window,
            "span_mean_s": self.spans / self.count if some else None,
            "mean_m_per_s": self.total / self.count if some else None,
            "max_m_per_s": self.max if some else None,
            "p10_m_per_s": _quantile(self.hist, 0.10),
            "p50_m_per_s": _quantile(self.hist, 0.50),
            "p90_m_per_s": _quantile(self.hist, 0.90),
            "samples": self.count,
            "without_window": self.no_window,
            "precision": f"float64 (/poses): {WHAT} (window_s, between the recorded frames "
                         "nearest its ends; span_mean_s: the time they span on average; "
                         "one-sided where the agent or the recording starts or ends within "
                         "it, as PedPy's compute_individual_speed), every agent of every "
                         f"frame; quantiles to {SPEED_BIN / 2:g} m/s",
        }

    def group_mean(self, idx: np.ndarray) -> float | None:
        """Mean speed (m/s) over every frame of the agents ``idx`` (None: no speed)."""
        idx = idx[idx < len(self.agent_frames)]
        count = float(self.agent_frames[idx].sum())
        return float(self.agent_sum[idx].sum()) / count if count else None
