"""Command a running sweep_node without a ROS distribution's CLI (rclpy only, as pip installs it).

    python -m sweep_ros.client pause            # std_srvs/SetBool data: true
    python -m sweep_ros.client resume           # std_srvs/SetBool data: false
    python -m sweep_ros.client step [N]         # N single steps while paused (default 1)
    python -m sweep_ros.client reset
    python -m sweep_ros.client cmd-vel VX VY    # the crowd's uniform field, m/s (crowd/cmd_vel)
    python -m sweep_ros.client goal X Y         # goal-directed field towards (X, Y), m
    python -m sweep_ros.client goal X Y --group NAME   # the same for the scene's group NAME only
    python -m sweep_ros.client status           # the node's status now (its status service)

Options: ``--namespace NS`` (the node's namespace, default none), ``--timeout S`` (discovery,
and then the reply or verdict, default 10 s). DDS settings come from the environment as for the
node (``ROS_DOMAIN_ID``, ``ROS_AUTOMATIC_DISCOVERY_RANGE``). A command (cmd-vel, goal) waits
for the node's verdict on ``command_result`` (:mod:`sweep_ros.results`) and prints it. Exit
status: 0 done (a command applied, or accepted while the node is paused); 1 the node refused
(its reason is printed), a command was superseded or got no verdict, or more than one node
answered; 2 bad arguments or no node found.
"""
from __future__ import annotations

import argparse
import math
import os
import re
import sys
import time
from collections.abc import Callable
from typing import Any

PROG = "sweep_client"


class ClientError(Exception):
    """A problem the user can fix: printed as one line, exit status 2."""


class Unanswered(Exception):
    """The node was found but its answer is not a success: printed as one line, exit 1."""


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


