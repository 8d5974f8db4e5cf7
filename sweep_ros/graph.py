"""What the node reads from the ROS graph: nodes with its own name, goals for unknown groups.

The graph is the middleware's view of the other participants' nodes and endpoints; it fills in
as discovery proceeds (on this machine typically within 0.1-0.5 s of a participant's start),
so every answer here is "as seen now".
"""
from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from typing import Any

from diagnostic_msgs.msg import KeyValue
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from sweep_ros.errors import StartError

#: how often the node looks for goals published to groups it does not have (s)
GRAPH_PERIOD_S = 0.2
#: at most this many refusing subscriptions for unknown group names (a flood of names must not
#: grow the node without bound)
MAX_UNKNOWN_GROUPS = 32


def same_name_count(node: Any) -> int:
    """How many nodes of the graph have this node's name and namespace (itself included)."""
    me = (node.get_name(), node.get_namespace())
    return sum(1 for entry in node.get_node_names_and_namespaces() if tuple(entry) == me)


def wait_for_same_name(node: Any, deadline: float, poll_s: float = 0.05) -> int:
    """Watches the graph until time.monotonic() reaches ``deadline`` (s) or a second node with
    this node's name and namespace shows up; returns the count (1: none but itself)."""
    while True:
        count = same_name_count(node)
        if count > 1 or time.monotonic() >= deadline:
            return count
        time.sleep(poll_s)


#: how long (s) a node that sees another of its name at start waits for the other's start
#: announcement (:class:`SameName`), which says which of the two started first
ANNOUNCE_WAIT_S = 5.0


def check_unique_name(node: Any, deadline: float, same: SameName) -> None:
    """Raises :class:`StartError` if another node with this node's name and namespace shows up
    in the graph before ``deadline`` (time.monotonic(), s) and started before this one, or
    does not say when it started within :data:`ANNOUNCE_WAIT_S` (``same``: this node's
    announcement and those heard): services, parameters and commands would reach both. A
    node of this name that started after this one is let be: it stops (two started together
    both stopped when each saw the other in the graph)."""
    count = wait_for_same_name(node, deadline)
    if count <= 1:
        return
    end = time.monotonic() + ANNOUNCE_WAIT_S
    while same.problem is None and len(same.seen) < count - 1 and time.monotonic() < end:
        time.sleep(0.05)
        same.poll()
    if same.problem is None and len(same.seen) >= count - 1:
        return  # every other node of this name started after this one, and stops
    raise StartError([same.problem or (
        f"another node named {node.get_fully_qualified_name()} is running on this ROS "
        "domain; services and commands would reach both (fix: stop it, or give this one "
        "another name or namespace: --ros-args -r __node:=NAME or -r __ns:=/NS)")])


#: the topic (relative to the node's name: one per fully qualified name) on which every node
#: says when it started, latched: two nodes of one name hear each other whenever discovery
#: joins them, however long it takes
INSTANCE_TOPIC = "~/instance"


