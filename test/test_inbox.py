"""The node's command inbox (latest wins, every message counted once) and its step gate
(a control callback goes first at the next step boundary; a tick's state is published before
one goes in), without ROS."""
from __future__ import annotations

import threading
import time
import types

import numpy as np

from sweep_core.model.fields import Uniform
from sweep_ros.gate import StepGate
from sweep_ros.inbox import CommandInbox
from sweep_ros.publishing import PublishingMixin
from sweep_ros.stepping import SteppingMixin


def _field(vx: float) -> Uniform:
    return Uniform(np.array([vx, 0.0]))


def _info(seq: int | None, gid: bytes = b"A") -> dict:
    return {"publication_sequence_number": seq, "publisher_gid": {"data": gid}}


def _balanced(c: dict) -> bool:
    return c["commands_received"] == (c["commands_applied"] + c["commands_superseded"]
                                      + c["commands_refused"] + c["commands_pending"])


def test_latest_wins_and_every_message_counted_once():
    inbox = CommandInbox()
    t0 = time.monotonic()
    for k in range(1, 6):  # 5 valid, then one refused
        inbox.arrived("/cmd_vel", _info(k))
        inbox.offer("/cmd_vel", _field(k), b"raw%d" % k, t0)
    inbox.arrived("/cmd_vel", _info(6))
    inbox.refuse()
    applied = inbox.take()
    assert applied is not None and applied.command.field.velocity[0] == 5.0
    assert applied.command.raw == b"raw5" and applied.superseded == 4
    assert applied.latency_s >= 0.0 and inbox.take() is None
    c = inbox.counters()
    assert (c["commands_received"], c["commands_applied"], c["commands_superseded"],
            c["commands_refused"], c["commands_pending"]) == (6, 1, 4, 1, 0)
    assert _balanced(c)
    assert c["command_latency_max_ms"] >= c["command_latency_last_ms"] >= 0.0


def test_reset_supersedes_a_waiting_command():
    inbox = CommandInbox()
    inbox.arrived("/goal", None)
    inbox.offer("/goal", _field(1.0), b"", time.monotonic())
    assert inbox.counters()["commands_pending"] == 1 and _balanced(inbox.counters())
    assert inbox.discard() == 1 and inbox.discard() == 0
    assert inbox.take() is None
    c = inbox.counters()
    assert c["commands_superseded"] == 1 and c["commands_pending"] == 0 and _balanced(c)


def test_publisher_counts_from_sequence_numbers():
    """Two publishers; the highest sequence number seen is each one's count, so messages
    that never reached the callback (gaps, a lost tail is invisible) are counted as lost."""
    inbox = CommandInbox()
    for seq in (1, 2, 5, 9):          # publisher A: 9 sent, 4 received
        inbox.arrived("/cmd_vel", _info(seq, b"A"))
    for seq in (3, 4):                # publisher B: 4 sent, 2 received
        inbox.arrived("/cmd_vel", _info(seq, b"B"))
    c = inbox.counters()
    assert c["commands_published"] == 13 and c["commands_lost"] == 7
    inbox.arrived("/goal", None)       # a middleware without sequence numbers
    c = inbox.counters()
    assert c["commands_published"] == "unknown" and c["commands_lost"] == "unknown"


def test_control_goes_first_at_the_next_step_boundary():
    """The step thread leaves a step and at once asks for the next one while a control
    callback waits: the control callback always goes first (a plain lock leaves that order
    to the scheduler)."""
    for _ in range(20):
        gate = StepGate()
        order: list[str] = []
        in_step = threading.Event()

        def stepper():
            with gate.step():
                in_step.set()
                while gate.waiting == 0:  # the control callback is now blocked on the gate
                    time.sleep(0.0005)
                order.append("step 1")
            with gate.step():
                order.append("step 2")

        def control():
            with gate.control():
                order.append("control")

        threads = [threading.Thread(target=stepper), threading.Thread(target=control)]
        threads[0].start()
        in_step.wait()
        threads[1].start()
        for t in threads:
            t.join(timeout=10)
        assert order == ["step 1", "control", "step 2"]


