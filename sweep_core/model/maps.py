"""Occupancy maps (the ROS map_server format, nav_msgs/OccupancyGrid) turned into walls.

A map is a grid of square cells of ``resolution`` m; a cell is *blocked* when it is occupied
or unknown (unknown space is treated as a wall: agents are never placed or pushed into what
the map does not know), and everything outside the grid is blocked too. The walls are the
boundary between blocked and free cells, written exactly (tolerance 0): every cell edge with
a blocked cell on one side and a free cell on the other, merged into one segment per straight
run. An agent whose centre is in a free cell and whose disk keeps clear of those segments is
in the free space; the steps never cross a segment (each segment's row is a half-plane clear
of the segment: reference §4), so it stays there.

A nav_msgs/OccupancyGrid (what map_server publishes; :meth:`OccupancyMap.from_occupancy_grid`)
holds the same cells as values 0..100 (occupancy, percent) or -1 (unknown), row 0 at the
origin (not flipped like an image); the same rule applies with p = value / 100.

Map files (map_server's YAML): ``image`` (PGM or PNG, relative to the YAML file),
``resolution`` (m per cell), ``origin`` [x, y, yaw] (the pose of the lower-left corner of the
lower-left pixel), ``negate`` (0/1), ``occupied_thresh``, ``free_thresh`` (probabilities),
``mode`` (trinary, the default, or scale: read the same way, since only free cells matter;
raw, whose pixels are occupancies 0..100, is refused). A pixel of value v (0..255) has
occupancy p = (255 - v) / 255 (v / 255 when negate); p > occupied_thresh: occupied;
p < free_thresh: free; otherwise unknown.
"""
from __future__ import annotations

import base64
import copy
import os
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sweep_core import checks
from sweep_core.errors import CostError, SceneError, show
from sweep_core.model import elementary
from sweep_core.model.yaml_files import YAMLError, load_yaml

#: most cells a map may have (a 40 000 x 40 000 grid would be 1.6e9)
MAX_CELLS = 25_000_000
#: most walls a map may make (straight runs of cell edges between blocked and free cells):
#: each costs about 0.4 kB and 8 us to build (measured: 1 million walls, from a map of
#: isolated blocked cells 166 kB packed, took 7.7 s and 0.45 GB before this bound)
MAX_MAP_WALLS = 250_000
#: largest map YAML file read (bytes): map_server's files are a few hundred bytes
MAX_YAML_BYTES = 1 << 20
#: largest map image read (bytes): an ASCII PGM of MAX_CELLS pixels of up to 3 digits
MAX_IMAGE_BYTES = 4 * MAX_CELLS + (1 << 20)


