"""Velocity-field commands: an organised sensor_msgs/PointCloud2 grid to a sweep_core Grid field
(:func:`grid_from_cloud`), checked (layout, regular axes, finite values, speed); anything
malformed raises :class:`~sweep_ros.messages.CommandError` naming the field and the fix.
"""
from __future__ import annotations

from typing import Any

import numpy as np
from sensor_msgs.msg import PointField

from sweep_core import SceneError, grid_field
from sweep_core.errors import show
from sweep_core.model.fields import Grid
from sweep_ros.messages import CommandError, check_speed

#: largest grid (points) a velocity_field command may carry
MAX_GRID_POINTS = 1_000_000
#: relative tolerance on grid node spacing (float32 clouds carry rounding of ~1e-7 relative)
GRID_TOLERANCE = 1e-4
#: field names a velocity_field cloud must have
GRID_FIELDS = ("x", "y", "vx", "vy")

_DTYPES = {PointField.FLOAT32: "f4", PointField.FLOAT64: "f8"}
_FIELDS_FIX = "send FLOAT32 or FLOAT64 fields x, y, vx, vy, count 1 each"


def _cloud_layout(msg: Any, topic: str) -> tuple[int, int, np.ndarray, dict[str, tuple[int, str]]]:
    """Check an organised cloud's layout: (height, width, data bytes, name -> (offset, code))."""
    h, w = int(msg.height), int(msg.width)
    if h < 1 or w < 1:
        raise CommandError(topic, f"empty grid (height {h}, width {w}) (fix: send an organised "
                                  "cloud of height >= 1 rows along y and width >= 1 columns "
                                  "along x)")
    if h * w > MAX_GRID_POINTS:
        raise CommandError(topic, f"{h} x {w} grid exceeds {MAX_GRID_POINTS} points (fix: "
                                  f"resample the field onto at most {MAX_GRID_POINTS} nodes)")
    by_name = {f.name: f for f in msg.fields}
    missing = [n for n in GRID_FIELDS if n not in by_name]
    if missing:
        raise CommandError(topic, f"missing fields {missing} (has {sorted(by_name)}) (fix: "
                                  f"{_FIELDS_FIX})")
    step, row = int(msg.point_step), int(msg.row_step)
    data = np.frombuffer(memoryview(msg.data).cast("B"), dtype=np.uint8)
    if row < w * step or len(data) < row * (h - 1) + w * step:
        raise CommandError(topic, f"data holds {len(data)} bytes, too few for {h} x {w} points "
                                  f"of point_step {step}, row_step {row} (fix: send row_step >= "
                                  "width * point_step and height * row_step bytes of data)")
    layout = {}
    for name in GRID_FIELDS:
        f = by_name[name]
        code = _DTYPES.get(int(f.datatype))
        if code is None or int(f.count) != 1:
            raise CommandError(topic, f"field {name!r} must be one FLOAT32 or FLOAT64 "
                                      f"(datatype {f.datatype}, count {f.count}) (fix: "
                                      f"{_FIELDS_FIX})")
        if int(f.offset) + int(code[1]) > step:
            raise CommandError(topic, f"field {name!r} at offset {f.offset} overruns "
                                      f"point_step {step} (fix: set point_step to the size of "
                                      "one point, at least the end of its last field)")
        layout[name] = (int(f.offset), code)
    return h, w, data, layout


def _cloud_columns(h: int, w: int, data: np.ndarray, layout: dict[str, tuple[int, str]],
                   step: int, row: int, order: str) -> dict[str, np.ndarray]:
    """The x, y, vx, vy columns as float64 (height, width) arrays, read in byte order
    ``order`` ("<" little-endian, ">" big-endian)."""
    return {name: np.ndarray((h, w), dtype=order + code, buffer=data, offset=offset,
                             strides=(row, step)).astype(np.float64)
            for name, (offset, code) in layout.items()}


