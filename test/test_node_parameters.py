"""The node's parameter refusals name types as users write them.

rclpy refuses a value of another type than a parameter's with the types' numeric codes
("Wrong parameter type, expected '3' got '4'" on Python 3.11); the node says "dt: is a double
parameter, got a string value" with the fix. In this process, through set_parameters and
set_parameters_atomically (what the SetParameters services and ``ros2 param set`` call).
"""
from __future__ import annotations

import pytest

rclpy = pytest.importorskip("rclpy")
from rclpy.parameter import Parameter  # noqa: E402

from sweep_ros.node import SweepNode, typed_reason  # noqa: E402


@pytest.fixture
def node():
    context = rclpy.Context()
    rclpy.init(context=context)
    n = SweepNode(context=context, parameter_overrides=[
        Parameter("name_check_s", value=0.0), Parameter("record", value="")])
    try:
        yield n
    finally:
        n.close()
        n.destroy_node()
        rclpy.shutdown(context=context)


@pytest.mark.parametrize("name,value,words", [
    ("dt", "fast", "dt: is a double parameter, got a string value (fix: give a double value)"),
    ("dt", 1, "dt: is a double parameter, got an integer value (fix: write the number with a "
              "decimal point"),
    ("seed", 1.5, "seed: is an integer parameter, got a double value"),
    ("enable_stamped_cmd_vel", "yes", "is a bool parameter, got a string value"),
])
def test_a_value_of_the_wrong_type_is_refused_with_type_names(node, name, value, words):
    if not node.has_parameter(name):
        pytest.fail(f"no parameter {name}")
    for result in (node.set_parameters_atomically([Parameter(name, value=value)]),
                   node.set_parameters([Parameter(name, value=value)])[0]):
        assert not result.successful
        assert words in result.reason and "'3'" not in result.reason, result.reason


def test_other_reasons_pass_unchanged():
    assert typed_reason("dt", "dt: 5 s is outside [1e-05, 1] s") == \
        "dt: 5 s is outside [1e-05, 1] s"