@dataclass(frozen=True)
class OccupancyMap:
    """blocked (H, W) bool, row 0 the lowest y (the image's last row); resolution m per cell;
    origin (x, y, yaw) the pose (m, m, rad) of the grid's lower-left corner; source: where it
    came from, for messages and the scene's spec."""

    blocked: np.ndarray
    resolution: float
    origin: tuple[float, float, float]
    source: str
    #: the image file it was read from ("" when not read from files)
    image: str = ""

    def __post_init__(self) -> None:
        h, w = self.shape
        corners = self.to_world(np.array([[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]])
                                * self.resolution)
        checks.within_bound(corners, "map corners", "coordinate")

    @property
    def shape(self) -> tuple[int, int]:
        return int(self.blocked.shape[0]), int(self.blocked.shape[1])

    def to_local(self, q: np.ndarray) -> np.ndarray:
        """World points (N, 2) in the grid frame (m from the lower-left corner)."""
        x0, y0, yaw = self.origin
        s, c = elementary.sincos(yaw)
        d = np.asarray(q, dtype=float) - [x0, y0]
        return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], axis=1)

    def to_world(self, p: np.ndarray) -> np.ndarray:
        """Grid-frame points (N, 2) in the world frame."""
        x0, y0, yaw = self.origin
        s, c = elementary.sincos(yaw)
        p = np.asarray(p, dtype=float)
        return np.stack([x0 + c * p[:, 0] - s * p[:, 1], y0 + s * p[:, 0] + c * p[:, 1]], axis=1)

    def is_blocked(self, q: np.ndarray) -> np.ndarray:
        """(N,) bool: the point lies in a blocked cell or outside the grid."""
        local = self.to_local(q) / self.resolution
        col, row = np.floor(local[:, 0]).astype(np.int64), np.floor(local[:, 1]).astype(np.int64)
        h, w = self.shape
        inside = (row >= 0) & (row < h) & (col >= 0) & (col < w)
        out = np.ones(len(local), dtype=bool)
        out[inside] = self.blocked[row[inside], col[inside]]
        return out

    def segments(self) -> tuple[np.ndarray, np.ndarray]:
        """The walls: end points a, b (S, 2) in the world frame, one per straight run of cell
        edges between a blocked and a free cell (the grid's outside counts as blocked)."""
        pad = np.pad(self.blocked, 1, constant_values=True)
        count = 0
        for grid in (pad, pad.T):  # the runs counted before any is built
            edge = grid[:-1, :] != grid[1:, :]
            count += int(np.count_nonzero(edge[:, 0]))
            count += int(np.count_nonzero(edge[:, 1:] & ~edge[:, :-1]))
        if count > MAX_MAP_WALLS:
            h, w = self.shape
            raise CostError("map", f"its {w} x {h} cells make {count} walls (straight runs "
                             f"between blocked and free cells), more than {MAX_MAP_WALLS}",
                             "use a coarser resolution, or clean isolated blocked cells from "
                             "the map")
        starts, ends = [], []
        for grid, flip in ((pad, False), (pad.T, True)):
            # edges between rows r and r + 1 of ``grid`` (padded), at height r in cells
            edge = grid[:-1, :] != grid[1:, :]
            rows, c0, c1 = _runs(edge)
            # padded column c is grid cell c - 1: a run of columns c0..c1 spans [c0 - 1, c1]
            a = np.stack([c0 - 1.0, rows.astype(float)], axis=1)
            b = np.stack([c1.astype(float), rows.astype(float)], axis=1)
            if flip:
                a, b = a[:, ::-1], b[:, ::-1]
            starts.append(a)
            ends.append(b)
        a = np.concatenate(starts) * self.resolution
        b = np.concatenate(ends) * self.resolution
        return self.to_world(a), self.to_world(b)

    @classmethod
    def from_occupancy_grid(cls, data: Any, width: int, height: int, resolution: float,
                            origin_xy_yaw: Any, occupied_thresh: float = 0.65,
                            free_thresh: float = 0.25, source: str = "OccupancyGrid",
                            field: str = "map") -> OccupancyMap:
        """A nav_msgs/OccupancyGrid: ``data`` (width x height int8 values, row-major from the
        grid origin, row 0 the lowest y: not flipped like an image), 0..100 the occupancy in
        percent, -1 unknown; ``resolution`` m per cell; ``origin_xy_yaw`` (m, m, rad) the pose
        of the lower-left corner of cell (0, 0). The rule of the map files: a cell is free iff
        p = value / 100 < free_thresh, blocked otherwise (occupied or unknown);
        ``occupied_thresh`` only has to be >= free_thresh (it separates occupied from unknown,
        both blocked here). Raises SceneError naming ``field`` for a malformed grid."""
        w = checks.integer(width, f"{field}.info.width", low=1)
        h = checks.integer(height, f"{field}.info.height", low=1)
        if w * h > MAX_CELLS:
            raise SceneError(field, f"has {w} x {h} = {w * h} cells, more than {MAX_CELLS}",
                             "publish a coarser or cropped map")
        occupied = checks.number(occupied_thresh, "occupied_thresh")
        free = checks.number(free_thresh, "free_thresh")
        if not 0.0 <= free <= occupied <= 1.0:
            raise SceneError(field, f"free_thresh {free:g} and occupied_thresh {occupied:g} "
                             "are not 0 <= free <= occupied <= 1", "use e.g. 0.25 and 0.65")
        values = np.asarray(data)
        if values.ndim != 1 or (len(values) and values.dtype.kind not in "iu"):
            raise SceneError(f"{field}.data", f"must be a flat sequence of integers, got "
                             f"{values.dtype} of shape {values.shape}",
                             "give the OccupancyGrid's data (int8, row-major)")
        if len(values) != w * h:
            raise SceneError(f"{field}.data", f"holds {len(values)} cells, not width x height "
                             f"= {w} x {h} = {w * h}", "publish width * height values")
        values = values.astype(np.int64)
        bad = np.flatnonzero((values < -1) | (values > 100))
        if len(bad):
            k = int(bad[0])
            raise SceneError(f"{field}.data", f"holds {int(values[k])} at cell {k} (row "
                             f"{k // w}, column {k % w}; {len(bad)} such cells)",
                             "use 0..100 (occupancy, percent) or -1 (unknown)")
        free_cells = (values >= 0) & (values / 100.0 < free)
        return cls(~free_cells.reshape(h, w), _resolution(resolution, f"{field}.info.resolution"),
                   _origin(origin_xy_yaw, f"{field}.info.origin"), source)

    def to_spec(self) -> dict:
        """The map in a scene's normalised dict, self-contained (the cells packed, base64), so a
        recording replays without the map file."""
        h, w = self.shape
        packed = base64.b64encode(np.packbits(self.blocked.ravel()).tobytes()).decode()
        return {"source": self.source, "resolution": self.resolution,
                "origin": list(self.origin), "width": w, "height": h, "blocked": packed}