def _timeout(text: str) -> float:
    value = _finite("--timeout", "seconds")(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(
            f"--timeout = {text!r} is not > 0 (fix: give the seconds to wait, e.g. 10)")
    return value


def _namespace(text: str) -> str:
    from rclpy.exceptions import InvalidNamespaceException
    from rclpy.validate_namespace import validate_namespace

    ns = text if not text or text.startswith("/") else "/" + text
    try:
        if ns:
            validate_namespace(ns)
    except InvalidNamespaceException as err:
        why = str(err).splitlines()[0].removeprefix("Invalid namespace: ").rstrip(": ")
        raise argparse.ArgumentTypeError(
            f"--namespace = {text!r} is not a ROS namespace: {why} (fix: give the node's "
            "namespace, e.g. /crowd)") from None
    return ns


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
    ap.add_argument("--namespace", type=_namespace, default="",
                    help="namespace of sweep_node (default: none)")
    ap.add_argument("--timeout", type=_timeout, default=10.0,
                    help="seconds to wait for the node, then for its reply or verdict "
                         "(default 10)")
    sub = ap.add_subparsers(dest="command", required=True)
    sub.add_parser("pause", help="pause the simulation")
    sub.add_parser("resume", help="resume the simulation")
    step = sub.add_parser("step", help="take N steps while paused")
    step.add_argument("n", nargs="?", type=_positive_int, default=1, metavar="N")
    sub.add_parser("reset", help="back to t = 0, the seed and the scene's drift")
    vel = sub.add_parser("cmd-vel", help="the crowd's uniform velocity field (m/s) on crowd/cmd_vel")
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
    sub.add_parser("status", help="print the node's status now, as it answers between two "
                   "steps (level, message, steps, paused, rates, counters)")
    return ap


class Client:
    """A short-lived node that talks to one sweep_node. Waits poll the graph every
    :attr:`POLL_S` between executor events (discovery, matches and messages wake it at once)."""

    POLL_S = 0.01

    def __init__(self, namespace: str, timeout: float) -> None:
        from rclpy.node import Node
        from rclpy.parameter import Parameter
        from rclpy.qos import QoSProfile, ReliabilityPolicy

        # a name of its own (graph lookups find its endpoints); no parameter services, rosout
        # or type description service: fewer endpoints for the node to discover
        self.node = Node(f"sweep_client_{os.getpid()}", namespace=namespace or None,
                         start_parameter_services=False, enable_rosout=False,
                         parameter_overrides=[Parameter("start_type_description_service",
                                                        value=False)])
        self.timeout = timeout
        self.reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        #: problems reported by endpoint events (incompatible QoS or type): raised at once
        self._problems: list[str] = []

    def _spin_until(self, done: Callable[[], Any], what: str,
                    fail: type[Exception] = ClientError, fix: str = "",
                    problem: str = "") -> Any:
        import rclpy

        end = time.monotonic() + self.timeout
        while True:
            if self._problems:
                raise ClientError(self._problems[0])
            value = done()
            if value:
                return value
            if time.monotonic() >= end:
                break
            rclpy.spin_once(self.node, timeout_sec=self.POLL_S)
        raise fail((problem or f"no answer from {what}") + f" within {self.timeout:g} s (fix: " + (
            fix or "start sweep_node with the same ROS_DOMAIN_ID, "
            "ROS_AUTOMATIC_DISCOVERY_RANGE and --namespace, or raise --timeout") + ")")

    def _events(self, kind: str, name: str, matched: list[int]) -> Any:
        """Endpoint event callbacks: incompatible QoS or type become a problem, matches are
        counted in ``matched[0]``."""
        from rclpy import event_handler

        def incompatible(what: str) -> Callable[[Any], None]:
            def report(info: Any) -> None:
                self._problems.append(
                    f"{name}: the node's endpoint has an incompatible {what} (fix: check that "
                    "the node and this client are the same version of sweep_ros)")
            return report

        def on_match(info: Any) -> None:
            matched[0] = info.current_count
        callbacks = (event_handler.PublisherEventCallbacks if kind == "pub"
                     else event_handler.SubscriptionEventCallbacks)
        return callbacks(incompatible_qos=incompatible("QoS"),
                         incompatible_type=incompatible("message type"), matched=on_match)

    def call(self, srv_type: Any, name: str, request: Any) -> Any:
        """Calls a service of the node; returns its response. More than one server answering
        it raises :class:`Unanswered` after the reply."""
        client: Any = self.node.create_client(srv_type, name)
        full = client.service_name
        self._spin_until(client.service_is_ready, f"service {full}")
        future = client.call_async(request)
        self._spin_until(future.done, f"service {full}", Unanswered,
                         "raise --timeout: the node answers between two steps")
        self.servers = self.node.count_services(full)
        return future.result()

    def command(self, msg_type: Any, name: str, msg: Any) -> list[dict[str, str]]:
        """Publishes one command once a node that gives verdicts subscribes to it, and returns
        the verdicts on it (one per such node; normally one): final ones, or ``accepted``
        while paused. :class:`Unanswered` if a verdict does not come within the timeout."""
        from diagnostic_msgs.msg import DiagnosticArray

        from sweep_ros import results

        got: list[dict[str, str]] = []
        pub_matched, sub_matched = [0], [0]

        def on_result(arr: Any) -> None:
            verdict = results.parse(arr)
            if verdict is not None:
                got.append(verdict)
        sub = self.node.create_subscription(
            DiagnosticArray, results.TOPIC, on_result, results.QOS,
            event_callbacks=self._events("sub", self.node.resolve_topic_name(results.TOPIC),
                                         sub_matched))
        pub = self.node.create_publisher(
            msg_type, name, self.reliable,
            event_callbacks=self._events("pub", self.node.resolve_topic_name(name),
                                         pub_matched))
        topic, result_topic = pub.topic_name, sub.topic_name
        def ready() -> int:
            """The nodes that take the command, once every one of them is matched both ways
            (a command published before a second node's subscription matched would never
            reach it, and its verdict never come)."""
            n = self.commanders(topic, result_topic)
            heard = sub_matched[0] or self.node.count_publishers(result_topic)
            if n and max(pub_matched[0], pub.get_subscription_count()) >= n and heard >= n:
                return n
            return 0
        try:
            commanders = self._spin_until(
                ready, f"a sweep_node subscribing to {topic} and publishing {result_topic}")
        except ClientError as err:
            raise ClientError(f"{err}{self._mismatch(topic, msg_type)}") from None
        gid = self._own_gid(topic)
        msg_stamp = None
        if hasattr(msg, "header"):  # a nonce the node echoes as stamp_ns
            ns = time.time_ns()
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 10**9)
            msg_stamp = str(ns)

        def mine() -> list[dict[str, str]]:
            out = [v for v in got if v.get("topic") == topic and (
                v.get("publisher_gid") == gid if gid and v.get("publisher_gid")
                else msg_stamp is not None and v.get("stamp_ns") == msg_stamp)]
            answered = [v for v in out if v["verdict"] in results.FINAL
                        or v.get("paused") == "true"]
            return answered if len(answered) >= commanders else []
        pub.publish(msg)
        return self._spin_until(mine, "", Unanswered,
                                "see the node's log; raise --timeout if it is busy",
                                f"the node gave no verdict on the command on {topic}")

    def commanders(self, topic: str, result_topic: str) -> int:
        """How many subscriptions to ``topic`` belong to nodes that also publish verdicts."""
        givers = {(e.node_namespace, e.node_name)
                  for e in self.node.get_publishers_info_by_topic(result_topic)}
        return sum(1 for e in self.node.get_subscriptions_info_by_topic(topic)
                   if (e.node_namespace, e.node_name) in givers)

    def _mismatch(self, topic: str, msg_type: Any) -> str:
        """What the graph shows on ``topic`` that is not a sweep_node taking ``msg_type``
        (appended to the error when none answered), or ""."""
        from sweep_ros.msgdefs import msgtype_of

        mine = msgtype_of(msg_type)
        me = (self.node.get_namespace(), self.node.get_name())
        others = [e for e in self.node.get_subscriptions_info_by_topic(topic)
                  if (e.node_namespace, e.node_name) != me]
        wrong = [e for e in others if e.topic_type != mine]
        if wrong:
            e = wrong[0]
            return (f"; {topic} is subscribed to as {e.topic_type} (not {mine}) by "
                    f"{e.node_namespace.rstrip('/')}/{e.node_name}")
        if others:
            names = ", ".join(sorted({f"{e.node_namespace.rstrip('/')}/{e.node_name}"
                                      for e in others}))
            return f"; {topic} is subscribed to only by nodes that give no verdicts ({names})"
        return ""

    def _own_gid(self, topic: str) -> str:
        from sweep_ros.results import gid_hex

        me = (self.node.get_namespace(), self.node.get_name())
        for e in self.node.get_publishers_info_by_topic(topic):
            if (e.node_namespace, e.node_name) == me:
                return gid_hex(e.endpoint_gid)
        return ""



