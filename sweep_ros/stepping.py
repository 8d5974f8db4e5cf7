"""The node's step thread (:class:`SteppingMixin` of :class:`sweep_ros.node.SweepNode`): ticks
every 1 / rate_hz s, each taking its steps one at a time under the gate (real-time factor,
overruns), the newest waiting commands applied at the start of a step, an infeasible step
pausing the node.
"""
from __future__ import annotations

import math
import time
import traceback
from typing import Any

from sweep_core import InfeasibleError, SceneError


class SteppingMixin:
    """Stepping of :class:`~sweep_ros.node.SweepNode` (its attributes are the node's)."""

    _p: dict[str, Any]

    def _steps_this_tick(self, now: float) -> int:
        rtf = self._p["real_time_factor"]
        if rtf <= 0:
            return self._p["steps_per_tick"]
        if self._rt_anchor is None:
            self._rt_anchor = (now, self.sim.t)
        wall0, sim0 = self._rt_anchor
        behind = sim0 + rtf * (now - wall0) - self.sim.t
        steps = int(math.floor(behind / self.sim.dt + 1e-9))
        cap = self._p["max_steps_per_tick"]
        if steps > cap:
            self._window.overruns += 1
            self._overruns += 1
            if behind > rtf * 1.0 + cap * self.sim.dt:  # more than 1 s behind: give it up
                self._rt_anchor = (now, self.sim.t + cap * self.sim.dt)
            steps = cap
        return max(steps, 0)

    def _advance(self) -> bool:
        """Take one step, after applying the newest waiting command; on an infeasible step
        pause and report (the state stays at the last accepted step, which is published).
        The caller holds the gate. Returns whether the step was taken."""
        while (applied := self._inbox.take()) is not None:
            self._apply_command(applied)
        start = time.perf_counter()
        try:
            self._command_robots()
            self.sim.step(1)
            self.failure = None
        except (InfeasibleError, SceneError) as err:
            self.failure = str(err)
            self.paused = True
            self._rt_anchor = None
            self.get_logger().error(f"step {self.sim.n_steps + 1} failed, simulation paused: "
                                    f"{err}")
            self._publish_diagnostics()
            return False
        self._record_robot_step()
        self._window.steps += 1
        self._window.step_s += time.perf_counter() - start
        return True

    def _step_loop(self) -> None:
        """The step timer: a tick every 1 / rate_hz s (read at every tick) until the node
        stops; after a tick that overran its period the next starts at once (_tick counts
        the periods missed). An exception ends the loop and is kept in ``crash``."""
        next_start = time.monotonic()
        try:
            while not self._stopping.is_set():
                self._tick()
                next_start += 1.0 / self._p["rate_hz"]
                now = time.monotonic()
                if next_start <= now:
                    next_start = now
                elif self._wake.wait(next_start - now):
                    self._wake.clear()
                    next_start = time.monotonic()
        except Exception as err:  # noqa: BLE001 - reported by main, which stops the node
            self.crash = f"{type(err).__name__}: {err}"
            self.get_logger().error(f"step thread stopped: {traceback.format_exc()}")

    def _tick(self) -> None:
        """One timer tick: its steps one at a time (the gate held for one step each), the
        state published with the last of them. A pause, reset or stop between two steps ends
        the tick there."""
        start = time.monotonic()
        with self._gate.step():
            period = 1.0 / self._p["rate_hz"]
            if self._last_tick_start is not None:
                missed = int((start - self._last_tick_start) / period + 0.5) - 1
                if missed > 0:
                    self._overruns += missed
                    self._window.overruns += missed
            self._last_tick_start = start
            if self.paused or self._closed:
                return
            n = self._steps_this_tick(start)
            segment = self._resets
        taken = 0
        for _ in range(n):
            with self._gate.step():
                going = not (self.paused or self._stopping.is_set() or self._closed
                             or self._resets != segment) and self._advance()
                taken += going
                if not going or taken == n:
                    # published while the gate is still held (and by a placement between two
                    # steps of the tick, before it moves the robot): a recorded state is the
                    # one its step made
                    if taken and self._resets == segment and not self._closed:
                        self._publish_pending()
                    break
        with self._gate.step():
            self._window.ticks += 1
            self._window.tick_s += time.monotonic() - start