def _runs(edge: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Maximal runs of True along the rows of edge (R, C): their row, first and last column."""
    padded = np.pad(edge.astype(np.int8), ((0, 0), (1, 1)))
    step = np.diff(padded, axis=1)
    r0, c0 = np.nonzero(step == 1)
    r1, c1 = np.nonzero(step == -1)
    # both are in row-major order, one start and one end per run
    return r0, c0, c1 - 1


def replace_map(spec: dict, packed: dict) -> dict:
    """A copy of a scene's normalised spec with its ``map`` entry replaced by ``packed`` (what
    :meth:`OccupancyMap.to_spec` gives): ``Scene.from_dict`` of it is the scene with the new
    map's walls and everything else as before (how the node and replay apply a map)."""
    out = copy.deepcopy(spec)
    out["map"] = copy.deepcopy(packed)
    return out


def map_from_spec(value: Any, field: str, base: Path | None, files: bool = True
                  ) -> OccupancyMap:
    """The scene's ``map`` entry: ``{yaml: PATH}`` (relative to the scene file, else to the
    working directory) or the packed form :meth:`OccupancyMap.to_spec` writes. ``files=False``
    (a scene carried by a recording) refuses ``{yaml: PATH}``: a recording is replayed from
    the packed map it carries, never from a local file it names."""
    spec = checks.mapping(value, field, allowed={"yaml", "source", "resolution", "origin",
                                                 "width", "height", "blocked"})
    if "yaml" in spec:
        if set(spec) != {"yaml"}:
            raise SceneError(field, "mixes yaml with the packed form",
                             "give either {yaml: PATH} or the packed map a recording holds")
        if not files:
            raise SceneError(f"{field}.yaml", "names a map file; a recorded scene carries its "
                             "map packed, and local files it names are never read",
                             "use a recording made by sweep run or sweep_node")
        path = Path(str(spec["yaml"]))
        if not path.is_absolute() and base is not None:
            path = base / path
        return read_map_yaml(path, f"{field}.yaml")
    missing = {"resolution", "origin", "width", "height", "blocked"} - set(spec)
    if missing:
        raise SceneError(field, f"has no {', '.join(sorted(missing))}",
                         "give {yaml: PATH} to a map_server YAML file")
    w = checks.integer(spec["width"], f"{field}.width", low=1)
    h = checks.integer(spec["height"], f"{field}.height", low=1)
    if w * h > MAX_CELLS:
        raise CostError(field, f"has {w * h} cells, more than {MAX_CELLS}",
                         "use a coarser resolution or crop the map")
    try:
        bits = np.frombuffer(base64.b64decode(str(spec["blocked"]), validate=True), np.uint8)
    except ValueError as err:
        raise SceneError(f"{field}.blocked", "is not base64", "use the form a recording holds") \
            from err
    if len(bits) * 8 < w * h:
        raise SceneError(f"{field}.blocked", f"holds {len(bits) * 8} cells, not {w} x {h}",
                         "use the form a recording holds")
    blocked = np.unpackbits(bits)[: w * h].astype(bool).reshape(h, w)
    return OccupancyMap(blocked, _resolution(spec["resolution"], f"{field}.resolution"),
                        _origin(spec["origin"], f"{field}.origin"), str(spec.get("source", "")))


