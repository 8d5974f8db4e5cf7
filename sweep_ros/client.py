"""Command a running sweep_node without a ROS distribution's CLI (rclpy only, as pip installs it).

    python -m sweep_ros.client pause            # std_srvs/SetBool data: true
    python -m sweep_ros.client resume           # std_srvs/SetBool data: false
    python -m sweep_ros.client step [N]         # N single steps while paused (default 1)
    python -m sweep_ros.client reset
    python -m sweep_ros.client cmd-vel VX VY    # uniform field, m/s
    python -m sweep_ros.client goal X Y         # goal-directed field towards (X, Y), m
    python -m sweep_ros.client goal X Y --group NAME   # the same for the scene's group NAME only
    python -m sweep_ros.client status           # the next diagnostics message

Options: ``--namespace NS`` (the node's namespace, default none), ``--timeout S`` (discovery
and reply, default 10 s). DDS settings come from the environment as for the node
(``ROS_DOMAIN_ID``, ``ROS_AUTOMATIC_DISCOVERY_RANGE``). Exit status: 0 done, 1 the node
refused (its reason is printed), 2 bad arguments or no node found.
"""
from __future__ import annotations

import argparse
import math
import re
import sys
import time
from collections.abc import Callable
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped, Twist
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_srvs.srv import SetBool, Trigger

PROG = "sweep_client"


class ClientError(Exception):
    """A problem the user can fix: printed as one line, exit status 2."""


def _finite(name: str, unit: str) -> Callable[[str], float]:
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(
                f"{name} = {text!r} is not a finite number (fix: give {name} in {unit})")
        return value
    return parse


def _group_name(text: str) -> str:
    if re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", text) is None:
        raise argparse.ArgumentTypeError(
            f"NAME = {text!r} is not a group name (fix: give the name of one of the scene's "
            "agents.groups: a letter, then letters, digits or underscores)")
    return text


