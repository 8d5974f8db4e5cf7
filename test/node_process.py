"""sweep_node built in this test's process, on its own rclpy context, closed afterwards."""
from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import rclpy
from rclpy.parameter import Parameter

from sweep_ros.node import SweepNode


@contextmanager
def node_in_process(overrides: list[Parameter]) -> Iterator[SweepNode]:
    """The node with the parameters ``overrides`` (and its name check off), on a fresh rclpy
    context; closed, destroyed and the context shut down on leaving."""
    context = rclpy.Context()
    rclpy.init(context=context)
    n = SweepNode(context=context, parameter_overrides=[Parameter("name_check_s", value=0.0),
                                                         *overrides])
    try:
        yield n
    finally:
        n.close()
        n.destroy_node()
        rclpy.shutdown(context=context)
