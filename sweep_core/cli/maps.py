"""``sweep map``: what a map_server map becomes in a scene (its walls), a PNG of them over the
map image, and a starter scene file that uses it."""
from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from sweep_core.cli.commands import summary
from sweep_core.errors import SceneError
from sweep_core.io.outputs import check_output, replacing, write_text
from sweep_core.model.maps import OccupancyMap, read_map_yaml
from sweep_core.model.scene import Scene
from sweep_core.model.spawn import capacity, grown_area
from sweep_core.model.yaml_files import dump_yaml

__all__ = ["register"]


def describe(grid: OccupancyMap, walls: tuple[np.ndarray, np.ndarray]) -> list[tuple[str, str]]:
    """Key/value lines about the map and its walls (``grid.segments()``)."""
    a, b = walls
    h, w = grid.shape
    free = ~grid.blocked
    # the world-frame bounding box of the map's four corners (a yaw turns them)
    corners = grid.to_world(np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]]) * grid.resolution)
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    return [("map", grid.source), ("cells", f"{w} x {h} of {grid.resolution:g} m"),
            ("origin", ", ".join(f"{v:g}" for v in grid.origin)),
            ("extent_m", f"[{lo[0]:g}, {lo[1]:g}] to [{hi[0]:g}, {hi[1]:g}]"
                         + (" (bounding box of the rotated map)" if grid.origin[2] else "")),
            ("free_cells", f"{int(free.sum())} ({100.0 * free.mean():.1f} %, "
                           f"{float(free.sum()) * grid.resolution ** 2:g} m^2)"),
            ("wall_segments", str(len(a))),
            ("wall_length_m", f"{float(np.hypot(*(b - a).T).sum()):g}")]


#: the starter scene's walking speed, m/s: Weidmann's free walking speed (1993)
STARTER_SPEED = 1.34
#: how far the starter scene's paths keep from the walls, m (the geodesic drift's default)
STARTER_BUFFER = 0.3


def _coordinates(points: np.ndarray) -> list[list[float]]:
    """Points as plain lists, rounded to 1e-9 m (cell arithmetic leaves 0.30000000000000004)."""
    return [[round(float(v), 9) for v in p] for p in points]


def starter_scene(grid: OccupancyMap, yaml_path: str, count: int, radius: float) -> dict:
    """A scene on the map: ``count`` agents spawned in the largest connected free space and a
    geodesic drift, at :data:`STARTER_SPEED`, to its point farthest from any blocked cell.

    The free space is the cells whose centre lies at least ``radius`` +
    :data:`STARTER_BUFFER` + half a cell from every blocked cell's centre (so a path and a
    disk fit); its largest 8-connected part gives the goal and, by its bounding box, the spawn
    region.

    Raises:
        SceneError: the map has no such free space (naming ``--radius``).
    """
    from scipy import ndimage

    free = ~grid.blocked
    clearance = ndimage.distance_transform_edt(free) * grid.resolution
    room = clearance >= radius + STARTER_BUFFER + 0.5 * grid.resolution
    parts, n = ndimage.label(room, structure=np.ones((3, 3), dtype=bool))
    if n == 0:
        raise SceneError("--radius", f"{radius:g} m leaves no free space on the map that keeps "
                         f"{STARTER_BUFFER:g} m from its blocked cells",
                         "a smaller --radius, or a map with more free space")
    largest = 1 + int(np.argmax(np.bincount(parts.ravel())[1:]))
    rows, cols = np.nonzero(parts == largest)
    lo = np.array([cols.min(), rows.min()], dtype=float) * grid.resolution
    hi = (np.array([cols.max(), rows.max()], dtype=float) + 1.0) * grid.resolution
    box = grid.to_world(np.array([lo, hi]))
    inner = np.where(parts == largest, clearance, -1.0)
    r, c = np.unravel_index(int(np.argmax(inner)), inner.shape)
    goal = grid.to_world(np.array([[c + 0.5, r + 0.5]]) * grid.resolution)
    return {"name": Path(yaml_path).stem, "map": {"yaml": yaml_path},
            "agents": {"spawn": {"region": {"kind": "rectangle",
                                            "min": _coordinates(box.min(axis=0)[None])[0],
                                            "max": _coordinates(box.max(axis=0)[None])[0]},
                                 "count": count, "radius": radius, "seed": 0}},
            "drift": {"kind": "geodesic", "goal": _coordinates(goal)[0],
                      "speed": STARTER_SPEED},
            "noise": {"sigma": 0.05}}


