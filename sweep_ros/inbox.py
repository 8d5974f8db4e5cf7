"""The node's velocity-field commands between arrival and use (:class:`CommandInbox`).

Semantics, chosen on purpose: a command replaces the whole drift field, so only the newest
one matters. A valid command waits until the next step starts; a newer command arriving before
then replaces it (the older one is *superseded*), and so does a reset. A group's command
(``group`` k: a goal for the scene's group k only) replaces only that group's drift, so it
supersedes only an older command for the same group: commands for other groups, and a whole
command before them, wait with it and are applied in their order of arrival at that step.
Every message taken from the subscription queues is counted once:

    received = applied + superseded + refused + pending

Where the middleware reports publication sequence numbers (Fast DDS does), the highest one seen
per publisher is that publisher's count of messages sent, so ``published - received`` counts
the messages that never reached the node's callback (dropped from a full subscription queue,
or sent before the node subscribed). geometry_msgs/Twist has no header or sequence field of
its own; these numbers come from the DDS sample info, not from the message.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Any

from sweep_core.model.fields import Field


@dataclass(frozen=True)
class Command:
    """A valid command waiting for a step: ``field`` replaces the drift (or, with ``group``
    k, the drift of the scene's group k); ``raw`` is the CDR message as received (recorded
    when applied); ``arrival`` is time.monotonic() (s); ``built_for``: the scene a navigation
    field was computed for (None when the field does not depend on the walls); ``ident``: what
    names the message in its verdict (:class:`sweep_ros.results.CommandId`)."""

    topic: str
    field: Field
    raw: bytes
    arrival: float
    group: int | None = None
    built_for: Any = None
    ident: Any = None


@dataclass(frozen=True)
class Applied:
    """A command as a step takes it: ``latency_s`` from its arrival to the start of the
    first step that uses it (s); ``superseded`` commands were replaced since the last one
    applied (by it or by each other)."""

    command: Command
    latency_s: float
    superseded: int


class CommandInbox:
    """Latest-wins slot for commands, with the counters the node reports (thread-safe)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._pending: list[Command] = []
        self._superseded_since_applied = 0
        self.received = 0
        self.applied = 0
        self.superseded = 0
        self.refused = 0
        self.latency_last_s: float | None = None
        self.latency_max_s = 0.0
        #: highest publication sequence number seen per (topic, publisher gid)
        self._sequence: dict[tuple[str, bytes], int] = {}
        self._sequence_known = True

    # -- the subscription side ---------------------------------------------------------------
    def arrived(self, topic: str, info: Any | None) -> None:
        """Counts one message taken from a subscription queue; ``info`` is rclpy's
        MessageInfo (a dict) or None."""
        seq = info.get("publication_sequence_number") if info else None
        gid = info.get("publisher_gid") if info else None
        with self._lock:
            self.received += 1
            if seq is None or not gid:
                self._sequence_known = False
                return
            key = (topic, bytes(gid.get("data", b"")))
            self._sequence[key] = max(self._sequence.get(key, 0), int(seq))

    def refuse(self) -> None:
        """The message counted by the last :meth:`arrived` was refused."""
        with self._lock:
            self.refused += 1

    def offer(self, topic: str, field: Field, raw: bytes, arrival: float,
              group: int | None = None, built_for: Any = None, ident: Any = None
              ) -> list[Command]:
        """A valid command: it replaces any command still waiting for a step (with ``group``:
        any for the same group). Returns the commands it superseded."""
        cmd = Command(topic, field, raw, arrival, group, built_for, ident)
        with self._lock:
            keep = [c for c in self._pending if group is not None and c.group != group]
            dropped = [c for c in self._pending if group is None or c.group == group]
            self.superseded += len(dropped)
            self._superseded_since_applied += len(dropped)
            self._pending = keep + [cmd]
        return dropped

    # -- the stepping side -------------------------------------------------------------------
    def take(self) -> Applied | None:
        """The oldest waiting command, now applied by the step about to start, or None (call
        it until None: the commands for different groups wait together)."""
        now = time.monotonic()
        with self._lock:
            if not self._pending:
                return None
            cmd = self._pending.pop(0)
            self.applied += 1
            latency = max(now - cmd.arrival, 0.0)
            self.latency_last_s = latency
            self.latency_max_s = max(self.latency_max_s, latency)
            superseded, self._superseded_since_applied = self._superseded_since_applied, 0
        return Applied(cmd, latency, superseded)

    def discard(self) -> int:
        """Drops the waiting commands (a reset replaces them); returns how many were dropped."""
        return len(self.discard_all())

    def discard_all(self) -> list[Command]:
        """Drops the waiting commands (a reset replaces them); returns them."""
        with self._lock:
            dropped, self._pending = self._pending, []
            self.superseded += len(dropped)
            self._superseded_since_applied = 0
            return dropped

    def refuse_taken(self) -> None:
        """The command the last :meth:`take` returned was refused after all (its field could
        not be built again for walls changed since it arrived): counted refused, not
        applied."""
        with self._lock:
            self.applied -= 1
            self.refused += 1

    # -- reporting ---------------------------------------------------------------------------
    def counters(self) -> dict[str, Any]:
        """The counters for diagnostics and the recording's metadata: counts, latencies in
        ms; ``commands_published`` and ``commands_lost`` are "unknown" where the middleware
        gave no publication sequence numbers."""
        with self._lock:
            pending = len(self._pending)
            published: Any = sum(self._sequence.values()) if self._sequence_known else "unknown"
            lost: Any = (max(published - self.received, 0) if self._sequence_known
                         else "unknown")
            return {
                "commands_received": self.received,
                "commands_applied": self.applied,
                "commands_superseded": self.superseded,
                "commands_refused": self.refused,
                "commands_pending": pending,
                "commands_published": published,
                "commands_lost": lost,
                "command_latency_last_ms": (1e3 * self.latency_last_s
                                            if self.latency_last_s is not None else 0.0),
                "command_latency_max_ms": 1e3 * self.latency_max_s,
            }