def read_map_yaml(path: Path, field: str = "map.yaml") -> OccupancyMap:
    """A map_server map: its YAML file and the image it names (see the module docstring).

    Both are read only when they are regular files of at most :data:`MAX_YAML_BYTES` /
    :data:`MAX_IMAGE_BYTES` (no FIFO, device or huge file is opened); errors name the file and
    what is wrong with it, never its contents."""
    fix = "give the path of a map_server YAML file"
    try:
        meta = load_yaml(read_bounded(path, MAX_YAML_BYTES, field, fix).decode())
    except UnicodeDecodeError as err:
        raise SceneError(field, f"{str(path)!r} is not UTF-8 text", fix) from err
    except YAMLError as err:
        raise SceneError(field, f"{path} is not valid YAML ({_yaml_where(err)})",
                         "correct the map file's YAML syntax at that line") from err
    where = f"{field} ({path.name})"
    if not isinstance(meta, dict):
        raise SceneError(where, f"{str(path)!r} is not a map_server YAML file (its top level "
                         "is not a mapping of image, resolution, origin, ...)", fix)
    allowed = {"image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh",
               "mode"}
    unknown = [k for k in meta if k not in allowed]
    if unknown:  # not named: the file may be anything, and errors quote none of it
        raise SceneError(where, f"{str(path)!r} has {len(unknown)} key(s) a map_server YAML "
                         "file does not have", f"use only the keys {sorted(allowed)}")
    meta = checks.mapping(meta, where, allowed=allowed, required={"image", "resolution", "origin"})
    resolution = _resolution(meta["resolution"], f"{where}.resolution")
    origin = _origin(meta["origin"], f"{where}.origin")
    negate = meta.get("negate", 0)
    if negate not in (0, 1, True, False):
        raise SceneError(f"{where}.negate", f"must be 0 or 1, got {negate!r}", "write 0 or 1")
    mode = meta.get("mode", "trinary")
    if mode == "raw":
        raise SceneError(f"{where}.mode", "is raw: its pixels are occupancies 0..100 (255 "
                         "unknown), which are not read here", "convert the image to trinary "
                         "(0 occupied, 254 free, 205 unknown) and write mode: trinary")
    if mode not in ("trinary", "scale"):
        raise SceneError(f"{where}.mode", f"unknown mode {show(mode)}",
                         "write mode: trinary (or scale, read the same way: a cell is free "
                         "when its occupancy is under free_thresh)")
    occupied = checks.number(meta.get("occupied_thresh", 0.65), f"{where}.occupied_thresh")
    free = checks.number(meta.get("free_thresh", 0.25), f"{where}.free_thresh")
    if not 0.0 <= free <= occupied <= 1.0:
        raise SceneError(where, f"free_thresh {free:g} and occupied_thresh {occupied:g} are "
                         "not 0 <= free <= occupied <= 1", "use e.g. 0.25 and 0.65")
    image = Path(str(meta["image"]))
    if not image.is_absolute():
        image = path.parent / image
    pixels = read_image(image, f"{where}.image")
    p = pixels / 255.0 if negate else (255.0 - pixels) / 255.0
    blocked = ~(p < free)  # occupied or unknown
    # image row 0 is the top of the map: flip so that row 0 is the lowest y
    return OccupancyMap(blocked[::-1].copy(), resolution, origin, str(path), str(image))


def _yaml_where(err: YAMLError) -> str:
    """Where a YAML error is (line, column) and what it is, without the text it quotes."""
    mark = getattr(err, "problem_mark", None)
    problem = getattr(err, "problem", None) or "not YAML"
    at = f"line {mark.line + 1} column {mark.column + 1}: " if mark is not None else ""
    return f"{at}{problem.split(' that ')[0].split(chr(39))[0].strip()}"


def read_bounded(path: Path, limit: int, field: str, fix: str) -> bytes:
    """The bytes of ``path`` once it is known to be a regular file of at most ``limit``
    bytes (checked with stat before it is opened, and again on the open file)."""
    data = b""
    try:
        st = os.stat(path)
        if stat.S_ISREG(st.st_mode) and st.st_size <= limit:
            with open(path, "rb") as f:
                st = os.fstat(f.fileno())
                data = f.read(limit + 1) if stat.S_ISREG(st.st_mode) else b""
    except OSError as err:
        raise SceneError(field, f"cannot read {str(path)!r}: {err.strerror}", fix) from err
    if not stat.S_ISREG(st.st_mode):
        raise SceneError(field, f"{str(path)!r} is {checks.file_kind(st.st_mode)}, not a regular file",
                         fix)
    if st.st_size > limit or len(data) > limit:
        raise SceneError(field, f"{str(path)!r} has {max(st.st_size, len(data))} bytes, more "
                         f"than the limit of {limit} bytes for this file", fix)
    return data


