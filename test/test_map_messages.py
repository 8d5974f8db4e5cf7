"""sweep_ros.messages.map_from_grid and the map_topic parameter: pure functions, no DDS
(issue 13, the node's map topic)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from nav_msgs.msg import OccupancyGrid
from rclpy.serialization import deserialize_message, serialize_message

from sweep_ros import messages, params
from sweep_ros.messages import CommandError


def grid_msg(cells: np.ndarray, res: float = 0.5, origin=(1.0, -2.0), yaw: float = 0.0,
             frame: str = "map") -> OccupancyGrid:
    m = OccupancyGrid()
    m.header.frame_id = frame
    m.info.resolution = res
    m.info.height, m.info.width = cells.shape
    m.info.origin.position.x, m.info.origin.position.y = origin
    m.info.origin.orientation.z, m.info.origin.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    m.data = np.asarray(cells, dtype=np.int8).ravel().tolist()
    return m


CELLS = np.array([[100, 100, 100], [0, -1, 24], [25, 0, 0]])  # row 0 = lowest y


def test_a_map_server_grid_becomes_the_map() -> None:
    msg = deserialize_message(serialize_message(grid_msg(CELLS, yaw=0.3)), OccupancyGrid)
    grid = messages.map_from_grid(msg, "map", "/map")
    assert grid.blocked.tolist() == [[True, True, True], [False, True, False],
                                     [True, False, False]]
    assert grid.resolution == 0.5 and grid.origin[:2] == (1.0, -2.0)
    assert grid.origin[2] == pytest.approx(0.3, abs=1e-12) and grid.source == "/map"
    # an empty frame is taken as the simulation frame
    assert messages.map_from_grid(grid_msg(CELLS, frame=""), "map").shape == (3, 3)


@pytest.mark.parametrize("change, words", [
    (lambda m: setattr(m.header, "frame_id", "odom"), "frame 'odom' is not the simulation frame"),
    (lambda m: setattr(m.info.origin.orientation, "x", 0.5), "is not a rotation about z"),
    (lambda m: setattr(m.info.origin.orientation, "w", 0.0), "its norm 0 is below 1e-09"),
    (lambda m: setattr(m.info.origin.position, "x", math.nan), "non-finite info.origin"),
    (lambda m: setattr(m.info, "resolution", 0.0), "info.resolution must be"),
    (lambda m: setattr(m.info, "resolution", math.inf), "info.resolution inf is not finite"),
    (lambda m: setattr(m.info, "width", 4), "data holds 9 cells, not width x height = 4 x 3"),
    (lambda m: setattr(m.info, "width", 0), "info.width must be an integer >= 1"),
    (lambda m: setattr(m, "data", [0] * 8 + [101]), "data holds 101 at cell 8"),
])
def test_malformed_grids_are_refused_naming_the_field(change, words) -> None:
    msg = grid_msg(CELLS)
    change(msg)
    with pytest.raises(CommandError) as err:
        messages.map_from_grid(msg, "map", "/map")
    text = str(err.value)
    assert text.startswith("/map: ") and words in text and "(fix: " in text, text
    assert "\n" not in text and "array(" not in text


def test_a_huge_origin_quaternion_is_checked_as_the_rotation_it_names() -> None:
    """Components near 1e200 (their squares overflow) name the rotation they do: a planar one
    is taken with its yaw, one with a roll as large as its yaw is refused (it was taken as
    planar: the overflowed norm let any roll through)."""
    msg = grid_msg(CELLS)
    o = msg.info.origin.orientation
    o.z, o.w = 1e200, 1e200
    assert messages.map_from_grid(msg, "map", "/map").origin[2] == pytest.approx(math.pi / 2)
    o.x = 1e200
    with pytest.raises(CommandError, match="is not a rotation about z"):
        messages.map_from_grid(msg, "map", "/map")


def test_map_topic_parameter() -> None:
    assert params.defaults()["map_topic"] == ""
    assert "map_topic" not in params.LIVE
    assert params.check_value("map_topic", "map") is None
    assert params.check_value("map_topic", "/robot/map") is None
    problem = params.check_value("map_topic", "my map")
    assert problem is not None and problem.startswith("map_topic: 'my map' is not a valid")
