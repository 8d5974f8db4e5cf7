"""What the node reads from the ROS graph: nodes with its own name, goals for unknown groups.

The graph is the middleware's view of the other participants' nodes and endpoints; it fills in
as discovery proceeds (on this machine typically within 0.1-0.5 s of a participant's start),
so every answer here is "as seen now".
"""
from __future__ import annotations

import time
from typing import Any

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


__all__ = ["GRAPH_PERIOD_S", "MAX_UNKNOWN_GROUPS", "foreign_goal_topics", "same_name_count",
           "wait_for_same_name"]
