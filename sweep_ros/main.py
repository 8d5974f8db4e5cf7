"""Entry point of ``ros2 run sweep_ros sweep_node`` (installed as ``lib/sweep_ros/sweep_node``):
start rclpy, run :class:`sweep_ros.node.SweepNode` (its steps on a thread of their own, services
and commands on this one) until SIGINT or SIGTERM, close the recording with a final status
record.

    ros2 run sweep_ros sweep_node --ros-args --params-file config/sweep_node.yaml
    sweep_node --ros-args -p scene:=my_scene.yaml -p record:=run.mcap     (pip install, no ROS CLI)
"""
from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Callable
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions

from sweep_ros import params_files
from sweep_ros.errors import StartError
from sweep_ros.node import NODE_NAME, SweepNode


class StopOnSignal:
    """SIGINT and SIGTERM set a flag that the spin loop checks between callbacks.

    With rclpy's own handlers SIGINT becomes a KeyboardInterrupt raised wherever the main
    thread happens to be (inside a publish, a queue operation), and SIGTERM is not handled at
    all. With a flag both take the same path: the tick in progress ends at its next step
    boundary (``on_signal``), then the node writes its ``status`` record (``interrupted``,
    reason ``SIGINT`` or ``SIGTERM``) and closes the recording. A step that blocks in native
    code (a QP solve) delays the stop until it returns; a second signal of the same kind gets
    the default action (immediate termination; the recording stays readable up to its last
    flushed chunk).
    """

    def __init__(self) -> None:
        self.event = threading.Event()
        self.signum: int | None = None
        self.on_signal: Callable[[], None] | None = None
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, self._handle)

    def _handle(self, signum: int, frame: Any) -> None:
        self.signum = signum
        self.event.set()
        signal.signal(signum, signal.SIG_DFL)
        if self.on_signal is not None:
            self.on_signal()

    @property
    def name(self) -> str:
        """The signal's name (``SIGTERM``), or empty if none arrived."""
        return signal.Signals(self.signum).name if self.signum is not None else ""


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run sweep_ros sweep_node``."""
    # a broken --params-file is a one-line error here, not rclpy's traceback
    problems = params_files.check_params_files(sys.argv if args is None else args, NODE_NAME)
    if problems:
        for problem in problems:
            print(f"{NODE_NAME}: error: {problem}", file=sys.stderr)
        return 2
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    stop = StopOnSignal()
    node: SweepNode | None = None
    executor: SingleThreadedExecutor | None = None
    code = 0
    status, reason = "completed", "the ROS context was shut down"
    try:
        node = SweepNode()
        stop.on_signal = node.request_stop
        # services, commands, parameters and diagnostics on this thread; steps on the node's
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        while (not stop.event.is_set() and rclpy.ok() and node.crash is None
               and node.duplicate is None):
            executor.spin_once(timeout_sec=0.1)
        if node.crash is not None:
            status, reason, code = "failed", node.crash, 1
        elif node.duplicate is not None:
            print(f"{NODE_NAME}: error: {node.duplicate}", file=sys.stderr)
            status, reason, code = "failed", node.duplicate, 2
    except StartError as err:
        for problem in err.problems:
            print(f"{NODE_NAME}: error: {problem}", file=sys.stderr)
        code = 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception as err:  # a callback raised: record why before the traceback
        status, reason = "failed", f"{type(err).__name__}: {err}"
        raise
    finally:
        if stop.event.is_set():
            status, reason = "interrupted", stop.name
        if node is not None:
            node.close(status, reason)  # after the step in progress
        if executor is not None:
            executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return code


if __name__ == "__main__":
    sys.exit(main())