def test_group_commands_wait_together_and_supersede_their_own_group():
    """A group's command supersedes only an older one for the same group; a whole command
    supersedes everything before it; the waiting ones come out in order of arrival."""
    inbox = CommandInbox()
    t0 = time.monotonic()
    sent = [("/goal", None, 1.0), ("/goal/a", 0, 2.0), ("/goal/b", 1, 3.0),
            ("/goal/a", 0, 4.0)]
    for k, (topic, group, vx) in enumerate(sent, 1):
        inbox.arrived(topic, _info(k, topic.encode()))
        inbox.offer(topic, _field(vx), b"", t0, group)
    c = inbox.counters()
    assert c["commands_pending"] == 3 and c["commands_superseded"] == 1 and _balanced(c)
    got = []
    while (applied := inbox.take()) is not None:
        got.append((applied.command.topic, applied.command.group,
                    applied.command.field.velocity[0]))
    assert got == [("/goal", None, 1.0), ("/goal/b", 1, 3.0), ("/goal/a", 0, 4.0)]
    # a whole command supersedes every group's command waiting before it
    for topic, group in (("/goal/a", 0), ("/goal/b", 1), ("/cmd_vel", None)):
        inbox.arrived(topic, None)
        inbox.offer(topic, _field(0.0), b"", t0, group)
    assert inbox.counters()["commands_pending"] == 1
    assert inbox.take().command.topic == "/cmd_vel"
    # refused after it was taken (its walls changed): counted refused, not applied
    inbox.arrived("/goal", None)
    inbox.offer("/goal", _field(0.0), b"", t0)
    inbox.take()
    inbox.refuse_taken()
    c = inbox.counters()
    assert c["commands_applied"] == 4 and c["commands_refused"] == 1
    assert c["commands_superseded"] == 3 and _balanced(c)


class _Ticker(SteppingMixin, PublishingMixin):
    """The step thread's tick over a stand-in engine: each step and each publication logs
    what it saw; a control callback (a placement, which publishes a pending state first as
    the node's does) waits for the gate during the step it is placed after."""

    def __init__(self, steps: int, pause_after: int | None = None) -> None:
        self._gate, self._p = StepGate(), {"rate_hz": 50.0, "real_time_factor": 0.0,
                                           "steps_per_tick": steps}
        self._last_tick_start, self._overruns = None, 0
        self._window = types.SimpleNamespace(overruns=0, ticks=0, tick_s=0.0)
        self.paused, self._closed, self._resets = False, False, 0
        self._stopping = threading.Event()
        self.log: list[str] = []
        self.n, self.placed, self.pause_after = 0, False, pause_after
        self.control: threading.Thread | None = None
        self._published: tuple[int, int] | None = None

    @property
    def sim(self) -> types.SimpleNamespace:
        return types.SimpleNamespace(n_steps=self.n)

    def _advance(self) -> bool:
        self.n += 1
        self.log.append(f"step {self.n}")
        if self.n == self.pause_after:
            self.paused = True  # as a pause service between two steps would
        if self.n == self._p["steps_per_tick"] or self.n == self.pause_after:
            self.control = threading.Thread(target=self._place)
            self.control.start()
            while self._gate.waiting == 0:  # the placement now waits for the gate
                time.sleep(0.0005)
        return True

    def _place(self) -> None:
        with self._gate.control():
            self._publish_pending()
            self.placed = True
            self.log.append("placed")

    def _publish_state(self, force_markers: bool = False) -> None:
        self._published = (self._resets, self.n)
        self.log.append(f"published step {self.n}" + (" after the placement"
                                                       if self.placed else ""))


def test_a_tick_publishes_its_state_before_a_waiting_command_goes_in():
    """The state a tick ends with is published before a command waiting for the gate (a
    robot placement, a map) is applied, so a recorded state is always the one its step made
    (the placement is recorded as made after that step, and replay applies it there)."""
    for steps, pause_after in ((3, None), (1, None), (4, 2)):
        t = _Ticker(steps, pause_after)
        t._tick()
        t.control.join(timeout=10)
        last = pause_after or steps
        assert t.log[-2:] == [f"published step {last}", "placed"], t.log
        assert t.log.count(f"published step {last}") == 1 and t.n == last
