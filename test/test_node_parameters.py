"""The node's parameter refusals name types as users write them.

rclpy refuses a value of another type than a parameter's with the types' numeric codes
("Wrong parameter type, expected '3' got '4'" on Python 3.11); the node says "dt: is a double
parameter, got a string value" with the fix. In this process, through set_parameters and
set_parameters_atomically (what the SetParameters services and ``ros2 param set`` call).
"""
from __future__ import annotations

import pytest

rclpy = pytest.importorskip("rclpy")
from node_process import node_in_process  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from sweep_ros.node import typed_reason  # noqa: E402


@pytest.fixture
def node():
    with node_in_process([Parameter("record", value="")]) as n:
        yield n


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