def plot(grid: OccupancyMap, walls: tuple[np.ndarray, np.ndarray], out: str,
         inputs: list[str] | None = None) -> None:
    """The blocked cells in grey and the walls in red, world coordinates, as PNG to ``out``
    (through a temporary file renamed over it; never one of ``inputs``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    a, b = walls
    h, w = grid.shape
    fig, ax = plt.subplots(figsize=(8, 8 * h / max(w, 1) + 0.5))
    x0, y0, yaw = grid.origin
    if yaw == 0.0:
        ax.imshow(~grid.blocked, cmap="gray", origin="lower", vmin=-0.5, vmax=1.0,
                  extent=(x0, x0 + w * grid.resolution, y0, y0 + h * grid.resolution))
    ax.plot(np.stack([a[:, 0], b[:, 0]]), np.stack([a[:, 1], b[:, 1]]), color="tab:red", lw=1)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{Path(grid.source).name}: {len(a)} wall segments")
    try:
        with replacing(out, inputs or [], other="--png OTHER.png") as tmp:
            fig.savefig(tmp, format="png", dpi=120, bbox_inches="tight")
    finally:
        plt.close(fig)


def _map(args: argparse.Namespace) -> int:
    grid = read_map_yaml(Path(args.map), "map")
    inputs = [args.map, grid.image]
    png = scene = None  # checked before anything is written
    if args.png:
        png = check_output(args.png, inputs, other="--png OTHER.png")
    if args.scene:
        scene = check_output(args.scene, inputs, other="--scene OTHER.yaml")
    walls = grid.segments()  # the map's one costly computation, done once
    lines = describe(grid, walls)
    width = max(len(k) for k, _ in lines) + 2
    for key, value in lines:
        print(f"{key:<{width}}{value}")
    if png is not None:
        plot(grid, walls, str(png), inputs)
        print(f"{'png':<{width}}{png}")
    if scene is not None:
        spawn_spec = starter_scene(grid, "", args.count, args.radius)["agents"]["spawn"]
        box = np.array([spawn_spec["region"]["min"], spawn_spec["region"]["max"]])
        corners = np.array([box[0], [box[1, 0], box[0, 1]], box[1], [box[0, 0], box[1, 1]]])
        most = capacity(grown_area(corners, args.radius), args.radius, args.radius)
        if args.count > most:
            raise SceneError("--count", f"{args.count} agents of radius {args.radius:g} m "
                             f"exceed the {most} that the map's free cells' bounding box can "
                             "hold (random sequential addition jams at 0.547 coverage)",
                             f"give --count {most} or less, or a smaller --radius")
        rel = Path(args.map).resolve()
        try:
            rel = rel.relative_to(scene.resolve().parent)
        except ValueError:
            pass
        spec = starter_scene(grid, str(rel), args.count, args.radius)
        try:  # written only when it loads: its agents placed, each with a way to the goal
            Scene.from_dict(spec, base=scene.resolve().parent)
        except SceneError as err:
            raise SceneError("--scene", f"the starter scene does not load: {err}",
                             "a smaller --count or --radius, or edit a scene by hand "
                             "(docs/scenes.md)") from None
        write_text(scene, dump_yaml(spec), inputs, other="--scene OTHER.yaml")
        print(f"{'scene':<{width}}{scene}")
    return 0


def _positive(kind: type) -> Any:
    """An argparse type: a number of ``kind`` > 0 (finite), else a one-line usage error."""
    def parse(text: str) -> Any:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not (0 < value < math.inf):
            raise argparse.ArgumentTypeError(f"{text} is not > 0 (give a positive number)")
        return value
    parse.__name__ = kind.__name__
    return parse


def register(sub: argparse._SubParsersAction) -> None:
    """Adds ``map`` to the ``sweep`` command's subparsers."""
    p = sub.add_parser("map", help=summary("map"),
                       description="Reads a map_server YAML (PGM or PNG image) and prints its "
                       "cells, free area and the wall segments a scene gets from it (the exact "
                       "boundary of blocked cells: occupied or unknown).")
    p.add_argument("map", help="map_server YAML file")
    p.add_argument("--png", help="write the walls over the map to this PNG")
    p.add_argument("--scene", help="write a starter scene to this YAML: the map, --count agents "
                        "spawned in its largest free space, walking round the walls to its "
                        "most open point")
    p.add_argument("--count", type=_positive(int), default=50,
                   help="agents of the starter scene (50)")
    p.add_argument("--radius", type=_positive(float), default=0.25,
                   help="their radius, m (0.25)")
    p.set_defaults(func=_map)