def _positive_int(text: str) -> int:
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(
            f"N = {text!r} is not a whole number >= 1 (fix: give the number of steps)")
    return int(text)


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m sweep_ros.client``."""
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n\n")[0])
    ap.add_argument("--namespace", default="", help="namespace of sweep_node (default: none)")
    ap.add_argument("--timeout", type=_finite("--timeout", "seconds"), default=10.0,
                    help="seconds to wait for the node and its reply (default 10)")
    sub = ap.add_subparsers(dest="command", required=True)
    sub.add_parser("pause", help="pause the simulation")
    sub.add_parser("resume", help="resume the simulation")
    step = sub.add_parser("step", help="take N steps while paused")
    step.add_argument("n", nargs="?", type=_positive_int, default=1, metavar="N")
    sub.add_parser("reset", help="back to t = 0, the seed and the scene's drift")
    vel = sub.add_parser("cmd-vel", help="uniform velocity field (m/s) on cmd_vel")
    vel.add_argument("vx", type=_finite("VX", "m/s"), metavar="VX")
    vel.add_argument("vy", type=_finite("VY", "m/s"), metavar="VY")
    goal = sub.add_parser("goal", help="goal-directed field towards (X, Y) on goal")
    goal.add_argument("x", type=_finite("X", "m"), metavar="X")
    goal.add_argument("y", type=_finite("Y", "m"), metavar="Y")
    goal.add_argument("--frame", default="",
                      help="header.frame_id (default empty: the node's frame_id)")
    goal.add_argument("--group", type=_group_name, default=None, metavar="NAME",
                      help="only the scene's group NAME heads there (topic goal/NAME); the "
                           "others keep their drift")
    sub.add_parser("status", help="print the node's next diagnostics message")
    return ap


class Client:
    """A short-lived node that talks to one sweep_node."""

    def __init__(self, namespace: str, timeout: float) -> None:
        self.node = Node("sweep_client", namespace=namespace or None)
        self.timeout = timeout
        self.reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)

    def _spin_until(self, done: Callable[[], Any], what: str) -> Any:
        end = time.monotonic() + self.timeout
        while time.monotonic() < end:
            value = done()
            if value:
                return value
            rclpy.spin_once(self.node, timeout_sec=0.05)
        raise ClientError(f"no answer from {what} within {self.timeout:g} s (fix: start "
                          "sweep_node with the same ROS_DOMAIN_ID, "
                          "ROS_AUTOMATIC_DISCOVERY_RANGE and --namespace, or raise --timeout)")

    def call(self, srv_type: Any, name: str, request: Any) -> Any:
        """Calls a service of the node; returns its response."""
        client: Any = self.node.create_client(srv_type, name)
        full = client.service_name
        self._spin_until(client.service_is_ready, f"service {full}")
        future = client.call_async(request)
        self._spin_until(future.done, f"service {full}")
        return future.result()

    def publish(self, msg_type: Any, name: str, msg: Any,
                group: str | None = None) -> str:
        """Publishes one message once the node subscribes and waits until it is acknowledged;
        returns the topic's full name. With ``group`` (the topic is ``goal/<group>``): a node
        that takes goals for other groups only (seen for 1 s) is reported at once, naming
        them."""
        pub = self.node.create_publisher(msg_type, name, self.reliable)
        since: list[float] = []

        def ready() -> bool:
            if pub.get_subscription_count() > 0:
                return True
            if group is not None and self.group_goal_topics():
                since.append(time.monotonic())
                if since[-1] - since[0] >= 1.0:
                    self._no_group(group)
            return False
        try:
            self._spin_until(ready, f"a subscriber of {pub.topic_name}")
        except ClientError:
            if group is not None and self.group_goal_topics():
                self._no_group(group)
            raise
        pub.publish(msg)
        if not pub.wait_for_all_acked(Duration(seconds=self.timeout)):
            raise ClientError(f"{pub.topic_name}: the message was not acknowledged within "
                              f"{self.timeout:g} s (fix: raise --timeout)")
        return pub.topic_name

    def group_goal_topics(self) -> list[str]:
        """The ``goal/<group>`` topics the node subscribes to, as the graph shows them now."""
        prefix = self.node.resolve_topic_name("goal") + "/"
        return sorted(name for name, _ in self.node.get_topic_names_and_types()
                      if name.startswith(prefix)
                      and self.node.get_subscriptions_info_by_topic(name))

    def _no_group(self, group: str) -> None:
        groups = ", ".join(t.rsplit("/", 1)[1] for t in self.group_goal_topics())
        raise ClientError(f"no group {group!r}: the node takes goals for the groups {groups} "
                          "(fix: --group one of them)")

    def diagnostics(self) -> DiagnosticArray:
        """The next diagnostics message the node publishes (1 Hz)."""
        got: list[DiagnosticArray] = []
        self.node.create_subscription(DiagnosticArray, "diagnostics", got.append,
                                      self.reliable)
        return self._spin_until(lambda: got and got[0], "topic diagnostics")


def run(args: argparse.Namespace, client: Client) -> int:
    """Executes one command; prints what the node said. Returns the exit status."""
    cmd = args.command
    if cmd in ("pause", "resume"):
        res = client.call(SetBool, "pause", SetBool.Request(data=cmd == "pause"))
        print(res.message)
        return 0 if res.success else 1
    if cmd in ("step", "reset"):
        for _ in range(args.n if cmd == "step" else 1):
            res = client.call(Trigger, cmd, Trigger.Request())
            print(res.message)
            if not res.success:
                return 1
        return 0
    if cmd == "cmd-vel":
        twist = Twist()
        twist.linear.x, twist.linear.y = args.vx, args.vy
        topic = client.publish(Twist, "cmd_vel", twist)
        print(f"published ({args.vx:g}, {args.vy:g}) m/s on {topic}: it replaces the drift "
              "from the next step (diagnostics count it as applied, superseded or refused)")
        return 0
    if cmd == "goal":
        point = PointStamped()
        point.header.frame_id = args.frame
        point.point.x, point.point.y = args.x, args.y
        if args.group is None:
            topic = client.publish(PointStamped, "goal", point)
            print(f"published goal ({args.x:g}, {args.y:g}) m on {topic}: it replaces the drift "
                  "from the next step")
            return 0
        topic = client.publish(PointStamped, f"goal/{args.group}", point, args.group)
        print(f"published goal ({args.x:g}, {args.y:g}) m on {topic}: group {args.group} "
              "heads there from the next step, the others keep their drift")
        return 0
    status = client.diagnostics().status[0]
    level = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}.get(status.level[0], "?")
    print(f"{status.name}: {level} {status.message}")
    for kv in status.values:
        print(f"  {kv.key}: {kv.value}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``python -m sweep_ros.client``."""
    args = build_parser().parse_args(argv)
    rclpy.init()
    client: Client | None = None
    try:
        client = Client(args.namespace, args.timeout)
        return run(args, client)
    except ClientError as err:
        print(f"{PROG}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    finally:
        if client is not None:
            client.node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