def _axis_nodes(values: np.ndarray, axis: int, name: str, topic: str) -> np.ndarray:
    """Node coordinates of a grid axis: values must depend on one index only and be evenly
    spaced (within GRID_TOLERANCE of the spacing); returned snapped to x0 + k dx."""
    nodes = values[0, :] if axis == 1 else values[:, 0]
    along = "column" if axis == 1 else "row"
    other = values - (nodes[None, :] if axis == 1 else nodes[:, None])
    n = nodes.size
    spacing = float(np.max(np.abs(np.diff(nodes)))) if n > 1 else 1.0
    if np.max(np.abs(other)) > GRID_TOLERANCE * spacing:
        r, c = (int(i) for i in np.unravel_index(int(np.argmax(np.abs(other))), other.shape))
        raise CommandError(topic, f"{name} must depend on the {along} index only, but row {r}, "
                                  f"column {c} holds {name} = {values[r, c]:g} (fix: rows "
                                  "along y, columns along x)")
    if n == 1:
        return nodes.copy()
    step = (nodes[-1] - nodes[0]) / (n - 1)
    ideal = nodes[0] + step * np.arange(n)
    if step == 0 or np.max(np.abs(nodes - ideal)) > GRID_TOLERANCE * abs(step):
        raise CommandError(topic, f"{name} is an irregular grid {show(nodes)} (fix: resample "
                                  "onto evenly spaced nodes)")
    return ideal


def _grid(cols: dict[str, np.ndarray], max_speed: float, topic: str) -> Grid:
    """The Grid of a cloud's columns (see :func:`grid_from_cloud`)."""
    for name, arr in cols.items():
        if not np.all(np.isfinite(arr)):
            r, c = (int(i) for i in np.argwhere(~np.isfinite(arr))[0])
            raise CommandError(topic, f"non-finite {name} {arr[r, c]:g} at row {r}, column {c} "
                                      "(fix: send finite numbers only)")
    x = _axis_nodes(cols["x"], 1, "x", topic)
    y = _axis_nodes(cols["y"], 0, "y", topic)
    vx, vy = cols["vx"], cols["vy"]
    if x.size > 1 and x[1] < x[0]:
        x, vx, vy = x[::-1], vx[:, ::-1], vy[:, ::-1]
    if y.size > 1 and y[1] < y[0]:
        y, vx, vy = y[::-1], vx[::-1], vy[::-1]
    check_speed(topic, float(np.max(np.hypot(vx, vy))), max_speed)
    try:
        return grid_field(x, y, np.ascontiguousarray(vx), np.ascontiguousarray(vy), topic)
    except SceneError as err:
        raise CommandError(topic, str(err).removeprefix(f"{topic}.")) from err


def grid_from_cloud(msg: Any, max_speed: float, topic: str = "velocity_field") -> Grid:
    """sensor_msgs/PointCloud2 organised grid (height x width; fields x, y, vx, vy) -> Grid.

    Row r, column c holds the node (x_c, y_r). Axes may run either way (they are sorted);
    spacing must be even. Big- and little-endian data are both read (``is_bigendian``). The
    field is bilinear inside the grid and, outside, takes the value at the nearest point of the
    grid (sweep_core's Grid). A cloud refused as it is flagged, but valid in the other byte
    order, is refused with a message saying that is_bigendian does not match its data."""
    h, w, data, layout = _cloud_layout(msg, topic)
    step, row = int(msg.point_step), int(msg.row_step)
    big = bool(msg.is_bigendian)
    try:
        return _grid(_cloud_columns(h, w, data, layout, step, row, ">" if big else "<"),
                     max_speed, topic)
    except CommandError as err:
        try:
            _grid(_cloud_columns(h, w, data, layout, step, row, "<" if big else ">"),
                  max_speed, topic)
        except CommandError:
            raise err from None
        flag, other = ("true", "little") if big else ("false", "big")
        raise CommandError(topic, f"is_bigendian={flag} but the data is {other}-endian: read "
                                  f"as flagged, {err.problem.split(' (fix: ')[0]} (fix: set "
                                  f"is_bigendian={'false' if big else 'true'} to match the "
                                  "data's byte order)") from None
