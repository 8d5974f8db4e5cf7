"""Entry point of ``ros2 run sweep_ros sweep_node`` (installed as ``lib/sweep_ros/sweep_node``):
start rclpy, run :class:`sweep_ros.node.SweepNode` until SIGINT or SIGTERM, close the recording.

    ros2 run sweep_ros sweep_node --ros-args --params-file config/sweep_node.yaml
    sweep_node --ros-args -p scene:=my_scene.yaml -p record:=run.mcap     (pip install, no ROS CLI)
"""
from __future__ import annotations

import signal
import sys
import threading
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions

from sweep_ros.errors import StartError
from sweep_ros.node import NODE_NAME, SweepNode


class StopOnSignal:
    """SIGINT and SIGTERM set a flag that the spin loop checks between callbacks.

    With rclpy's own handlers SIGINT becomes a KeyboardInterrupt raised wherever the main
    thread happens to be (inside a step, a publish, a queue operation). With a flag the node
    stops between callbacks, so the engine and the recording are in a consistent state when
    the recording is closed. A step that blocks in native code (a QP solve) delays the stop
    until it returns; a second signal of the same kind gets the default action (immediate
    termination; the recording stays readable up to its last flushed chunk).
    """

    def __init__(self) -> None:
        self.event = threading.Event()
        self.signum: int | None = None
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, self._handle)

    def _handle(self, signum: int, frame: Any) -> None:
        self.signum = signum
        self.event.set()
        signal.signal(signum, signal.SIG_DFL)


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run sweep_ros sweep_node``."""
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    stop = StopOnSignal()
    node: SweepNode | None = None
    code = 0
    try:
        node = SweepNode()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        while not stop.event.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    except StartError as err:
        for problem in err.problems:
            print(f"{NODE_NAME}: error: {problem}", file=sys.stderr)
        code = 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.close()
            node.destroy_node()
        rclpy.try_shutdown()
    return code


if __name__ == "__main__":
    sys.exit(main())
