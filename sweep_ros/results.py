"""Verdicts on commands: the node's acknowledgement of every command message it takes.

Each message taken from a command subscription (``crowd/cmd_vel``, ``goal``, ``goal/<name>``,
``velocity_field``) gets a verdict on the latched ``command_result`` topic (reliable,
transient-local, depth :data:`DEPTH`; diagnostic_msgs/DiagnosticArray with one status), which
is recorded like every published message:

- ``refused``: the node's reason (status ERROR; the message is the reason);
- ``applied``: it is the drift from step ``step`` on (status OK);
- ``superseded``: a newer command for the same drift, or a reset, replaced it before a step used
  it (status WARN);
- ``accepted``: valid and waiting for the next step while the node is paused (status OK; the
  final verdict follows when a step takes it, or a newer command or a reset supersedes it).

A running node gives ``refused`` at once and ``applied`` or ``superseded`` within one tick. The
command is named by ``command``, ``<publisher gid>:<publication sequence number>`` (both from
the DDS sample info), and, for messages with a header, by ``stamp_ns``, the header stamp as it
came (a client may put a nonce there). ``sweep_client`` matches its own command by its
publisher's gid. This module imports only rclpy and diagnostic_msgs (the client imports it).
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message

TOPIC = "command_result"
#: verdicts kept for late subscribers (transient-local history)
DEPTH = 20
QOS = QoSProfile(depth=DEPTH, reliability=ReliabilityPolicy.RELIABLE,
                 durability=DurabilityPolicy.TRANSIENT_LOCAL)
LEVEL = {"applied": DiagnosticStatus.OK, "accepted": DiagnosticStatus.OK,
         "superseded": DiagnosticStatus.WARN, "refused": DiagnosticStatus.ERROR}
#: verdicts after which nothing more is said about a command
FINAL = frozenset({"applied", "superseded", "refused"})


@dataclass(frozen=True)
class CommandId:
    """What names one command message: its publisher's DDS gid (hex, "" when the middleware
    gives none), its publication sequence number (0 when unknown), and its header stamp (ns;
    None for messages without a header)."""

    gid: str = ""
    sequence: int = 0
    stamp_ns: int | None = None

    @property
    def text(self) -> str:
        """``<gid>:<sequence>``, or ``unknown``."""
        return f"{self.gid}:{self.sequence}" if self.gid else "unknown"


def command_id(info: Any | None, msg: Any | None = None) -> CommandId:
    """The id of a command from rclpy's MessageInfo (a dict, or None) and the deserialised
    message (None when it could not be decoded)."""
    gid_info = info.get("publisher_gid") if info else None
    gid = bytes(gid_info.get("data", b"")).hex() if gid_info else ""
    seq = info.get("publication_sequence_number") if info else None
    header = getattr(msg, "header", None)
    stamp = (int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)
             if header is not None else None)
    return CommandId(gid, int(seq) if seq else 0, stamp)


def gid_hex(endpoint_gid: Any) -> str:
    """A graph endpoint's gid (TopicEndpointInfo.endpoint_gid, a list of ints) as the hex of
    :class:`CommandId`."""
    return bytes(endpoint_gid).hex()


class CommandResults:
    """Publishes (and records, through ``record(topic, log_ns, data)``) one verdict per
    command. Thread-safe: verdicts come from the executor's thread (refused, superseded,
    accepted) and from the step thread (applied)."""

    def __init__(self, publisher: Any, node_name: str, record: Any) -> None:
        self.publisher = publisher
        self.node_name = node_name
        self._record = record
        self._lock = threading.Lock()
        self.published = 0

    @property
    def topic(self) -> str:
        return str(self.publisher.topic_name)

    def verdict(self, verdict: str, topic: str, ident: CommandId, text: str, step: int,
                t: float, stamp_ns: int, log_ns: int, **extra: Any) -> None:
        """Publishes one verdict: ``step`` is the step it applies from (applied) or the last
        step taken (the others); ``t`` that step's simulated time (s), ``stamp_ns`` the same
        as the header stamp (ns); ``text`` the message (the node's reason for refused);
        ``log_ns`` the record's log time."""
        values: dict[str, Any] = {
            "verdict": verdict, "command": ident.text, "topic": topic, "step": step,
            "t_s": f"{t:.9g}", "publisher_gid": ident.gid, "sequence": ident.sequence,
            "stamp_ns": "" if ident.stamp_ns is None else ident.stamp_ns,
            **extra, "wall_time_s": f"{time.time():.6f}"}
        status = DiagnosticStatus(
            level=LEVEL[verdict], name=self.node_name, message=text, hardware_id=topic,
            values=[KeyValue(key=k, value=str(v).lower() if isinstance(v, bool) else str(v))
                    for k, v in values.items()])
        msg = DiagnosticArray(status=[status])
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
        data = bytes(serialize_message(msg))
        with self._lock:
            self.publisher.publish(data)
            self._record(self.topic, log_ns, data)
            self.published += 1


def parse(msg: DiagnosticArray) -> dict[str, str] | None:
    """A verdict as a mapping (``node``, ``message`` and the values), or None for anything
    else."""
    if len(msg.status) != 1:
        return None
    status = msg.status[0]
    out = {kv.key: kv.value for kv in status.values}
    if "verdict" not in out:
        return None
    out["node"] = status.name
    out["message"] = status.message
    return out


__all__ = ["CommandId", "CommandResults", "DEPTH", "FINAL", "QOS", "TOPIC", "command_id",
           "gid_hex", "parse"]
