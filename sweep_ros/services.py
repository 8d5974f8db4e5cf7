"""The node's services and live parameters (:class:`ServicesMixin` of
:class:`sweep_ros.node.SweepNode`): reset, pause and step, each between two steps; parameter
changes checked and applied (the model's recorded for replay).
"""
from __future__ import annotations

import json
from typing import Any

from rclpy.serialization import serialize_message
from std_srvs.srv import SetBool, Trigger

from sweep_ros import markers, params


class ServicesMixin:
    """Services and parameters of :class:`~sweep_ros.node.SweepNode` (its attributes are the
    node's)."""

    _p: dict[str, Any]

    # -- services (each between two steps: see sweep_ros.node) ----------------------------------
    def _on_reset(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        with self._gate.control():
            before = (self.sim.n_steps, self.sim.t)
            self._epoch_ns = self._last_log_ns + self._dt_ns
            for old in self._inbox.discard_all():  # not yet applied: superseded by the reset
                self._verdict("superseded", old.topic, old.ident,
                              "superseded by a reset before a step used it")
            self.sim.reset()
            self._forget_robot_commands()
            self._apply_sigma()
            self.failure = None
            self._rt_anchor = None
            self._resets += 1
            if self.recorder is not None:
                self.recorder.metadata(f"reset_{self._resets:06d}", {
                    "log_time_ns": str(self._epoch_ns), "previous_step": str(before[0]),
                    "previous_t": repr(before[1]), "seed": str(self.sim.seed)})
            if self._p["publish_markers"]:
                clear = markers.delete_all(self.frame_id, 0)
                self._publish(self.pub_markers, bytes(serialize_message(clear)),
                              self._log_ns(0.0))
            self._publish_walls()
            self._publish_state(force_markers=True)
            self._publish_diagnostics()
            response.success = True
            response.message = (f"reset to t = 0 with seed {self.sim.seed} (was step "
                                f"{before[0]}, t = {before[1]:g} s); drift back to the scene's "
                                f"{self.sim.drift.kind}")
        return response

    def _on_pause(self, request: SetBool.Request, response: SetBool.Response
                  ) -> SetBool.Response:
        self.paused = bool(request.data)  # seen by the tick at its next step boundary
        with self._gate.control():
            self.paused = bool(request.data)
            self._rt_anchor = None
            self._publish_diagnostics()
            response.success = True
            response.message = (f"{'paused' if self.paused else 'running'} at step "
                                f"{self.sim.n_steps}, t = {self.sim.t:g} s")
        return response

    def _on_step(self, request: Trigger.Request, response: Trigger.Response
                 ) -> Trigger.Response:
        with self._gate.control():
            if not self.paused:
                response.success = False
                response.message = ("not paused (fix: pause first: sweep_client pause, or the "
                                    "pause service with data: true)")
            elif self._advance():
                self._publish_state(force_markers=True)
                self._publish_diagnostics()
                response.success = True
                response.message = f"step {self.sim.n_steps}, t = {self.sim.t:g} s"
            else:
                response.success = False
                response.message = f"step failed: {self.failure}"
        return response

    def _on_status(self, request: Trigger.Request, response: Trigger.Response
                   ) -> Trigger.Response:
        """The node's status now, between two steps (the latched diagnostics message can be up
        to a second old)."""
        with self._gate.control():
            response.success = not self._closed
            response.message = self._status_text() if not self._closed else "closing"
        return response

    # -- parameters ------------------------------------------------------------------------------
    def _check_parameters(self, changes: list) -> Any:
        return params.check_live([(p.name, p.value) for p in changes], self._p)

    def _apply_parameters(self, changes: list) -> None:
        with self._gate.control():
            for p in changes:
                if p.name in params.BY_NAME:
                    self._apply_parameter(p.name, p.value)

    def _apply_parameter(self, name: str, value: Any) -> None:
        old = self._p.get(name)
        self._p[name] = value
        if value == old:
            return
        if name == "rate_hz":
            self._last_tick_start = None
            self._wake.set()  # the step thread starts the next tick now, at the new period
        elif name == "noise_sigma":
            self._apply_sigma()
            if self.recorder is not None:  # replay needs every live change of the model
                self._parameter_changes += 1
                self.recorder.metadata(f"parameter_{self._parameter_changes:06d}", {
                    "name": name, "value": json.dumps(value),
                    "step": str(self.sim.n_steps),
                    "log_time_ns": str(self._log_ns(self.sim.t))})
        elif name == "marker_height":
            self._publish_walls()
        elif name in ("real_time_factor", "max_steps_per_tick"):
            self._rt_anchor = None
        self.get_logger().info(f"parameter {name} = {value!r}")

    def _apply_sigma(self) -> None:
        sigma = self._p["noise_sigma"]
        self.sim.set_sigma(self.scene.sigma if sigma == -1.0 else sigma)