def _one_server(client: Client, what: str) -> int:
    """Exit status 1 with a warning when more than one node answered."""
    n = getattr(client, "servers", 1)
    if n > 1:
        print(f"{PROG}: warning: {n} nodes answer {what}; the one reply shown came from one "
              "of them, and the request reached all (fix: give each node its own name or "
              "namespace)", file=sys.stderr)
        return 1
    return 0


def _report(client: Client, verdicts: list[dict[str, str]], what: str) -> int:
    """Prints the verdicts of a command; returns the exit status."""
    code = 0
    for v in verdicts:
        verdict, message = v["verdict"], v["message"]
        if verdict == "applied":
            print(f"applied: {what} on {v['topic']} from step {v['step']} (t = {v['t_s']} s)")
        elif verdict == "accepted":
            print(f"accepted: {what} on {v['topic']}; {message.removeprefix('accepted: ')}")
        else:
            print(f"{verdict}: {message}")
            code = 1
    if len(verdicts) > 1:
        print(f"{PROG}: warning: {len(verdicts)} nodes took the command on {v['topic']} "
              "(fix: give each node its own name or namespace)", file=sys.stderr)
        code = 1
    return code


def run(args: argparse.Namespace, client: Client) -> int:
    """Executes one command; prints what the node said. Returns the exit status."""
    cmd = args.command
    if cmd in ("pause", "resume"):
        from std_srvs.srv import SetBool

        res = client.call(SetBool, "pause", SetBool.Request(data=cmd == "pause"))
        print(res.message)
        return (0 if res.success else 1) or _one_server(client, "pause")
    if cmd in ("step", "reset"):
        from std_srvs.srv import Trigger

        for _ in range(args.n if cmd == "step" else 1):
            res = client.call(Trigger, cmd, Trigger.Request())
            print(res.message)
            if not res.success:
                return 1
        return _one_server(client, cmd)
    if cmd == "cmd-vel":
        from geometry_msgs.msg import Twist

        twist = Twist()
        twist.linear.x, twist.linear.y = args.vx, args.vy
        return _report(client, client.command(Twist, "crowd/cmd_vel", twist),
                       f"({args.vx:g}, {args.vy:g}) m/s")
    if cmd == "goal":
        from geometry_msgs.msg import PointStamped

        point = PointStamped()
        point.header.frame_id = args.frame
        point.point.x, point.point.y = args.x, args.y
        topic = "goal" if args.group is None else f"goal/{args.group}"
        who = "" if args.group is None else f" for group {args.group}"
        return _report(client, client.command(PointStamped, topic, point),
                       f"goal ({args.x:g}, {args.y:g}) m{who}")
    from std_srvs.srv import Trigger

    res = client.call(Trigger, "status", Trigger.Request())
    print(res.message)
    return (0 if res.success else 1) or _one_server(client, "status")


def main(argv: list[str] | None = None, tidy: bool = True) -> int:
    """Entry point of ``python -m sweep_ros.client``; with ``tidy`` the node is destroyed and
    rclpy shut down before returning (for a caller that goes on in the same process)."""
    args = build_parser().parse_args(argv)
    import rclpy

    rclpy.init()
    client: Client | None = None
    try:
        client = Client(args.namespace, args.timeout)
        return run(args, client)
    except ClientError as err:
        print(f"{PROG}: error: {err}", file=sys.stderr)
        return 2
    except Unanswered as err:
        print(f"{PROG}: error: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    finally:
        if tidy:
            if client is not None:
                client.node.destroy_node()
            rclpy.try_shutdown()


def cli() -> None:
    """Console entry point (``sweep_client``, ``python -m sweep_ros.client``): :func:`main`
    without tidying, then the process ends at once with its status, after flushing its
    output. Destroying the node and shutting rclpy down while the DDS library's threads still
    run can crash (measured: a command under load printed its answer, then died by SIGSEGV in
    that teardown; rclpy's destruction of service clients has a known crash of this kind), and
    a process that ends needs neither: the node's peers see it leave as they see any process
    that ends. Every command has had its answer (a reply or a verdict) before it returns."""
    code = main(tidy=False)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    cli()