def read_image(path: Path, field: str) -> np.ndarray:
    """A grey image (H, W) of values 0..255: binary or ASCII PGM (8 or 16 bit), or PNG (the
    mean of its colour channels; alpha ignored); a regular file of at most
    :data:`MAX_IMAGE_BYTES`."""
    data = read_bounded(path, MAX_IMAGE_BYTES, field,
                        "give the map image's path relative to the map YAML")
    if data[:2] in (b"P5", b"P2"):
        return _pgm(data, path, field)
    if data[:8] == b"\x89PNG\r\n\x1a\n":
        import io

        import matplotlib.image

        img = np.asarray(matplotlib.image.imread(io.BytesIO(data), format="png"), dtype=float)
        if img.ndim == 3:
            img = img[..., :3].mean(axis=2) if img.shape[2] >= 3 else img[..., 0]
        scale = 255.0 if img.max(initial=0.0) <= 1.0 else 1.0
        pixels = img * scale
    else:
        raise SceneError(field, f"{path.name} is neither PGM (P5/P2) nor PNG",
                         "save the map as PGM or PNG, as map_server writes it")
    _check_size(pixels.shape, field)
    return pixels


def _pgm(data: bytes, path: Path, field: str) -> np.ndarray:
    tokens: list[bytes] = []
    pos = 2
    while len(tokens) < 3:  # width, height, maxval, skipping comments
        while pos < len(data) and data[pos:pos + 1].isspace():
            pos += 1
        if data[pos:pos + 1] == b"#":
            pos = data.find(b"\n", pos) + 1 or len(data)
            continue
        end = pos
        while end < len(data) and not data[end:end + 1].isspace():
            end += 1
        if end == pos:
            raise SceneError(field, f"{path.name} ends inside its PGM header",
                             "re-save the map image")
        tokens.append(data[pos:end])
        pos = end
    try:
        w, h, maxval = (int(t) for t in tokens)
    except ValueError as err:
        raise SceneError(field, f"{path.name} has a broken PGM header", "re-save the map image") \
            from err
    if w < 1 or h < 1 or not 0 < maxval < 65536:
        raise SceneError(field, f"{path.name}: PGM size {w} x {h}, maxval {maxval}",
                         "re-save the map image")
    _check_size((h, w), field)
    if data[:2] == b"P5":
        dtype = np.dtype(">u2") if maxval > 255 else np.dtype(np.uint8)
        body = data[pos + 1: pos + 1 + w * h * dtype.itemsize]
        if len(body) < w * h * dtype.itemsize:
            raise SceneError(field, f"{path.name} holds fewer than {w} x {h} pixels",
                             "the file is cut short: re-save the map image")
        values = np.frombuffer(body, dtype=dtype).astype(float)
    else:
        values = np.array(data[pos:].split()[: w * h], dtype=float)
        if len(values) < w * h:
            raise SceneError(field, f"{path.name} holds fewer than {w} x {h} pixels",
                             "the file is cut short: re-save the map image")
    return values.reshape(h, w) * (255.0 / maxval)


def _check_size(shape: tuple[int, ...], field: str) -> None:
    cells = int(shape[0]) * int(shape[1])
    if cells > MAX_CELLS:
        raise SceneError(field, f"the image has {cells} pixels, more than {MAX_CELLS}",
                         "crop the map or use a coarser resolution")


def _resolution(value: Any, field: str) -> float:
    return checks.number(value, field, positive=True)


def _origin(value: Any, field: str) -> tuple[float, float, float]:
    """An origin [x, y, yaw] (m, m, rad): three numbers, as the map_server format has it."""
    arr = checks.array(value, field, (None,), "as [x, y, yaw]")
    if len(arr) != 3:
        raise SceneError(field, f"is {show(value)}, {len(arr)} numbers, not [x, y, yaw]",
                         "give the pose of the lower-left corner as [x, y, yaw] (m, m, rad), "
                         "e.g. [0.0, 0.0, 0.0] for no rotation")
    checks.within_bound(arr[:2], field)
    return float(arr[0]), float(arr[1]), float(arr[2])