class SameName:
    """The node's start announced on :data:`INSTANCE_TOPIC` (diagnostic_msgs/KeyValue: key a
    token unique to this process, value JSON ``{"started_ns", "pid"}``, reliable and
    transient-local), and the announcements of others of its name heard: the later of two
    (by wall-clock start, then token) calls ``on_later(problem)`` and stops; the earlier logs
    an error naming the later one, which stops."""

    def __init__(self, node: Any, on_later: Callable[[str], None]) -> None:
        self.node, self.on_later = node, on_later
        self.started_ns = time.time_ns()
        self.token = f"{os.getpid()}-{os.urandom(8).hex()}"
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.seen: set[str] = set()
        #: why this node stops: an earlier node of its name heard (None: none)
        self.problem: str | None = None
        self.subscription = node.create_subscription(
            KeyValue, INSTANCE_TOPIC, self.take, QoSProfile(
                depth=16, reliability=ReliabilityPolicy.RELIABLE,
                durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self.publisher = node.create_publisher(KeyValue, INSTANCE_TOPIC, latched)
        self.publisher.publish(KeyValue(key=self.token, value=json.dumps(
            {"started_ns": self.started_ns, "pid": os.getpid()})))

    def poll(self) -> None:
        """Takes the announcements received so far, before the node spins (at its start)."""
        with self.subscription.handle:
            while (got := self.subscription.handle.take_message(KeyValue, False)) is not None:
                self.take(got[0])

    def take(self, msg: KeyValue) -> None:
        """An announcement: ours, one already judged, or another node of this name."""
        if msg.key == self.token or msg.key in self.seen:
            return
        try:
            other = int(json.loads(msg.value)["started_ns"])
        except (ValueError, KeyError, TypeError, RecursionError):
            return  # not a node's announcement
        self.seen.add(msg.key)
        name = self.node.get_fully_qualified_name()
        if (other, msg.key) < (self.started_ns, self.token):
            ago = (self.started_ns - other) / 1e9
            self.problem = (f"another node named {name} is running on this ROS domain "
                            f"(started {ago:.3g} s before this one); services and commands "
                            "would reach both (fix: stop it, or give this one another name or "
                            "namespace: --ros-args -r __node:=NAME or -r __ns:=/NS)")
            self.on_later(self.problem)
        else:
            self.node.get_logger().error(
                f"another node named {name} started on this ROS domain "
                f"{(other - self.started_ns) / 1e9:.3g} s after this one; it stops")


def foreign_goal_topics(node: Any, goal_topic: str, groups: tuple[str, ...]) -> list[str]:
    """Topics ``<goal_topic>/<name>`` that some publisher (not this node) offers as
    geometry_msgs/PointStamped where ``name`` is not one of the scene's ``groups``."""
    prefix = goal_topic.rstrip("/") + "/"
    known = {prefix + name for name in groups}
    out = []
    for name, types in node.get_topic_names_and_types():
        if (name.startswith(prefix) and name not in known and "/" not in name[len(prefix):]
                and "geometry_msgs/msg/PointStamped" in types and node.count_publishers(name)):
            out.append(name)
    return sorted(out)


def unknown_group_problem(name: str, goal_topic: str, groups: tuple[str, ...]) -> str:
    """Why a goal on ``<goal_topic>/<name>`` is refused: ``name`` is no group of the scene."""
    if groups:
        return (f"no group {name!r} in the scene (its groups: {', '.join(groups)}) (fix: "
                f"publish on {goal_topic}/<group> for one of them, or on {goal_topic} for every "
                "agent)")
    return (f"no group {name!r}: the scene has no agents.groups (fix: publish on {goal_topic} "
            "for every agent)")


class UnknownGroups:
    """Subscriptions to the ``<goal_topic>/<name>`` topics someone publishes for a name that is
    no group of the scene (found by :meth:`watch`, called on a timer), so that their goals get
    a verdict; ``on_message(subscription, raw, info)`` takes each message."""

    def __init__(self, node: Any, goal_topic: str, groups: tuple[str, ...], qos: Any,
                 on_message: Callable[[Any, bytes, Any], None]) -> None:
        self.node, self.goal_topic, self.groups = node, goal_topic, groups
        self.qos, self.on_message = qos, on_message
        self.subscriptions: dict[str, Any] = {}

    def watch(self) -> None:
        """Subscribes to the new ones (at most :data:`MAX_UNKNOWN_GROUPS` in all)."""
        from geometry_msgs.msg import PointStamped

        for topic in foreign_goal_topics(self.node, self.goal_topic, self.groups):
            if (topic in self.subscriptions
                    or len(self.subscriptions) >= MAX_UNKNOWN_GROUPS):
                continue
            box: list[Any] = []
            box.append(self.node.create_subscription(
                PointStamped, topic, lambda raw, info, b=box: self.on_message(b[0], raw, info),
                self.qos, raw=True))
            self.subscriptions[topic] = box[0]


__all__ = ["ANNOUNCE_WAIT_S", "GRAPH_PERIOD_S", "MAX_UNKNOWN_GROUPS", "SameName", "UnknownGroups",
           "check_unique_name", "foreign_goal_topics", "same_name_count", "unknown_group_problem",
           "wait_for_same_name"]
