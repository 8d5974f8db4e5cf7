"""The node's diagnostics (:class:`DiagnosticsMixin` of :class:`sweep_ros.node.SweepNode`, once
a second on the latched ``diagnostics`` topic, and at once after pause, step and reset; the same
status answered now by the ``status`` service) and the DiagnosticArray they are sent as
(:func:`diagnostics`).
"""
from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.serialization import serialize_message

from sweep_core.io import topics
from sweep_core.numerics import kernels
from sweep_ros import graph
from sweep_ros.messages import time_msg
from sweep_ros.timing import Window

LEVELS = {"OK": DiagnosticStatus.OK, "WARN": DiagnosticStatus.WARN,
          "ERROR": DiagnosticStatus.ERROR, "STALE": DiagnosticStatus.STALE}


def _show(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def diagnostics(stamp_ns: int, name: str, hardware_id: str, level: str, message: str,
                values: Mapping[str, Any]) -> DiagnosticArray:
    """A DiagnosticArray with one status; ``level`` is OK, WARN, ERROR or STALE."""
    status = DiagnosticStatus(level=LEVELS[level], name=name, message=message,
                              hardware_id=hardware_id,
                              values=[KeyValue(key=k, value=_show(v)) for k, v in values.items()])
    arr = DiagnosticArray(status=[status])
    arr.header.stamp = time_msg(stamp_ns)
    return arr


class DiagnosticsMixin:
    """Diagnostics of :class:`~sweep_ros.node.SweepNode` (its attributes are the node's)."""

    _p: dict[str, Any]

    def _on_diag_timer(self) -> None:
        with self._gate.control():
            if not self._closed:
                self._publish_diagnostics()

    def _status_now(self) -> tuple[str, str, dict[str, Any]]:
        """The node's level, message and values now (the caller holds the gate); nothing is
        published or reset."""
        w, now = self._window, time.monotonic()
        wall = max(now - w.wall0, 1e-9)
        sim, rec = self.sim, self.recorder
        counters = self._inbox.counters()
        lost = counters["commands_lost"]
        new_lost = lost - self._lost_reported if isinstance(lost, int) else 0
        same_name = graph.same_name_count(self)
        robot_stops = self._robot_stops(wall)
        if self.failure:
            level, message = "ERROR", f"infeasible, paused: {self.failure}"
        elif same_name > 1:
            level, message = "WARN", (f"{same_name} nodes named "
                                      f"{self.get_fully_qualified_name()} on this ROS domain: "
                                      "services and commands reach all of them")
        elif rec is not None and rec.error:
            level, message = "WARN", f"recording stopped: {rec.error}"
        elif self._map_problem:
            level, message = "WARN", self._map_problem
        elif robot_stops:
            level, message = "WARN", robot_stops
        elif w.overruns:
            level, message = "WARN", f"{w.overruns} timer overruns in the last {wall:.1f} s"
        elif new_lost > 0:
            level, message = "WARN", (f"{new_lost} commands never reached the node in the last "
                                      f"{wall:.1f} s (subscription queue full; latest wins)")
        else:
            level, message = "OK", "paused" if self.paused else "running"
        values = {
            "sim_time_s": sim.t, "steps": sim.n_steps, "agents": len(sim.positions),
            "paused": self.paused,
            "step_time_ms": 1e3 * w.step_s / w.steps if w.steps else 0.0,
            "steps_per_s": w.steps / wall,
            "tick_rate_hz": w.ticks / wall,
            "tick_time_ms": 1e3 * w.tick_s / w.ticks if w.ticks else 0.0,
            "real_time_factor": (sim.t - w.sim0) / wall,
            "timer_overruns": self._overruns,
            "active_contacts": sim.contacts,
            "backend_agents": sim.backend_agents,
            "projection_bound_m": sim.bound,
            "min_gap_m": sim.min_gap,
            "drift": sim.drift.kind,
            "compile_s": self.warm_up.seconds,
            "kernels_compiled_late": kernels.compiled_count() - self._compiled_at_start,
            **counters,
            **self._robot_diagnostics(),
            "command_results": self._results.published,
            "resets": self._resets,
            "maps_applied": self._maps_applied,
            "map_refused": self._maps_refused,
            "recording": rec.path if rec is not None else "off",
            "recording_backlog": rec.backlog if rec is not None else 0,
            "recorded_messages": rec.written if rec is not None else 0,
        }
        return level, message, values

    def _status_text(self) -> str:
        """What the ``status`` service answers: the diagnostics' status line and values, now
        (the caller holds the gate)."""
        level, message, values = self._status_now()
        lines = [f"{self.get_name()}: simulation: {level} {message}"]
        lines += [f"  {k}: {_show(v)}" for k, v in values.items()]
        return "\n".join(lines)

    def _publish_diagnostics(self) -> None:
        """Publishes (and records) one diagnostics message; the caller holds the gate."""
        level, message, values = self._status_now()
        lost = values["commands_lost"]
        if isinstance(lost, int):
            self._lost_reported = lost
        msg = diagnostics(topics.stamp_ns(self.sim.t), f"{self.get_name()}: simulation",
                          self.scene.name, level, message, values)
        self._publish(self.pub_diag, bytes(serialize_message(msg)), self._log_ns(self.sim.t))
        self._window = Window(self.sim.t)
        self._map_problem = None
